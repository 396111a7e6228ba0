"""Motor voltage inputs: constant, a profile from CSV, or a PWM duty cycle.

A PWM power switch does not convert duty to voltage linearly (the thesis's BTS 133 on 24 V:
-6.7 % at 20 % duty, +4.1 % at 50 %), so a duty cycle is mapped to the motor terminal
voltage by a :class:`DutyMap` of measured points, which a machine's description gives
(``[supply] duty_percent`` and ``motor_voltage_V``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from mechanism.errors import UserError
from mechanism.files.tables import check_increasing, read_table

DEFAULT_RATED_VOLTAGE_V = 30.0  # a motor that states no [motor] rated_voltage_V
MAX_VOLTAGE_V = 1000.0  # any input beyond this is a typo, whatever the motor


def _check_voltage(values, label: str, high: float = MAX_VOLTAGE_V) -> None:
    values = np.atleast_1d(values)
    bad = np.flatnonzero(~((values >= 0.0) & (values <= high)))  # NaN fails both
    if bad.size:
        raise UserError(f"{label}: voltage {values[bad[0]]:g} V is outside 0-{high:g} V")


def check_rated_voltage(voltage: "VoltageProfile", rated_V: float, where: str) -> None:
    """A voltage input within what the described motor is rated for, either way round (``where``
    names the key)."""
    values = np.atleast_1d(voltage.voltage_V)
    bad = np.flatnonzero(~(np.abs(values) <= rated_V))  # NaN fails
    if bad.size:
        span = f"-{rated_V:g} to {rated_V:g}" if np.any(values < 0) else f"0-{rated_V:g}"
        raise UserError(
            f"motor voltage (rated {rated_V:g} V by {where}): voltage {values[bad[0]]:g} V is outside {span} V"
        )


@dataclass(frozen=True)
class DutyMap:
    """Measured (duty %, motor V) points of a PWM supply, interpolated linearly."""

    duty_percent: np.ndarray
    motor_voltage_V: np.ndarray

    def __call__(self, duty_percent: float) -> float:
        if not 0 <= duty_percent <= 100:  # NaN too
            raise UserError(f"duty cycle must be between 0 and 100 %, got {duty_percent:g}")
        return float(np.interp(duty_percent, self.duty_percent, self.motor_voltage_V))


@dataclass(frozen=True)
class VoltageProfile:
    """Piecewise-constant voltage: ``voltage_V[i]`` holds from ``time_s[i]`` to the next time
    (zero-order hold, as a logged command); before the first time the first value holds."""

    time_s: np.ndarray
    voltage_V: np.ndarray

    def __call__(self, t):
        index = np.searchsorted(self.time_s, t, side="right") - 1
        return self.voltage_V[np.clip(index, 0, len(self.voltage_V) - 1)]

    @property
    def end_s(self) -> float:
        return float(self.time_s[-1])

    @classmethod
    def constant(cls, voltage_V: float) -> "VoltageProfile":
        _check_voltage(voltage_V, "--voltage")
        return cls(np.array([0.0]), np.array([float(voltage_V)]))

    @classmethod
    def from_duty(cls, duty_percent: float, duty_map: DutyMap) -> "VoltageProfile":
        return cls.constant(duty_map(duty_percent))

    @classmethod
    def from_csv(cls, path: str | os.PathLike) -> "VoltageProfile":
        table = read_table(
            path,
            required=["time", "voltage"],
            aliases={"time": ["time_s"], "voltage": ["voltage_V"]},
            what="voltage profile",
        )
        check_increasing(table["time"], table.source)
        _check_voltage(table["voltage"], table.source)
        if table["time"][0] < 0:
            raise UserError(f"{table.source}: times must not be negative")
        return cls(table["time"], table["voltage"])


MOTOR_INPUT_RANGES = {"V": (-1e3, 1e3), "rad": (-1e4, 1e4), "A": (-1e4, 1e4)}


def read_motor_profiles(
    path: str | os.PathLike, units: dict[str, str]
) -> dict[str, VoltageProfile]:
    """Per-motor inputs from a profile CSV: ``time_s`` (or ``time``) and one column per motor
    named ``JOINT_V`` (dc), ``JOINT_rad`` (servo goal) or ``JOINT_A`` (current command), each
    held until the next time. A motor without a column is left out (its default input holds)."""
    names = {joint: f"{joint}_{unit}" for joint, unit in units.items()}
    table = read_table(
        path,
        required=["time"],
        optional=list(names.values()),
        aliases={"time": ["time_s"]},
        what="input profile",
    )
    check_increasing(table["time"], table.source)
    if table["time"][0] < 0:
        raise UserError(f"{table.source}: times must not be negative")
    out = {}
    for joint, column in names.items():
        if column not in table.columns:
            continue
        values = np.asarray(table[column], dtype=float)
        low, high = MOTOR_INPUT_RANGES[units[joint]]
        bad = np.flatnonzero(~((values >= low) & (values <= high)))
        if bad.size:
            raise UserError(
                f"{table.source}: {column} {values[bad[0]]:g} {units[joint]} is outside {low:g} to {high:g}"
            )
        out[joint] = VoltageProfile(np.asarray(table["time"], dtype=float), values)
    if not out:
        raise UserError(
            f"{table.source}: missing required column: voltage_V (the main motor) or one input column per "
            f"motor ({', '.join(names.values())})"
        )
    return out


def parse_joint_values(texts, option: str, unit: str, joints: dict[str, str]) -> dict[str, float]:
    """``JOINT=VALUE`` options (``--voltage``, ``--goal``, ``--current``) for the motors whose
    input is in ``unit`` (``joints``: joint -> its input unit)."""
    from mechanism.errors import close_matches

    out = {}
    for text in texts:
        joint, sep, value = str(text).rpartition("=")
        if not sep or not joint:
            raise UserError(f"{option} {text!r}: expected JOINT=VALUE in {unit}")
        if joint not in joints:
            raise UserError(
                f"{option} {text!r}: no motor on joint {joint!r}; close matches: {close_matches(joint, list(joints))}"
            )
        if joints[joint] != unit:
            wanted = {"V": "--voltage", "rad": "--goal", "A": "--current"}[joints[joint]]
            raise UserError(
                f"{option} {text!r}: the motor on {joint} takes {joints[joint]} ({wanted} {joint}=...)"
            )
        try:
            number = float(value)
        except ValueError:
            raise UserError(f"{option} {text!r}: {value!r} is not a number of {unit}") from None
        low, high = MOTOR_INPUT_RANGES[unit]
        if not low <= number <= high:
            raise UserError(f"{option} {text!r}: {number:g} {unit} is outside {low:g} to {high:g}")
        out[joint] = number
    return out
