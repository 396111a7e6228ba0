"""Errors raised while reading a CAD export. The CLI shows them as one ``error:`` line."""

from mechanism.errors import UserError


class ExportError(UserError, ValueError):
    """The export (XML, geometry, side-car) is malformed, unsafe or unsupported: bad input the
    user can fix, so a :class:`~mechanism.errors.UserError` (the one root every verb catches)."""
