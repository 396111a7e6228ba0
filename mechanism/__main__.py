"""``python -m mechanism`` and the ``mechanism`` command (``[project.scripts]``)."""

import signal
import sys

# 130 for Ctrl-C, 143 for a kill, as mechanism.files.interrupts says once it is imported
_EARLY_STATUS: dict[int, int] = {signal.SIGINT: 130, signal.SIGTERM: 143}
_early_signal: list[int] = []


def _early_handler(signum, frame):  # noqa: ARG001 - signal API
    """Until :mod:`mechanism.files.interrupts` is imported (milliseconds: it is the first import)."""
    if not _early_signal:
        _early_signal.append(signum)
        raise KeyboardInterrupt


def run() -> int:
    """The CLI, with its signal handlers in place before its own imports: a Ctrl-C or a kill
    in the first hundredths of a second is then an ``error: interrupted`` line too (not a
    traceback, or a death by SIGTERM). Only Python's own start-up and ``import mechanism``
    (kept free of imports: 1-2 ms) come before the first handler, which needs only
    ``signal``."""
    try:
        signal.signal(signal.SIGINT, _early_handler)
        signal.signal(signal.SIGTERM, _early_handler)
    except ValueError:  # not the main thread: the caller owns the signals
        pass
    try:
        from mechanism.files import interrupts

        interrupts.install()
        from mechanism.cli import main
    except BaseException as exc:  # noqa: BLE001 - a signal during the imports (or what it broke)
        interrupted = "interrupts" in locals() and interrupts.interrupted()
        if not (isinstance(exc, KeyboardInterrupt) or _early_signal or interrupted):
            raise
        sys.stderr.write("error: interrupted\n")
        if _early_signal and not interrupted:
            return _EARLY_STATUS.get(_early_signal[0], 130)
        return interrupts.exit_status(exc)
    return main()


if __name__ == "__main__":
    raise SystemExit(run())
