"""Curated package namespaces whose names are imported on first use.

A subpackage's ``__init__`` lists its public API (``__all__``) by module; nothing is imported
until a name is used, so ``import mechanism.inspection`` does not load fcl, and a package never
imports its own modules in an order that could circle.
"""

from __future__ import annotations

import importlib

# not typing's: importing typing costs the CLI milliseconds before its signal handlers
TYPE_CHECKING = False
if TYPE_CHECKING:
    from typing import Any, Callable


def lazy_exports(
    package: str, exports: dict[str, tuple[str, ...]]
) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """``(__all__, __getattr__, __dir__)`` for ``package`` whose public names live in the
    modules ``exports`` maps them from (module names relative to the package)."""
    where = {name: f"{package}.{module}" for module, names in exports.items() for name in names}

    def __getattr__(name: str) -> Any:
        if name in where:
            return getattr(importlib.import_module(where[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(where)

    return sorted(where), __getattr__, __dir__


def renamed(name: str) -> Any:
    """A class attribute that reads and writes the attribute ``name``: an old name of a
    renamed dataclass field kept working (``needle_z_mm = renamed("tool_z_mm")``)."""

    def get(self):
        return getattr(self, name)

    def put(self, value) -> None:
        setattr(self, name, value)

    return property(get, put, doc=f"Deprecated alias of ``{name}``.")
