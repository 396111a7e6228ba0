"""The thesis's numbers (Tegsten 2008), read from one JSON file, never copied into code.

``mechanism/data/tegsten2008.json`` is a verbatim copy of the project's shared
reference file (a test checks the two are identical when the shared folder is present).
"""

from __future__ import annotations

import functools
import json
from importlib import resources


@functools.lru_cache(maxsize=None)
def thesis() -> dict:
    """The parsed reference file (treat as read-only)."""
    text = (
        resources.files("mechanism.data").joinpath("tegsten2008.json").read_text(encoding="utf-8")
    )
    return json.loads(text)
