"""The metrics of one sweep variant's run (``mechanism sweep``, docs/sweeps.md): speed, ripple,
settling, current, tool timing, break-away voltage and bearing loads, from a run from rest."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

if TYPE_CHECKING:  # the CLI's help lists METRICS without the simulator's imports
    from mechanism.dynamics.reduced import ReducedModel
    from mechanism.dynamics.simulation import SimulationResult
    from mechanism.machine.machine import Machine

TWO_PI = 2 * np.pi
SETTLING_BAND = 0.02  # settled: within the steady ripple band widened by 2 % of the mean speed
STEADY_CHANGE = 0.01  # the last two revolutions' mean speeds differ by less: steady state reached

METRICS = {
    "mean_speed_rpm": "mean shaft speed in steady state (the last revolution)",
    "ripple_pp_rad_s": "shaft speed peak to peak over the last revolution",
    "ripple_min_angle_deg": "shaft angle of the slowest point of the last revolution",
    "settling_s": "time from the voltage step until the speed stays in the steady ripple band (+/- 2 % of the mean)",
    "peak_current_A": "largest armature current of the run (the start)",
    "rms_current_A": "RMS armature current over the last revolution (heating in steady state)",
    "tool_above_plate_ms": "time per stitch (the last revolution) the tool is above the plate",
    "breakaway_V": "smallest constant motor voltage that starts the machine from rest at every shaft angle",
}


def variant_metrics(result: SimulationResult, reduced: ReducedModel) -> dict[str, Any]:
    """:data:`METRICS` of one run from rest (a voltage step at t = 0), plus a ``note`` when the
    run did not reach a steady state."""
    t, angle, speed = result.time_s, result.shaft_angle_rad, result.shaft_velocity_rad_s
    row: dict[str, Any] = {name: math.nan for name in METRICS}
    row["peak_current_A"] = float(np.max(np.abs(result.current_A)))
    row["breakaway_V"] = breakaway_voltage(reduced)
    notes = []
    last = np.flatnonzero(angle <= angle[-1] - TWO_PI)
    if not last.size or t[last[-1]] < t[-1] / 2:
        window = slice(int(len(t) * 0.75), None)
        row["mean_speed_rpm"] = float(np.mean(speed[window]) * 60 / TWO_PI)
        row["rms_current_A"] = float(np.sqrt(np.mean(result.current_A[window] ** 2)))
        row["note"] = (
            "no steady running: under one revolution in the second half of the run (stalled or too slow)"
        )
        return row
    start = int(last[-1]) + 1
    steady = slice(start, None)
    period = t[-1] - np.interp(angle[-1] - TWO_PI, angle[: start + 1], t[: start + 1])
    mean = TWO_PI / period
    row["mean_speed_rpm"] = float(mean * 60 / TWO_PI)
    low, high = float(np.min(speed[steady])), float(np.max(speed[steady]))
    row["ripple_pp_rad_s"] = high - low
    row["ripple_min_angle_deg"] = float(
        np.degrees(np.mod(angle[start + int(np.argmin(speed[steady]))], TWO_PI))
    )
    row["rms_current_A"] = float(np.sqrt(np.mean(result.current_A[steady] ** 2)))
    if np.isfinite(result.tool_z_mm).all():
        row["tool_above_plate_ms"] = (
            _time_above(t[start - 1 :], result.tool_z_mm[start - 1 :]) * 1e3
        )
    previous = np.flatnonzero(angle <= angle[-1] - 2 * TWO_PI)
    if previous.size:
        before = t[start - 1] - np.interp(angle[start - 1] - TWO_PI, angle[:start], t[:start])
        if abs(before - period) > STEADY_CHANGE * period:
            notes.append(
                f"not steady: the last two revolutions differ by {abs(before - period) / period:.1%}"
            )
    band = SETTLING_BAND * mean
    outside = np.flatnonzero((speed[:start] < low - band) | (speed[:start] > high + band))
    if notes:
        row["settling_s"] = math.nan
    else:
        row["settling_s"] = float(t[outside[-1] + 1]) if outside.size else float(t[0])
    row["note"] = "; ".join(notes)
    return row


def _time_above(t: np.ndarray, height: np.ndarray) -> float:
    """Time a sampled height spends above 0, with the crossings interpolated linearly."""
    dt, low, high = np.diff(t), height[:-1], height[1:]
    both = (low > 0) & (high > 0)
    crossing = (low > 0) != (high > 0)
    share = np.where(
        crossing, np.maximum(low, high) / np.maximum(np.abs(low) + np.abs(high), 1e-300), 0.0
    )
    return float(np.sum(dt[both]) + np.sum((dt * share)[crossing]))


def driven_inertia_kgm2(machine: Machine) -> float:
    """The shaft side's own inertia: the mean effective inertia at the shaft without the
    motor rotor's share (its axial inertia times its ratio squared): what a flywheel on
    the shaft is compared with."""
    import mujoco

    data = machine.reset(0.0)
    mass = np.zeros((machine.model.nv, machine.model.nv))
    mujoco.mj_fullM(machine.model, data, mass)
    rotor = mass[machine.motor_dof, machine.motor_dof]
    return float(machine.tables.mean_inertia_kgm2 - rotor * machine.motor_ratio**2)


def breakaway_voltage(reduced: ReducedModel) -> float:
    """The smallest constant motor voltage that starts the machine forward from rest at any
    shaft angle: static friction against the motor's stall torque, gravity and cogging (the
    integrator's own break-away test, solved for the voltage). NaN when the supply cannot."""
    angles = reduced.tables.angle_rad
    rest = np.zeros_like(angles)
    static = reduced.static_friction(angles)
    at_rest = reduced.generalized_force(angles, rest, rest)
    per_volt = reduced.generalized_force(angles, rest, rest + 1.0) - at_rest
    if np.any(per_volt <= 0):
        return math.nan
    needed = float(np.max((static - at_rest) / per_volt))
    # linear in the voltage until the supply limits the current: check the answer
    reached = reduced.generalized_force(angles, rest, rest + needed)
    return needed if np.all(reached - static >= -1e-9 * np.maximum(static, 1e-9)) else math.nan


def bearing_loads(result: SimulationResult, bearings: Sequence[str]) -> dict[str, float]:
    """Peak reaction force [N] at each bearing over the run's last revolution (the whole run
    when it never turned a revolution), from the ``bearing:<joint>`` force sensors."""
    if not bearings:
        return {}
    assert result.sensordata is not None
    machine_sensors = result.metadata.get("sensor_columns", {})
    angle = result.shaft_angle_rad
    last = np.flatnonzero(angle <= angle[-1] - TWO_PI)
    window = slice(int(last[-1]) + 1 if last.size else 0, None)
    out = {}
    for joint in bearings:
        column = machine_sensors[f"bearing:{joint}"]
        force = result.sensordata[window, column : column + 3]
        out[f"bearing_{joint}_peak_N"] = float(np.max(np.linalg.norm(force, axis=1)))
    return out
