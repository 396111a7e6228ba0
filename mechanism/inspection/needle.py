"""Deprecated: the sewing machine's name of :mod:`mechanism.inspection.tool`.

``NeedleMotion``, ``needle_motion``, ``plot`` and ``write_csv`` are the very objects of
``mechanism.inspection.tool`` (``ToolMotion``, ``tool_motion``, ...), kept importable from here for code
written before the core spoke of shaft and tool.
"""

from mechanism.inspection.tool import (
    ColumnNames,
    NeedleMotion,
    ToolMotion,
    needle_motion,
    plot,
    tool_motion,
    write_csv,
)

__all__ = [
    "ColumnNames",
    "NeedleMotion",
    "ToolMotion",
    "needle_motion",
    "plot",
    "tool_motion",
    "write_csv",
]
