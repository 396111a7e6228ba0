"""Faults injected at the N-th write event under a folder: a full disk (ENOSPC), a quota
(EDQUOT), a file size limit (EFBIG), or a signal (SIGINT, SIGTERM) delivered to this process.

A write event is one ``write`` on a file opened for writing, one rename, replace, folder
exchange, hard link, mkdir or file copy whose target lies under ``root``: the points at which
a run writes or publishes its outputs. Used in-process by the fault suite and from scripts
the tests run in a subprocess."""

from __future__ import annotations

import builtins
import contextlib
import errno
import io
import os
import shutil
import signal
from pathlib import Path

FAULTS = ("ENOSPC", "EDQUOT", "EFBIG", "SIGINT", "SIGTERM")


class Injector:
    def __init__(self, root: Path, fail_at: int, fault: str):
        self.root = str(Path(root).absolute())
        self.fail_at, self.fault = fail_at, fault
        self.events = 0
        self.fired = False
        self.publishing = False  # inside Transaction._publish: the renames that publish a run
        self.fired_publishing = False

    def under(self, path) -> bool:
        try:
            return os.path.abspath(os.fsdecode(path)).startswith(self.root)
        except TypeError:
            return False  # a descriptor

    def event(self, path) -> None:
        if self.fired or not self.under(path):
            return
        self.events += 1
        if self.events <= self.fail_at:
            return
        self.fired = True
        self.fired_publishing = self.publishing
        if self.fault.startswith("SIG"):
            # the handler runs at the next bytecode
            os.kill(os.getpid(), getattr(signal, self.fault))
            return
        number = getattr(errno, self.fault)
        raise OSError(number, os.strerror(number), os.fsdecode(path))


class _File:
    """A file object whose writes are write events."""

    def __init__(self, handle, injector: Injector, path):
        self._handle, self._injector, self._path = handle, injector, path

    def write(self, data):
        self._injector.event(self._path)
        return self._handle.write(data)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._handle.close()

    def __iter__(self):
        return iter(self._handle)

    def __getattr__(self, name):
        return getattr(self._handle, name)


@contextlib.contextmanager
def injected(root, fail_at: int, fault: str):
    """Inject ``fault`` at write event ``fail_at`` (0 = the first) under ``root``; yields the
    injector (``events`` counts what was seen, ``fired`` whether the fault came)."""
    from mechanism.files import outputs

    injector = Injector(root, fail_at, fault)
    real_open, real_io_open = builtins.open, io.open
    saved = {name: getattr(os, name) for name in ("rename", "replace", "link", "mkdir")}
    real_copyfile, real_exchange = shutil.copyfile, outputs._exchange

    def opener(real):
        def wrapped(file, mode="r", *args, **kwargs):
            handle = real(file, mode, *args, **kwargs)
            if (
                any(flag in mode for flag in "wax+")
                and not isinstance(file, int)
                and injector.under(file)
            ):
                return _File(handle, injector, file)
            return handle

        return wrapped

    def on_target(function, position):
        def wrapped(*args, **kwargs):
            injector.event(args[position])
            return function(*args, **kwargs)

        return wrapped

    builtins.open = opener(real_open)
    io.open = opener(real_io_open)
    os.rename, os.replace, os.link = (on_target(saved[n], 1) for n in ("rename", "replace", "link"))

    def mkdir(path, *args, **kwargs):
        if not os.path.lexists(path):  # an existing folder fails with EEXIST whatever the disk
            injector.event(path)
        return saved["mkdir"](path, *args, **kwargs)

    os.mkdir = mkdir
    shutil.copyfile = on_target(real_copyfile, 1)
    outputs._exchange = on_target(real_exchange, 1)
    real_publish = outputs.Transaction._publish

    def publish(transaction):
        injector.publishing = True
        try:
            return real_publish(transaction)
        finally:
            injector.publishing = False

    outputs.Transaction._publish = publish
    try:
        yield injector
    finally:
        builtins.open, io.open = real_open, real_io_open
        for name, function in saved.items():
            setattr(os, name, function)
        shutil.copyfile, outputs._exchange = real_copyfile, real_exchange
        outputs.Transaction._publish = real_publish


# the ways a system refuses worker processes: a process limit refuses the fork; a container
# without /dev/shm has no POSIX semaphores for a process pool's queues
WORKER_REFUSALS = {"a process limit": errno.EAGAIN, "a container without /dev/shm": errno.ENOSYS}


def refuse_worker_processes(monkeypatch, refusal: str) -> str:
    """Make this process's system refuse worker processes as ``refusal`` (a key of
    ``WORKER_REFUSALS``) does; returns the first word of the reason the system gives."""
    import multiprocessing.synchronize

    code = WORKER_REFUSALS[refusal]

    def refused(*args, **kwargs):
        raise OSError(code, os.strerror(code))

    if code == errno.EAGAIN:
        monkeypatch.setattr(os, "fork", refused)
    else:
        monkeypatch.setattr(multiprocessing.synchronize.SemLock, "__init__", refused)
    return os.strerror(code).split()[0]
