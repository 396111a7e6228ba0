"""Read any supported export: dispatch on the XML root element through a registry of readers.

Adding an exporter format is one new reader module and one line in :data:`READERS`.
"""

from __future__ import annotations

from pathlib import Path

from mechanism.converters import gen1, gen2
from mechanism.converters.assembly import Assembly
from mechanism.converters.couplings import read_couplings
from mechanism.converters.errors import ExportError
from mechanism.converters.safety import parse_xml

READERS = {
    gen1.ROOT_TAG: gen1.read,
    # a first-generation model element without its wrapper
    **{tag: gen1.read for tag in gen1.MODEL_TAGS},
    gen2.ROOT_TAG: gen2.read,
    gen2.LEGACY_ROOT_TAG: gen2.read,
}


def local_name(tag: str) -> str:
    """An element name without its XML namespace (``{urn:...}Name`` -> ``Name``)."""
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def read(export_path) -> Assembly:
    """The neutral assembly of an export file (with its couplings side-car, if any)."""
    path = Path(export_path)
    root = parse_xml(path)
    tag = local_name(root.tag)
    reader = READERS.get(tag)
    if reader is None:
        known = ", ".join(f"<{name}>" for name in READERS)
        raise ExportError(
            f"export {path}: root element <{tag}> is not a known CAD export format (expected {known})"
        )
    assembly = reader(root, path)
    read_couplings(assembly)
    return assembly
