"""The column map: which columns of a bench's file are time, voltage, the shaft angle and the
current, in which units, and what to do to them (the ``[recording]`` table of a machine
description, or of a ``--recording-map FILE.toml`` that wins over it; keys in
docs/machine.md).

Expressions are products and quotients of columns and numbers (``load * input_volts / 885``),
parsed with :mod:`ast` and evaluated over a whitelist of nodes: names, numbers, ``*``, ``/``,
unary ``-``/``+``, parentheses and dotted names (``data.position``: a nested field or a struct's);
never ``eval``. A column name that is not a Python name (``Motor/Voltage``, ``rec.Y(2).Data``)
is written alone or in backquotes inside an expression.

Units are an explicit table (the set is closed: three time units, six angle units of which
three need a stated constant, counts_per_rev or travel_per_rev_mm); what was applied is
returned as a ``reading`` dict that the identify and diagnose JSON carry.
"""

from __future__ import annotations

import ast
import math
import os
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mechanism.errors import UserError, close_matches
from mechanism.files.formats import Columns

TIME_PER_S = {"s": 1.0, "ms": 1e3, "us": 1e6}  # divided by, as a hand conversion does (t_ms / 1000)
# counts, m, mm need a constant
ANGLE_TO_RAD = {
    "rad": 1.0,
    "deg": math.pi / 180.0,
    "rev": 2 * math.pi,
}
MAX_MAP_BYTES = 1 << 16

# default column names of each signal (the CSV contract and its unit-named aliases)
DEFAULT_NAMES = {
    "time": ["time", "time_s", "t", "t_s"],
    "voltage": ["voltage", "voltage_V", "voltage_v", "U_V", "u_V"],
    "shaft_angle": [
        "shaft_angle",
        "arm_angle",
        "shaft_angle_rad",
        "arm_angle_rad",
        "angle_rad",
        "arm_position_rad",
    ],
    "current": ["current", "current_A", "current_a", "I_A"],
}
# the counts-per-turn metadata lines other tools write
COUNTS_METADATA = ("counts_per_rev", "encoder_counts_per_rev", "encoder_counts", "cpr", "counts")


@dataclass(frozen=True)
class RecordingMap:
    """A validated ``[recording]`` table and where it was written."""

    table: dict
    source: str

    def get(self, key: str, default=None):
        return self.table.get(key, default)


def _check_table(table, source: str) -> dict:
    from mechanism.machine.description import SCHEMA, _check_table as check

    checked = check(source, "recording", table, SCHEMA["recording"])
    where = f"{source}: [recording]"
    if checked.get("direction") == 0:
        raise UserError(f"{where} direction: must be 1 or -1")
    unit = checked.get("shaft_angle_unit", "rad")
    if unit == "counts" and "counts_per_rev" not in checked:
        raise UserError(
            f'{where} shaft_angle_unit = "counts" needs counts_per_rev (encoder counts per shaft turn)'
        )
    if unit in ("m", "mm") and "travel_per_rev_mm" not in checked:
        raise UserError(
            f'{where} shaft_angle_unit = "{unit}" needs travel_per_rev_mm (travel per shaft turn: a screw\'s '
            "lead, a pulley's circumference)"
        )
    for key in ("time", "voltage", "shaft_angle", "current"):
        text = checked.get(key)
        if text is not None and _clearly_an_expression(text):
            # anything else may be a file's column: checked when read
            parse_expression(text, f"{where} {key}")
    return checked


def read_recording_map(path: str | os.PathLike) -> RecordingMap:
    """A ``--recording-map FILE.toml``: a ``[recording]`` table (bounded, every key checked)."""
    from mechanism.files.limits import read_bounded

    path = Path(path)
    source = f"recording map {path}"
    raw = read_bounded(path, "recording map", MAX_MAP_BYTES)
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"{source}: not valid TOML: {' '.join(str(exc).split())}") from None
    others = [k for k in data if k != "recording"]
    if "recording" not in data or others:
        raise UserError(
            f"{source}: expected one [recording] table"
            + (f", found {', '.join(others)}" if others else "")
        )
    return RecordingMap(_check_table(data["recording"], source), source)


def resolve_recording_map(
    description=None, map_path: str | os.PathLike | None = None
) -> RecordingMap | None:
    """The map file's table if given (it wins), else the description's ``[recording]``, else None."""
    if map_path is not None:
        return read_recording_map(map_path)
    if description is not None and description.section("recording"):
        where = (
            f"machine description {description.path}" if description.path else "machine description"
        )
        return RecordingMap(_check_table(description.section("recording"), where), where)
    return None


# -- expressions --------------------------------------------------------------------------------

_QUOTED = re.compile(r"`([^`]+)`")
_NOT_NAMES = (
    ast.BoolOp,
    ast.Compare,
    ast.Lambda,
    ast.IfExp,
    ast.NamedExpr,
    ast.Starred,
    ast.Dict,
    ast.Set,
    ast.List,
    ast.ListComp,
    ast.SetComp,
    ast.DictComp,
    ast.GeneratorExp,
    ast.JoinedStr,
    ast.Await,
    ast.Yield,
)


