"""Third-party text on stderr and stdout (MuJoCo, OpenCASCADE via cascadio, C libraries)
captured and turned into our one-line form.

C code writes to file descriptors 1 and 2 directly, past ``sys.stdout``/``sys.stderr``.
:func:`captured_stderr` and :func:`captured_stdout` point the descriptor at a temporary file
for the duration of a run while Python's own stream (our results, ``error:``/``warning:``
lines, progress bars) keeps writing to the real terminal; what was captured is handed back
for the caller to report in one line (terminal colour codes removed).
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile

from mechanism.files.interrupts import deferred

UNSTABLE_MARKERS = ("simulation is unstable", "Nan, Inf or huge value")


class LineTracker(io.TextIOBase):
    """A text stream proxy that remembers whether the last write ended its line, so an
    ``error:`` line never lands glued to a progress bar's fragment."""

    def __init__(self, stream):
        self.stream = stream
        self.at_line_start = True

    def write(self, text):
        if text:
            self.at_line_start = text.endswith(("\n", "\r"))
        return self.stream.write(text)

    def flush(self):
        with contextlib.suppress(Exception):
            self.stream.flush()

    def isatty(self):
        return self.stream.isatty()

    def fileno(self):
        return self.stream.fileno()

    @property
    def encoding(self):
        return getattr(self.stream, "encoding", "utf-8")

    def end_line(self) -> None:
        if not self.at_line_start:
            self.write("\n")
        self.flush()


# colours and cursor moves (OpenCASCADE colours its messages)
TERMINAL_CODES = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def summarize(text: str, limit: int = 300) -> str:
    """Several lines of captured text as one line (colour codes and repeats dropped, trimmed)."""
    seen, pieces = set(), []
    for line in TERMINAL_CODES.sub("", text).splitlines():
        line = " ".join(line.split())
        if line and line not in seen:
            seen.add(line)
            pieces.append(line)
    joined = "; ".join(pieces)
    return joined if len(joined) <= limit else joined[: limit - 3] + "..."


def captured_stderr():
    """Yield a list that, after the block, holds the text C code wrote on descriptor 2."""
    return _captured(2, "stderr")


def captured_stdout():
    """Yield a list that, after the block, holds the text C code wrote on descriptor 1."""
    return _captured(1, "stdout")


@contextlib.contextmanager
def _captured(fd: int, name: str):
    """``sys.<name>`` is re-pointed to a duplicate of the original descriptor, so Python-level
    writes still reach the terminal; subprocesses started inside inherit the capture."""
    try:
        os.fstat(fd)
    except OSError:
        yield []  # no such descriptor to capture (embedded interpreter)
        return
    result: list[str] = []
    try:
        sink = tempfile.TemporaryFile()
    except OSError:  # no temporary folder can be written (full disk, ulimit -f 0): run uncaptured
        yield result
        return
    previous = getattr(sys, name)
    with contextlib.suppress(Exception):
        previous.flush()
    saved = os.dup(fd)
    real = open(saved, "w", encoding="utf-8", errors="replace", buffering=1, closefd=False)
    inner = getattr(previous, "stream", None)
    if inner is not None:  # a LineTracker: keep tracking, write to the real terminal
        previous.stream = real
    else:
        setattr(sys, name, real)
    with sink:
        os.dup2(sink.fileno(), fd)
        try:
            yield result
        finally:
            with deferred():  # a Ctrl-C here must not leave the descriptor in the sink
                _restore(fd, name, saved, real, previous, inner, sink, result)


def _restore(fd: int, name: str, saved, real, previous, inner, sink, result) -> None:
    """The descriptor and ``sys.<name>`` back as they were; the captured text into ``result``."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os.dup2(saved, fd)
    real.flush()
    if inner is not None:
        previous.stream = inner
    else:
        setattr(sys, name, previous)
    real.close()
    os.close(saved)
    sink.seek(0)
    result.append(sink.read(1 << 20).decode("utf-8", errors="replace"))
