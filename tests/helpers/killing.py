"""Kill this process (SIGKILL, no cleanup) just before its N-th rename: the instants at which
a run can die while it publishes its outputs. Used by scripts the tests run in a subprocess."""

from __future__ import annotations

import os
import signal


def kill_before_rename(kill_at: int, exchange: bool = True) -> None:
    """Count os.rename, os.replace and the atomic folder exchange; die before call ``kill_at``.
    ``exchange=False`` makes the system look like one without an atomic exchange."""
    from mechanism.files import outputs

    calls = [0]

    def counted(function):
        def wrapper(*args, **kwargs):
            if calls[0] == kill_at:
                os.kill(os.getpid(), signal.SIGKILL)
            calls[0] += 1
            return function(*args, **kwargs)

        return wrapper

    os.rename, os.replace = counted(os.rename), counted(os.replace)
    outputs._exchange = counted(outputs._exchange) if exchange else (lambda a, b: False)
