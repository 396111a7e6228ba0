"""Motor voltage inputs: constant, a profile from CSV, or a PWM duty cycle.

The thesis drove the motor from 24 V through a BTS 133 low-side switch with PWM; the
conversion was not linear (Table 2's error column: -6.7 % at 20 % duty, +4.1 % at 50 %).
:func:`pwm_voltage` maps a duty cycle to the motor terminal voltage by interpolating
Table 2's measured motor voltages; below 20 % duty it extends the 20-30 % segment's
straight line (the trend of the error there), clipped at 0 V.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from mechanism.errors import UserError
from mechanism.reference import thesis
from mechanism.tables import check_increasing, read_table

VOLTAGE_RANGE_V = (0.0, 30.0)


def _check_voltage(values, label: str) -> None:
    values = np.atleast_1d(values)
    low, high = VOLTAGE_RANGE_V
    bad = np.flatnonzero((values < low) | (values > high))
    if bad.size:
        raise UserError(f"{label}: voltage {values[bad[0]]:g} V is outside {low:g}-{high:g} V")


def table2_duty_voltage() -> tuple[np.ndarray, np.ndarray]:
    table = thesis()["steady_state_speed_table_2"]
    columns = table["columns"]
    rows = np.array(table["rows"], dtype=float)
    return rows[:, columns.index("duty_percent")], rows[:, columns.index("motor_voltage_V")]


def pwm_voltage(duty_percent: float) -> float:
    """Motor terminal voltage [V] for a PWM duty cycle [%] through the thesis's power switch."""
    if not 0 <= duty_percent <= 100:
        raise UserError(f"duty cycle must be between 0 and 100 %, got {duty_percent:g}")
    duty, volts = table2_duty_voltage()
    if duty_percent >= duty[0]:
        return float(np.interp(duty_percent, duty, volts))
    slope = (volts[1] - volts[0]) / (duty[1] - duty[0])
    return float(max(0.0, volts[0] + slope * (duty_percent - duty[0])))


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
    def from_duty(cls, duty_percent: float) -> "VoltageProfile":
        return cls.constant(pwm_voltage(duty_percent))

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
