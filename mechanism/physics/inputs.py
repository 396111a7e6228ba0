"""Motor voltage inputs: constant, a profile from CSV, or a PWM duty cycle.

The thesis drove the motor from 24 V through a BTS 133 low-side switch with PWM; the
conversion was not linear (Table 2's error column: -6.7 % at 20 % duty, +4.1 % at 50 %).
:func:`pwm_voltage` maps a duty cycle to the motor terminal voltage by interpolating
measured points:

- Table 2's motor voltages from 20 to 100 % duty;
- below 20 %, two points inferred from the thesis's start observations (5.2.1-5.2.2): the
  machine started at 12 % duty in its lowest-friction position and at 14 % in its highest,
  whose break-away torques were measured with a current drive (0.2384 and 0.2771 N m at the
  arm). At stall the motor voltage that gives a torque T at the arm is T R / (n Kt), so
  12 % -> 1.93 V and 14 % -> 2.24 V: far below the theoretical 24 V x duty (2.9-3.4 V), as
  a switch whose turn-on and turn-off times eat a large share of very short pulses would be.
- 0 V at 0 % duty.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from mechanism.errors import UserError
from mechanism.data.reference import thesis
from mechanism.files.tables import check_increasing, read_table

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


def start_duty_voltage() -> tuple[np.ndarray, np.ndarray]:
    """(duty %, motor V) at which the thesis's machine started, from its break-away torques."""
    ref = thesis()
    static, motor = ref["static_friction"], ref["main_motor"]
    ratio = ref["mechanism"]["motor_to_arm_ratio"]
    torques = np.array([static["lowest_breakaway_arm_Nm"], static["highest_breakaway_arm_Nm"]])
    duties = np.array([static["start_duty_cycle_percent"]["lowest_friction_position"],
                       static["start_duty_cycle_percent"]["highest_friction_position"]], dtype=float)
    return duties, torques * motor["resistance_ohm"] / (ratio * motor["torque_constant_Nm_per_A"])


def pwm_voltage(duty_percent: float) -> float:
    """Motor terminal voltage [V] for a PWM duty cycle [%] through the thesis's power switch."""
    if not 0 <= duty_percent <= 100:
        raise UserError(f"duty cycle must be between 0 and 100 %, got {duty_percent:g}")
    table_duty, table_volts = table2_duty_voltage()
    start_duty, start_volts = start_duty_voltage()
    duty = np.concatenate([[0.0], start_duty, table_duty])
    volts = np.concatenate([[0.0], start_volts, table_volts])
    return float(np.interp(duty_percent, duty, volts))


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
