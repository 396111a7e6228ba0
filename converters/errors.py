"""Errors raised while reading a CAD export. The CLI shows them as one ``error:`` line."""


class ExportError(ValueError):
    """The export (XML, geometry, side-car) is malformed, unsafe or unsupported."""
