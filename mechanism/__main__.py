"""``python -m mechanism`` and the ``mechanism`` command (``[project.scripts]``)."""

import signal
import sys

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
        handlers = locals().get("interrupts")  # bound only once its import has finished
        interrupted = handlers is not None and handlers.interrupted()
        if not (isinstance(exc, KeyboardInterrupt) or _early_signal or interrupted):
            raise
        sys.stderr.write("error: interrupted\n")
        if handlers is None or (_early_signal and not interrupted):
            # the shell's status for that signal: 130, 143
            return 128 + (_early_signal[0] if _early_signal else signal.SIGINT)
        return handlers.exit_status(exc)
    return main()


if __name__ == "__main__":
    raise SystemExit(run())
