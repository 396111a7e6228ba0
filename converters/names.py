"""MJCF names from CAD names (docs/architecture.md): characters outside ``[A-Za-z0-9_.-]``
become ``_``, runs of ``_`` collapse, and duplicates get ``_2``, ``_3``, ... suffixes."""

from __future__ import annotations

import re
from collections.abc import Iterable

_INVALID = re.compile(r"[^A-Za-z0-9_.\-]")
_RUNS = re.compile(r"_+")


def sanitize(name: str) -> str:
    cleaned = _RUNS.sub("_", _INVALID.sub("_", name.strip()))
    return cleaned or "unnamed"


class Namer:
    """Hands out unique sanitised names within one MJCF namespace (bodies, geoms, sites...)."""

    def __init__(self, reserved: Iterable[str] = ()) -> None:
        self._used: set[str] = set(reserved)

    def __call__(self, name: str, prefix: str = "") -> str:
        """A unique ``prefix + sanitize(name)`` (the prefix, e.g. ``loop:``, is kept as written)."""
        base = prefix + sanitize(name)
        candidate, counter = base, 1
        while candidate in self._used:
            counter += 1
            candidate = f"{base}_{counter}"
        self._used.add(candidate)
        return candidate