def _clearly_an_expression(text: str) -> bool:
    """True for text that cannot be a column name (``a + b``, ``x ** 2``, ``a if b else c``);
    a name with brackets or dots (``data(:,1)``, ``sig.x_screw``) waits for the file."""
    try:
        tree = ast.parse(_QUOTED.sub("x", text).strip(), mode="eval")
    except SyntaxError:
        return False  # "pwm (%)", "data(:,1)": a column's name, or an error naming the columns when read
    for node in ast.walk(tree):
        if isinstance(node, _NOT_NAMES):
            return True
        if isinstance(node, ast.BinOp) and not isinstance(node.op, (ast.Mult, ast.Div)):
            return True
        if isinstance(node, ast.Constant) and not isinstance(node.value, (int, float)):
            return True
    return False


def parse_expression(text: str, where: str) -> tuple[ast.Expression, dict[str, str]]:
    """The parsed expression and its placeholder -> column name table; UserError if it is not
    a product/quotient of columns and numbers."""
    names: dict[str, str] = {}

    def quote(match):
        key = f"_col{len(names)}_"
        names[key] = match.group(1)
        return key

    source = _QUOTED.sub(quote, text)
    try:
        tree = ast.parse(source.strip(), mode="eval")
    except SyntaxError:
        raise UserError(
            f"{where}: {text!r} is neither a column name nor an expression of columns and numbers "
            "(write a column name with other characters in `backquotes`)"
        ) from None
    for node in ast.walk(tree):
        if isinstance(
            node, (ast.Expression, ast.Name, ast.Load, ast.Mult, ast.Div, ast.USub, ast.UAdd)
        ):
            continue
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Mult, ast.Div)):
            continue
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            continue
        if (
            isinstance(node, ast.Constant)
            and isinstance(node.value, (int, float))
            and not isinstance(node.value, bool)
        ):
            continue
        if (
            isinstance(node, ast.Attribute) and _dotted(node) is not None
        ):  # data.position: a nested field's column
            continue
        raise UserError(
            f"{where}: {text!r}: only products and quotients of columns and numbers are allowed "
            f"(found {type(node).__name__.lower()})"
        )
    return tree, names


def _dotted(node) -> str | None:
    """``a.b.c`` for a chain of attribute names on a name, else None."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        base = _dotted(node.value)
        return None if base is None else f"{base}.{node.attr}"
    return None


def evaluate(
    text: str, columns: Columns, where: str, prepared: dict[str, np.ndarray]
) -> tuple[np.ndarray, list[str]]:
    """The expression's values and the columns it used."""
    if text in columns:
        return _column(columns, text, where, prepared), [text]
    tree, quoted = parse_expression(text, where)
    used: list[str] = []

    def value(node):
        if isinstance(node, ast.Expression):
            return value(node.body)
        if isinstance(node, ast.Constant):
            return float(node.value)
        if isinstance(node, (ast.Name, ast.Attribute)):
            name = (
                quoted.get(node.id, node.id) if isinstance(node, ast.Name) else str(_dotted(node))
            )
            if name not in columns:
                raise UserError(
                    f"{where}: no column {name!r} in {columns.label}; did you mean "
                    f"{close_matches(name, columns.names)}? (columns: {', '.join(columns.names[:20])})"
                )
            used.append(name)
            return _column(columns, name, where, prepared)
        if isinstance(node, ast.UnaryOp):
            inner = value(node.operand)
            return -inner if isinstance(node.op, ast.USub) else inner
        left, right = value(node.left), value(node.right)
        if isinstance(node.op, ast.Mult):
            return left * right
        if (
            isinstance(right, np.ndarray)
            and np.any(right == 0)
            or (not isinstance(right, np.ndarray) and right == 0)
        ):
            raise UserError(f"{where}: {text!r} divides by zero")
        return left / right

    result = value(tree)
    if not isinstance(result, np.ndarray):
        raise UserError(f"{where}: {text!r} names no column")
    lengths = {name: columns.length(name) for name in used}
    if len(set(lengths.values())) > 1:
        raise UserError(
            f"{where}: {text!r} combines columns of different lengths ({', '.join(f'{k} {v}' for k, v in lengths.items())})"
        )
    return np.asarray(result, dtype=float), used


def _column(columns: Columns, name: str, where: str, prepared: dict[str, np.ndarray]) -> np.ndarray:
    name = columns.find(name) or name
    if name not in prepared:
        prepared[name] = columns.numeric(name)
    return prepared[name]


def _signed(values: np.ndarray, bits: int, label: str) -> np.ndarray:
    span = float(2**bits)
    bad = (values != np.round(values)) | (values < 0) | (values >= span)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise UserError(
            f"{label}: value {i + 1} is {values[i]:g}, not an unsigned {bits}-bit register value (0 to {span - 1:.0f})"
        )
    return np.where(values >= span / 2, values - span, values)


# -- applying a map -----------------------------------------------------------------------------


@dataclass
class Signals:
    """Time [s], voltage [V], shaft angle [rad], optional current [A], and what was done."""

    time_s: np.ndarray
    voltage_V: np.ndarray
    shaft_angle_rad: np.ndarray
    current_A: np.ndarray | None
    unwrap: bool | None
    metadata: dict
    reading: dict


