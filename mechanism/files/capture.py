"""Third-party text on stderr (MuJoCo, OpenCASCADE via cascadio, C libraries) captured and
turned into our one-line form.

C code writes to file descriptor 2 directly, past ``sys.stderr``. :func:`captured_stderr`
points descriptor 2 at a temporary file for the duration of a run while Python's own
``sys.stderr`` (our ``error:``/``warning:`` lines, progress bars) keeps writing to the real
terminal; what was captured is handed back for the caller to report in one line.
"""

from __future__ import annotations

import contextlib
import io
import os
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


def summarize(text: str, limit: int = 300) -> str:
    """Several lines of captured text as one line (repeats dropped, trimmed)."""
    seen, pieces = set(), []
    for line in text.splitlines():
        line = " ".join(line.split())
        if line and line not in seen:
            seen.add(line)
            pieces.append(line)
    joined = "; ".join(pieces)
    return joined if len(joined) <= limit else joined[: limit - 3] + "..."


@contextlib.contextmanager
def captured_stderr():
    """Yield a list that, after the block, holds the text C code wrote on descriptor 2.

    ``sys.stderr`` is re-pointed to a duplicate of the original descriptor, so Python-level
    writes still reach the terminal; subprocesses started inside inherit the capture."""
    try:
        os.fstat(2)
    except OSError:
        yield []  # no descriptor 2 to capture (embedded interpreter)
        return
    result: list[str] = []
    try:
        sink = tempfile.TemporaryFile()
    except OSError:  # no temporary folder can be written (full disk, ulimit -f 0): run uncaptured
        yield result
        return
    sys.stderr.flush()
    saved = os.dup(2)
    real = open(saved, "w", encoding="utf-8", errors="replace", buffering=1, closefd=False)
    previous = sys.stderr
    inner = getattr(previous, "stream", None)
    if inner is not None:  # a LineTracker: keep tracking, write to the real terminal
        previous.stream = real
    else:
        sys.stderr = real
    with sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield result
        finally:
            with deferred():  # a Ctrl-C here must not leave descriptor 2 in the sink
                _restore(saved, real, previous, inner, sink, result)


def _restore(saved, real, previous, inner, sink, result) -> None:
    """Descriptor 2 and ``sys.stderr`` back as they were; the captured text into ``result``."""
    with contextlib.suppress(Exception):
        sys.stdout.flush()
    os.dup2(saved, 2)
    real.flush()
    if inner is not None:
        previous.stream = inner
    else:
        sys.stderr = previous
    real.close()
    os.close(saved)
    sink.seek(0)
    result.append(sink.read(1 << 20).decode("utf-8", errors="replace"))
