"""Ctrl-C (SIGINT) and ``kill`` (SIGTERM) as an orderly end of a run.

:func:`install` (the CLI calls it first) turns both signals into :class:`Interrupted`, an
exception that unwinds the run like any failure: the output transaction removes its
temporaries and publishes nothing, worker pools and a Ray instance the run started are
stopped, and the CLI prints one ``error: interrupted`` line and exits 130 (SIGINT) or 143
(SIGTERM). Only the first signal interrupts: a second Ctrl-C while the run cleans up is
noted and ignored, so the cleanup itself is never cut short. Code that must not be cut in
two (publishing, removing temporaries) runs inside :func:`deferred`: a signal arriving
there takes effect when the block ends.

``SIGXFSZ`` (a file grew past ``ulimit -f``) is ignored, so that the write fails with
``EFBIG`` and becomes an ``error:`` line instead of killing the process with a core dump.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from typing import Any

EXIT_STATUS: dict[int, int] = {signal.SIGINT: 130, signal.SIGTERM: 143}


class Interrupted(KeyboardInterrupt):
    """The run was interrupted by ``signum`` (a KeyboardInterrupt, so code that lets Ctrl-C
    through lets this through too)."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_status(self) -> int:
        return EXIT_STATUS.get(self.signum, 130)


_state: dict[str, Any] = {
    "installed": False,
    "interrupted": None,
    "depth": 0,
    "pending": None,
    "finished": False,
    "unraisablehook": sys.unraisablehook,
    "ends_process": False,
    "committed": False,
}


def _handler(signum, frame):  # noqa: ARG001 - signal API
    if _state["committed"]:
        return  # the run's outputs are published: it is complete, too late to interrupt
    if _state["interrupted"] is not None:
        return  # the run is already ending: a second signal must not cut its cleanup short
    if _state["depth"] > 0:
        _state["pending"] = signum  # inside a deferred block: interrupt when it ends
        return
    _state["interrupted"] = signum
    raise Interrupted(signum)


def _unraisable(unraisable) -> None:
    """The signal's exception was raised where Python ignores exceptions (a signal landing in an
    at-fork hook, as after a fork of Ray's or a subprocess's: the run went on to the end and
    exited 0): deliver the signal again, from outside that place, a moment later."""
    exc = unraisable.exc_value
    if isinstance(exc, Interrupted) and _state["interrupted"] == exc.signum:
        _state["interrupted"] = None
        again = threading.Timer(0.01, _deliver_again, (exc.signum,))
        again.daemon = True
        again.start()
        return
    _state["unraisablehook"](unraisable)


def _deliver_again(signum: int) -> None:
    if installed():  # not once a test calling main in-process has its own handlers back
        os.kill(os.getpid(), signum)


def install() -> None:
    """SIGINT and SIGTERM raise :class:`Interrupted` (once); SIGXFSZ is ignored."""
    if threading.current_thread() is not threading.main_thread():
        return
    numbers = [signal.SIGINT, signal.SIGTERM] + (
        [signal.SIGXFSZ] if hasattr(signal, "SIGXFSZ") else []
    )
    previous = {number: signal.getsignal(number) for number in numbers}
    signal.signal(signal.SIGINT, _handler)
    signal.signal(signal.SIGTERM, _handler)
    if hasattr(signal, "SIGXFSZ"):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    if sys.unraisablehook is not _unraisable:
        _state["unraisablehook"] = sys.unraisablehook
        sys.unraisablehook = _unraisable
    _state.update(
        installed=previous, interrupted=None, depth=0, pending=None, finished=False, committed=False
    )


def end_process_after_cleanup(ends: bool) -> None:
    """Say whether an interrupted run ends its process with ``os._exit`` once it has cleaned up
    (the command line; not a caller of ``cli.main`` in its own process)."""
    _state["ends_process"] = ends


def process_ends_after_cleanup() -> bool:
    """True when an interrupted run's process ends right after its cleanup: what it started
    may then be killed rather than shut down in order."""
    return bool(_state["ends_process"]) and interrupted()


def installed() -> bool:
    """True while :func:`install`'s handlers are in place (a CLI run, not a notebook)."""
    return bool(_state["installed"])


def reclaim() -> None:
    """Our handlers back after a library replaced them (``ray.init`` sets its own SIGTERM
    handler, which exits without cleaning up)."""
    if installed() and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _handler)
        signal.signal(signal.SIGTERM, _handler)