def _default_column(columns: Columns, signal: str, motor_joint: str | None = None) -> str | None:
    names = DEFAULT_NAMES[signal] + (
        [f"{motor_joint}_V"] if signal == "voltage" and motor_joint else []
    )
    return next((name for name in names if name in columns), None)


def apply_map(
    columns: Columns, mapping: RecordingMap | None, motor_joint: str | None = None
) -> Signals:
    """The four signals out of a file's columns by the map (or the default names)."""
    table = mapping.table if mapping else {}
    where = f"{mapping.source}: [recording]" if mapping else columns.label
    label = columns.label
    prepared: dict[str, np.ndarray] = {}
    reading: dict = {
        "file_format": columns.format + (columns.compression or ""),
        "map": mapping.source if mapping else "none: the default column names",
        "columns_found": columns.names[:200],
    }
    for name, bits in table.get("signed_bits", {}).items():
        if name not in columns:
            raise UserError(
                f"{where} signed_bits: no column {name!r} in {label}; did you mean {close_matches(name, columns.names)}?"
            )
        prepared[columns.find(name) or name] = _signed(
            columns.numeric(name), bits, f"{label}: column {name} (signed_bits {bits})"
        )
    if table.get("signed_bits"):
        reading["signed_bits"] = dict(table["signed_bits"])

    def signal(key: str, required: bool = True):
        text = table.get(key) or _default_column(columns, key, motor_joint)
        if text is None:
            if not required:
                return None, None
            hint = (
                f'write [recording] {key} = "COLUMN" in a --recording-map FILE.toml or the machine description'
                if not mapping
                else f'add {key} = "COLUMN" to {mapping.source}'
            )
            shown = "arm_angle (or shaft_angle)" if key == "shaft_angle" else key
            raise UserError(
                f"{label}: missing required column(s) {shown}; columns found: "
                f"{', '.join(columns.names[:20]) or 'none'}; {hint}"
            )
        values, _ = evaluate(text, columns, f"{where} {key}" if key in table else label, prepared)
        return values, text

    time, time_from = signal("time")
    time_unit = table.get("time_unit", "s")
    reading["time_s"] = {"from": time_from, "unit": time_unit}
    if (
        len(time) and abs(time[0] / TIME_PER_S[time_unit]) > 1e6
    ):  # epoch time stamps: seconds from the first sample
        reading["time_s"]["shifted_by_s"] = float(-time[0] / TIME_PER_S[time_unit])
        time = time - time[0]
    time = time / TIME_PER_S[time_unit]
    voltage, voltage_from = signal("voltage")
    reading["voltage_V"] = {"from": voltage_from, "unit": "V"}
    angle, angle_from = signal("shaft_angle")
    unit = table.get("shaft_angle_unit", "rad")
    counts = table.get("counts_per_rev")
    if unit == "counts":
        factor = 2 * math.pi / table["counts_per_rev"]  # _check_table: "counts" comes with it
    elif unit in ("m", "mm"):
        millimetres = 1.0 if unit == "mm" else 1e3
        factor = 2 * math.pi * millimetres / table["travel_per_rev_mm"]
    else:
        factor = ANGLE_TO_RAD[unit]
    angle = angle * factor
    unwrap = table.get("unwrap")
    angle_reading: dict = {"from": angle_from, "unit": unit, "rad_per_unit": factor}
    if unit in ("m", "mm"):
        angle_reading["travel_per_rev_mm"] = table["travel_per_rev_mm"]
    if unwrap:
        before = angle
        angle = np.unwrap(angle)
        angle_reading["unwrapped"] = (
            f"yes: {int(np.count_nonzero(np.abs(np.diff(before)) > math.pi))} jump(s) of more than pi removed"
        )
    elif unwrap is False:
        angle_reading["unwrapped"] = "no (unwrap = false)"
    direction = table.get("direction", 1)
    offset = table.get("offset_rad", 0.0)
    angle = direction * angle + offset
    angle_reading.update(
        direction=direction,
        offset_rad=offset,
        formula=f"shaft_angle_rad = {direction} * ({angle_from}) * {factor:.10g} + {offset:g}",
    )
    reading["shaft_angle_rad"] = angle_reading
    current, current_from = signal("current", required=False)
    if current is not None:
        reading["current_A"] = {"from": current_from, "unit": "A"}
    metadata = dict(columns.metadata)
    for key in COUNTS_METADATA:  # other tools' names for the encoder resolution
        if key in metadata and "counts_per_rev" not in metadata:
            metadata["counts_per_rev"] = metadata[key]
    if counts is not None:
        metadata["counts_per_rev"] = str(counts)
    lengths = {"time": len(time), "voltage": len(voltage), "shaft_angle": len(angle)}
    if current is not None:
        lengths["current"] = len(current)
    if len(set(lengths.values())) > 1:
        raise UserError(
            f"{label}: the mapped signals have different lengths ({', '.join(f'{k} {v}' for k, v in lengths.items())})"
        )
    return Signals(time, voltage, angle, current, unwrap, metadata, reading)
