"""Option strings where they enter the API: argparse's ``choices`` restrict them, this narrows
them to the ``Literal`` type the API declares (and says so if a verb ever sets one unchecked)."""

from __future__ import annotations

from typing import TypeVar, cast

T = TypeVar("T", bound=str)


def chosen(value: object, options: tuple[T, ...], option: str) -> T:
    """``value`` as one of ``options`` (a Literal type's ``get_args``), else a UserError."""
    if value not in options:
        from mechanism.errors import UserError

        raise UserError(f"{option} {value!r}: expected one of {', '.join(options)}")
    return cast(T, value)