def ignore_from_now() -> None:
    """The process is about to exit: later signals are ignored by the system itself (Python
    drops its own handlers while it shuts down, when a late Ctrl-C would kill it with 130's
    twin, a death by SIGINT)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def restore() -> None:
    """The handlers from before :func:`install` (``main`` called in-process, by tests)."""
    previous = _state["installed"]
    if previous and threading.current_thread() is threading.main_thread():
        for number, handler in previous.items():
            if handler is not None:
                signal.signal(number, handler)
        if sys.unraisablehook is _unraisable:
            sys.unraisablehook = _state["unraisablehook"]
    _state["installed"] = False


def finish() -> None:
    """The run has ended (its one line written or about to be): later signals are ignored."""
    _state["finished"] = True
    if _state["interrupted"] is None:
        _state["interrupted"] = 0


def commit() -> None:
    """The run's outputs are published: the run is complete. A signal from here on (while it
    publishes, or between its last rename and its exit) is too late to stop it; an ``error:
    interrupted`` and exit 130 then would say the previous outputs were kept when the new ones
    are in place."""
    _state["committed"] = True
    _state["pending"] = None


def checkpoint() -> None:
    """Raise the run's interrupt again where a library swallowed it: trimesh imports its
    optional modules under ``except BaseException``, and a Ctrl-C landing in such an import
    vanished (the run went on, published and exited 0: 1 in 6 signals sent 9.8 s into a youBot
    conversion). Called before a run publishes, when a deferred block ends and when the verb
    returns; a no-op while the interrupt is on its way out (it is the exception being handled)
    and once the run has ended."""
    signum = _state["interrupted"]
    if (
        signum
        and _state["installed"]
        and not _state["finished"]
        and not _state["committed"]
        and not isinstance(sys.exc_info()[1], (Interrupted, KeyboardInterrupt))
    ):
        raise Interrupted(signum)


def interrupted() -> bool:
    """True once a run was interrupted."""
    return bool(_state["interrupted"])


def exit_status(exc: BaseException) -> int:
    """The exit status of a run that ``exc`` ended: the signal's (130 for SIGINT, 143 for
    SIGTERM). A library may turn the signal into a plain KeyboardInterrupt (Ray does, when it
    arrives inside ``ray.wait``): the signal that was received still decides."""
    status = getattr(exc, "exit_status", None)
    if status is None and _state["interrupted"]:
        status = EXIT_STATUS.get(_state["interrupted"])
    return status if status is not None else 130


@contextlib.contextmanager
def deferred():
    """A block that a signal does not cut in two: the signal takes effect when it ends (and
    an interrupt that a library swallowed is raised again there, never before the block: many
    are cleanups, which must run)."""
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
        pending = _state["pending"]
        if _state["depth"] == 0 and pending is not None:
            _state["pending"] = None
            if _state["interrupted"] is None:
                _state["interrupted"] = pending
                raise Interrupted(pending)
        if _state["depth"] == 0:
            checkpoint()


def ignore_in_worker() -> None:
    """In a worker process: leave SIGINT and SIGTERM to the parent, which stops the workers
    itself (a Ctrl-C reaches every process of the terminal's group)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


PR_SET_PDEATHSIG = 1  # Linux prctl: the signal a process gets when the thread that forked it ends


def die_with_parent(parent_pid: int) -> bool:
    """In a worker process forked by ``parent_pid``: be killed (SIGKILL) when the parent ends,
    however it ends (a killed parent leaves no worker behind). Linux only: False elsewhere, or
    where the kernel refuses. A parent already gone ends this worker at once."""
    import ctypes

    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() != parent_pid:  # it died before the line above
        os._exit(1)
    return True


def stop_pool(pool, at_once: bool) -> None:
    """Shut a process pool down, its workers stopped at once (SIGTERM, then SIGKILL for any
    still there) where ``at_once``: after an error or an interrupt, not after their work."""
    with deferred():  # a second Ctrl-C must not leave workers behind
        if at_once:
            processes = list((getattr(pool, "_processes", None) or {}).values())
            for process in processes:
                with contextlib.suppress(Exception):
                    process.terminate()
            for process in processes:
                with contextlib.suppress(Exception):
                    process.join(1.0)
                    if process.is_alive():
                        process.kill()
                        process.join(1.0)
        pool.shutdown(wait=True, cancel_futures=True)
