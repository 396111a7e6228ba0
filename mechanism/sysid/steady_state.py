"""Steady-state identification: friction from constant-voltage speed points (thesis Table 2).

At a constant speed the lumped model (arm side) balances

    n Kt/R (U - Ke n w) = c w + Fc,        c = n^2 d (viscous, d motor side)

so each (voltage, speed) point is one linear equation in the viscous and Coulomb friction;
two or more points at different voltages give both by linear least squares (one point
cannot: that is why a constant-voltage recording is not identifiable). The thesis's
Table 2 gives cold, warm-30 s and warm-2 min speeds at six voltages, and its model is
stated valid to 20 V: :func:`table2` fits each column on the 4.5-19.6 V points and
asks what the 24 V point says is missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mechanism.errors import UserError
from mechanism.dynamics.lumped import MotorConstants

RPM = 2 * math.pi / 60


@dataclass
class SteadyStateFit:
    viscous_motor_side_Nm_s_per_rad: float
    coulomb_arm_Nm: float
    viscous_sigma: float
    coulomb_sigma: float
    rms_torque_residual_Nm: float
    motor: MotorConstants

    def speed_rpm(self, voltage_V) -> np.ndarray:
        """Predicted arm speed [rpm] (0 where the motor cannot overcome Coulomb friction)."""
        m = self.motor
        c = m.emf_damping_arm + m.ratio**2 * self.viscous_motor_side_Nm_s_per_rad
        w = (m.gain_arm * np.asarray(voltage_V, float) - self.coulomb_arm_Nm) / c
        return np.maximum(w, 0.0) / RPM

    def voltage_for(self, speed_rpm: float) -> float:
        """The motor voltage that gives ``speed_rpm`` in this model."""
        m = self.motor
        w = speed_rpm * RPM
        c = m.emf_damping_arm + m.ratio**2 * self.viscous_motor_side_Nm_s_per_rad
        return (c * w + self.coulomb_arm_Nm) / m.gain_arm


def fit_steady_state(voltage_V, arm_speed_rpm, motor: MotorConstants) -> SteadyStateFit:
    """Viscous (motor side) and Coulomb (arm side) friction from steady-state points."""
    u = np.asarray(voltage_V, float)
    w = np.asarray(arm_speed_rpm, float) * RPM
    if u.shape != w.shape or u.ndim != 1:
        raise UserError(
            "steady-state fit: voltages and speeds must be two lists of the same length"
        )
    if len(np.unique(np.round(u, 6))) < 2:
        raise UserError(
            "steady-state fit: at least two different voltages are needed to separate viscous from Coulomb friction"
        )
    available = motor.gain_arm * u - motor.emf_damping_arm * w  # torque left for friction [Nm]
    X = np.column_stack([w, np.ones_like(w)])
    coef, *_ = np.linalg.lstsq(X, available, rcond=None)
    r = available - X @ coef
    dof = max(len(u) - 2, 1)
    cov = np.linalg.inv(X.T @ X) * float(r @ r) / dof
    n2 = motor.ratio**2
    return SteadyStateFit(
        float(coef[0] / n2),
        float(coef[1]),
        float(math.sqrt(cov[0, 0]) / n2),
        float(math.sqrt(cov[1, 1])),
        float(math.sqrt(np.mean(r * r))),
        motor,
    )


@dataclass
class Table2Column:
    name: str
    fit: SteadyStateFit
    valid_voltage_V: np.ndarray
    valid_rpm: np.ndarray
    high_voltage_V: float
    high_rpm_measured: float
    high_rpm_predicted: float
    supply_deficit_V: float  # how much lower the motor voltage must be at the high point
    series_resistance_ohm: float  # the extra resistance that would cause that drop at that current
    extra_load_Nm: float  # or: the extra arm torque needed at the high point

    def to_json(self) -> dict:
        return {
            "viscous_motor_side_Nm_s_per_rad": self.fit.viscous_motor_side_Nm_s_per_rad,
            "viscous_sigma": self.fit.viscous_sigma,
            "coulomb_arm_Nm": self.fit.coulomb_arm_Nm,
            "coulomb_sigma": self.fit.coulomb_sigma,
            "rpm_at_%gV_measured" % self.high_voltage_V: self.high_rpm_measured,
            "rpm_at_%gV_predicted" % self.high_voltage_V: self.high_rpm_predicted,
            "supply_deficit_V": self.supply_deficit_V,
            "series_resistance_ohm": self.series_resistance_ohm,
            "extra_load_Nm": self.extra_load_Nm,
        }


def table2(table: dict, motor: MotorConstants, valid_below_V: float) -> dict[str, Table2Column]:
    """Fit each speed column of a Table-2-like table (the thesis's: cold, warm 30 s, warm
    2 min; ``columns`` and ``rows``) on the points up to ``valid_below_V`` and quantify the
    highest-voltage point."""
    cols = table["columns"]
    rows = np.array(table["rows"], dtype=float)
    voltage = rows[:, cols.index("motor_voltage_V")]
    valid = voltage <= valid_below_V
    high = int(np.argmax(voltage))
    out = {}
    for name in ("rpm_cold", "rpm_warm_30s", "rpm_warm_2min"):
        rpm = rows[:, cols.index(name)]
        fit = fit_steady_state(voltage[valid], rpm[valid], motor)
        predicted = float(fit.speed_rpm(voltage[high]))
        needed = fit.voltage_for(rpm[high])
        deficit = float(voltage[high] - needed)
        w = rpm[high] * RPM
        current = (needed - motor.back_emf_V_s_per_rad * motor.ratio * w) / motor.resistance_ohm
        c = motor.emf_damping_arm + motor.ratio**2 * fit.viscous_motor_side_Nm_s_per_rad
        extra = float(motor.gain_arm * voltage[high] - c * w - fit.coulomb_arm_Nm)
        out[name.removeprefix("rpm_")] = Table2Column(
            name.removeprefix("rpm_"),
            fit,
            voltage[valid],
            rpm[valid],
            float(voltage[high]),
            float(rpm[high]),
            predicted,
            deficit,
            float(deficit / current),
            extra,
        )
    return out
