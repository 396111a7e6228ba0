"""Unit names as CAD exporters write them, and their factors to SI.

First-generation files write short names (``"mm"``, ``"kg"``, ``"kg*m^2"``, ``"g*mm^2"``),
second-generation files long ones (``length="millimeter" mass="pound"``). Inertia units
are always a mass unit times a length unit squared, so they are parsed, not listed.
"""

from __future__ import annotations

import re

from mechanism.converters.errors import ExportError

LENGTH = {
    "m": 1.0,
    "meter": 1.0,
    "metre": 1.0,
    "meters": 1.0,
    "metres": 1.0,
    "mm": 1e-3,
    "millimeter": 1e-3,
    "millimetre": 1e-3,
    "millimeters": 1e-3,
    "millimetres": 1e-3,
    "cm": 1e-2,
    "centimeter": 1e-2,
    "centimetre": 1e-2,
    "centimeters": 1e-2,
    "centimetres": 1e-2,
    "um": 1e-6,
    "micron": 1e-6,
    "micrometer": 1e-6,
    "micrometre": 1e-6,
    "in": 0.0254,
    "inch": 0.0254,
    "inches": 0.0254,
    "ft": 0.3048,
    "foot": 0.3048,
    "feet": 0.3048,
}

MASS = {
    "kg": 1.0,
    "kilogram": 1.0,
    "kilograms": 1.0,
    "g": 1e-3,
    "gram": 1e-3,
    "grams": 1e-3,
    "mg": 1e-6,
    "milligram": 1e-6,
    "t": 1e3,
    "tonne": 1e3,
    "lbm": 0.45359237,
    "lb": 0.45359237,
    "lbs": 0.45359237,
    "pound": 0.45359237,
    "pounds": 0.45359237,
    "slug": 14.593902937206364,
    "slugs": 14.593902937206364,
    "oz": 0.028349523125,
    "ounce": 0.028349523125,
}

ANGLE = {
    "rad": 1.0,
    "radian": 1.0,
    "radians": 1.0,
    "deg": 0.017453292519943295,
    "degree": 0.017453292519943295,
    "degrees": 0.017453292519943295,
}


def _clean(unit: str) -> str:
    return unit.strip().strip('"').strip().lower()


def _lookup(table: dict, unit: str, kind: str, where: str) -> float:
    key = _clean(unit)
    if key in table:
        return table[key]
    raise ExportError(
        f"{where}: unknown {kind} unit '{unit}' (known: {', '.join(sorted(set(table)))})"
    )


def length_factor(unit: str, where: str) -> float:
    """Metres per ``unit``."""
    return _lookup(LENGTH, unit, "length", where)


def mass_factor(unit: str, where: str) -> float:
    """Kilograms per ``unit``."""
    return _lookup(MASS, unit, "mass", where)


def angle_factor(unit: str, where: str) -> float:
    """Radians per ``unit``."""
    return _lookup(ANGLE, unit, "angle", where)


_POWER = re.compile(r"^(?P<base>[a-z]+)(?:\^?(?P<exp>[0-9]))?$")


def inertia_factor(unit: str, where: str) -> float:
    """kg*m^2 per ``unit`` for units written as mass*length^2 (``kg*m^2``, ``g*mm^2``, ``lbm*in^2``, ``lbm*in*in``)."""
    text = _clean(unit).replace("²", "^2").replace(" ", "*").replace("·", "*")
    pieces = [piece for piece in re.split(r"[*.]", text) if piece]
    mass = length = None
    length_power = 0
    for piece in pieces:
        match = _POWER.match(piece)
        if not match:
            break
        base, exp = match["base"], int(match["exp"] or 1)
        if base in MASS and exp == 1 and mass is None:
            mass = MASS[base]
        elif base in LENGTH and (length is None or LENGTH[base] == length):  # m^2 or m*m
            length, length_power = LENGTH[base], length_power + exp
        else:
            break
    else:
        if mass is not None and length is not None and length_power == 2:
            return mass * length**2
    raise ExportError(
        f"{where}: unknown inertia unit '{unit}' (expected mass*length^2, e.g. kg*m^2 or g*mm^2)"
    )


def volume_factor(unit: str, where: str) -> float:
    """m^3 per ``unit`` for units written as length^3 (``mm^3``)."""
    text = _clean(unit).replace("³", "^3")
    match = _POWER.match(text)
    if match and match["base"] in LENGTH and match["exp"] == "3":
        return LENGTH[match["base"]] ** 3
    raise ExportError(f"{where}: unknown volume unit '{unit}' (expected length^3, e.g. mm^3)")
