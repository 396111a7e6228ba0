"""Untrusted input: XML parsed without DTDs or entities, sizes bounded, names kept in the export folder."""

from __future__ import annotations

import re
from pathlib import Path

import defusedxml
import defusedxml.ElementTree as SafeET
from xml.etree.ElementTree import ParseError

import numpy as np

from mechanism.converters.errors import ExportError

MAX_XML_BYTES = 200 * 1024 * 1024
MAX_GEOMETRY_BYTES = 1024 * 1024 * 1024
MAX_SIDECAR_BYTES = 4 * 1024 * 1024
MAX_DEPTH = 200  # nesting of sub-assemblies / elements we walk recursively


def read_bounded(path: Path, limit: int, what: str) -> bytes:
    """The bytes of an existing, non-empty regular file no larger than ``limit`` (the one bounded
    reader, :func:`mechanism.files.limits.read_bounded`, with the converter's error type)."""
    from mechanism.errors import UserError
    from mechanism.files.limits import read_bounded as read

    path = Path(path)
    if path.exists() and not path.is_file() and not path.is_dir():
        raise ExportError(f"{what} {path}: not a regular file")
    try:
        data = read(path, what, limit)
    except UserError as exc:
        raise ExportError(str(exc)) from None
    if not data:
        raise ExportError(f"{what} {path}: file is empty")
    return data


def parse_xml(path: Path):
    """Parse an export with entities, DTDs and external references forbidden; return the root element."""
    data = read_bounded(path, MAX_XML_BYTES, "export")
    try:
        root = SafeET.fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except defusedxml.DTDForbidden:
        raise ExportError(
            f"export {path}: contains a DTD (<!DOCTYPE ...>), refused as unsafe XML"
        ) from None
    except defusedxml.EntitiesForbidden:
        raise ExportError(f"export {path}: declares XML entities, refused as unsafe XML") from None
    except defusedxml.ExternalReferenceForbidden:
        raise ExportError(
            f"export {path}: refers to external XML resources, refused as unsafe XML"
        ) from None
    except ParseError as exc:
        line, column = getattr(exc, "position", (0, 0))
        reason = str(exc).split(":")[0]
        raise ExportError(
            f"export {path}: not well-formed XML ({reason} at line {line}, column {column})"
        ) from None
    except (ValueError, RecursionError) as exc:
        raise ExportError(
            f"export {path}: cannot be parsed as XML ({exc.__class__.__name__})"
        ) from None
    return root


def resolve_inside(folder: Path, name: str, what: str) -> Path:
    """The path of ``name`` inside ``folder``; anything that would escape the folder is an error.

    The name may use ``/`` or ``\\`` separators (exports written on Windows). Symbolic links
    are resolved first, so a link pointing out of the folder is refused as well.
    """
    if "\x00" in name:
        raise ExportError(f"{what}: file name contains a NUL character")
    cleaned = name.strip().replace("\\", "/")
    if cleaned.startswith("/") or (len(cleaned) > 1 and cleaned[1] == ":"):
        raise ExportError(
            f"{what}: file name '{name}' is an absolute path; geometry must lie inside the export folder"
        )
    folder = Path(folder).resolve()
    try:
        resolved = (folder / cleaned).resolve()
    except (OSError, RuntimeError):  # symlink loops
        raise ExportError(
            f"{what}: file name '{name}' cannot be resolved inside the export folder"
        ) from None
    if folder not in resolved.parents:
        raise ExportError(f"{what}: file name '{name}' points outside the export folder {folder}")
    return resolved


_SEPARATORS = re.compile(r"[,;\s]+")


def numbers(text: str | None, count: int, where: str) -> np.ndarray:
    """Exactly ``count`` finite numbers from untrusted text (comma, semicolon or space separated)."""
    if text is None:
        raise ExportError(f"{where}: missing")
    try:
        values = np.array([float(piece) for piece in _SEPARATORS.split(text.strip()) if piece])
    except ValueError:
        raise ExportError(f"{where}: '{text.strip()[:60]}' is not a list of numbers") from None
    if values.size != count:
        raise ExportError(f"{where}: expected {count} numbers, found {values.size}")
    if not np.all(np.isfinite(values)):
        raise ExportError(f"{where}: contains NaN/inf")
    return values
