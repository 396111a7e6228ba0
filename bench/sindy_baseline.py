"""A plain sparse-regression discovery baseline (SINDy-style) on the same effect library.

What a careful engineer would try first: differentiate the measured velocity numerically,
write the drive equation as a regression of the motor torque on a library of candidate
terms, and keep the terms that survive sequentially thresholded least squares (STLSQ,
Brunton et al. 2016). The library is the diagnosis's own effect library: each effect's
torque columns at its first grid point (its non-linear parameters fixed, since a linear
regression cannot fit them); the sensor error and the belt have no torque form, so they get
their first-order equivalents (the velocity error seen through J d/dt + c, and a jerk term).
An effect is named when its surviving columns explain at least ``SHARE`` of the torque the
baseline terms leave unexplained.
"""

from __future__ import annotations

import numpy as np

from mechanism.sysid.effects import library as effect_library
from mechanism.sysid.identification import ModelStructure, Problem, torque_balance
from mechanism.sysid.lumped_baseline import LumpedBaseline
from mechanism.sysid.recording import Recording, smoothed_velocity

THRESHOLD = 0.02  # on coefficients of unit-variance columns, relative to the target's std
SHARE = 0.05


def library(problem: Problem) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(target torque, columns, the effect each column belongs to) on moving samples."""
    s = problem.signals
    w = s.velocity_rad_s
    acc = smoothed_velocity(w, s.dt)
    jerk = smoothed_velocity(acc, s.dt)
    # moving samples away from voltage steps (where the numerical acceleration and the
    # winding lag dominate any regression on it)
    near_step = np.zeros(len(w), bool)
    for k in np.flatnonzero(np.abs(np.diff(s.voltage_V)) > 0.5):
        near_step[max(0, k - 20) : k + 60] = True
    sel = np.flatnonzero((np.abs(w) > 1.0) & ~near_step)[::2]
    base = LumpedBaseline(problem.nominal)
    values = {p.name: p.nominal for p in base.parameters}
    structure = ModelStructure(base)
    motor = base.motor(values)
    # the motor torque at zero speed is the target; back-emf and viscous damping are one
    # column (w), so that a torque gain unlike the datasheet's scales every coefficient alike
    target = motor.gain_arm * structure.drive(values, s).voltage_V
    columns = [acc, w, np.sign(w)]
    owners = ["baseline"] * 3
    for effect in effect_library(problem.nominal).values():
        if effect.linear is not None:
            st = structure.with_effect(effect)
            shape = effect.grid(s, None)[0]
            v0 = {
                **values,
                **{p.name: p.nominal for p in effect.parameters},
                **shape,
                **{n: 0.0 for n in effect.linear},
            }
            b0 = torque_balance(st.drive(v0, s), motor, w, acc)
            for name in effect.linear:
                if name == "supply_linear_V":
                    continue  # the same column as the motor gain
                step = next(p for p in effect.parameters if p.name == name).typical
                columns.append(
                    (b0 - torque_balance(st.drive({**v0, name: step}, s), motor, w, acc)) / step
                )
                owners.append(effect.name)
    c = motor.emf_damping_arm
    j = values["inertia_motor_side_kgm2"] * s.ratio**2
    for k in ("cos", "sin"):  # sensor error e w cos(theta): seen as a torque through J d/dt + c
        err = w * s.harmonic(1, k)
        columns.append(j * smoothed_velocity(err, s.dt) + c * err)
        owners.append("encoder_eccentricity")
    columns.append(jerk)  # an elastic belt adds a jerk term to first order
    owners.append("belt_compliance")
    # an angle logged d late reads w - d w': seen as a torque through J d/dt + c (backlash, a
    # dead zone, has no such linear column: the sparse regression cannot express it)
    columns.append(j * jerk + c * acc)
    owners.append("sensor_delay")
    X = np.column_stack(columns)[sel]
    return target[sel], X, owners


def stlsq(X: np.ndarray, y: np.ndarray, threshold: float, iterations: int = 10) -> np.ndarray:
    """Sequentially thresholded least squares on standardised columns."""
    scale = X.std(axis=0)
    scale[scale == 0] = 1.0
    Z = X / scale
    keep = np.ones(X.shape[1], bool)
    coef = np.zeros(X.shape[1])
    for _ in range(iterations):
        coef[:] = 0.0
        coef[keep] = np.linalg.lstsq(Z[:, keep], y, rcond=None)[0]
        small = np.abs(coef) < threshold * y.std()
        small[:3] = False  # the baseline terms always stay
        if not np.any(small & keep):
            break
        keep &= ~small
    return coef / scale


def discover(rec: Recording, nominal) -> list[str]:
    """Effect names the sparse regression keeps for this recording."""
    problem = Problem(rec, nominal)
    y, X, owners = library(problem)
    coef = stlsq(X, y, THRESHOLD)
    base = np.array([o == "baseline" for o in owners])
    residual_after_baseline = y - X[:, base] @ np.linalg.lstsq(X[:, base], y, rcond=None)[0]
    unexplained = float(np.var(residual_after_baseline))
    named = []
    for name in dict.fromkeys(o for o in owners if o != "baseline"):
        cols = np.array([o == name for o in owners])
        part = X[:, cols] @ coef[cols]
        if np.any(coef[cols]) and np.var(part) >= SHARE * unexplained:
            named.append(name)
    return named
