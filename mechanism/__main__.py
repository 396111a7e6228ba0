"""``python -m mechanism`` and the ``mechanism`` command (``[project.scripts]``)."""

import sys


def run() -> int:
    """The CLI, with its signal handlers in place before its own imports: a Ctrl-C or a kill
    in the first hundredths of a second is then an ``error: interrupted`` line too (not a
    traceback, or a death by SIGTERM). Only Python's own start-up comes before."""
    from mechanism.files import interrupts

    interrupts.install()
    try:
        from mechanism.cli import main
    except BaseException as exc:  # noqa: BLE001 - a signal during the imports (or what it broke)
        if not (isinstance(exc, KeyboardInterrupt) or interrupts.interrupted()):
            raise
        sys.stderr.write("error: interrupted\n")
        return interrupts.exit_status(exc)
    return main()


if __name__ == "__main__":
    raise SystemExit(run())
