"""Calibrate the shipped machine's position-dependent friction against the thesis.

The CAD model carries gravity and inertia of the stitch-forming parts; what it cannot know is
how friction varies over the arm revolution. The thesis gives two kinds of evidence:

- at rest (5.2.1-5.2.2): break-away 0.2384 N m with the needle going down, 0.2771 N m just
  after bottom dead centre. Static friction plus the CAD gravity must span exactly that:
  two equations for the static level Fs and the static amplitude a_s;
- running (3.2.2-3.2.3, figs. 11-14): the arm-speed ripple over a revolution, from
  +/-1.4 rad/s at 2.2 V to +/-0.7 rad/s at 19.8 V, slowest at the needle's lowest position
  at low speed. The running amplitude a and the phase φ are fitted to those observations
  (log-ratio least squares) with the reduced model.

``python -m mechanism.sysid.calibration`` prints the shaft's friction table for the shipped
description (mechanism/models/sapphire870/sapphire870.toml); tests/test_dynamics.py checks
the description against the thesis.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import brentq, least_squares

from mechanism.machine.machine import Machine, MachineConfig, friction_law, resolve_description
from mechanism.dynamics.reduced import ReducedModel
from mechanism.data.reference import thesis

TWO_PI = 2 * np.pi


def ripple(result, last_s: float = 3.0, bins: int = 72) -> tuple[float, float]:
    """(half peak-to-peak of the phase-averaged arm speed [rad/s], arm angle of its minimum [deg])."""
    window = result.window(last_s)
    speed = result.arm_velocity_rad_s[window]
    angle = np.mod(result.arm_angle_rad[window], TWO_PI)
    index = np.minimum((angle / TWO_PI * bins).astype(int), bins - 1)
    profile = np.bincount(index, speed, bins) / np.maximum(np.bincount(index, minlength=bins), 1)
    return float(np.ptp(profile) / 2), float(np.degrees((np.argmin(profile) + 0.5) * TWO_PI / bins))


def ripple_observations() -> list[tuple[float, float]]:
    """(voltage V, +/- arm-speed ripple rad/s) from the thesis's figures."""
    rows = []
    for item in thesis()["velocity_ripple_observations"]:
        if "voltage_V" not in item:
            continue
        if "ripple_rad_per_s" in item:
            rows.append((item["voltage_V"], item["ripple_rad_per_s"]))
        else:
            rows.append((item["voltage_V"], (item["rpm_max"] - item["rpm_min"]) / 2 * TWO_PI / 60))
    return rows


def _laws(amplitude, phase_rad, static=None, static_amplitude=None, description=None):
    """The described friction with the shaft's position dependence replaced."""
    description = resolve_description(description)
    laws = {joint: friction_law(values) for joint, values in description.friction.items()}
    changes = dict(position_amplitude=amplitude, position_phase_rad=phase_rad)
    if static is not None:
        changes.update(static=static, static_position_amplitude=static_amplitude)
    shaft = description.shaft_joint
    laws[shaft] = dataclasses.replace(laws.get(shaft, friction_law({})), **changes)
    return laws


def fit_running(description=None, start=(0.2, np.deg2rad(160.0))) -> tuple[float, float]:
    """Running amplitude and phase [rad] that best reproduce the thesis's ripple observations."""
    observations = ripple_observations()

    def residual(x):
        reduced = ReducedModel(Machine(description, MachineConfig(friction=_laws(x[0], x[1], description=description))))
        return [np.log(ripple(reduced.simulate(v, 8.0))[0] / r) for v, r in observations]

    fit = least_squares(residual, start, bounds=([0.0, 0.0], [0.6, TWO_PI]), diff_step=0.02)
    return float(fit.x[0]), float(fit.x[1])


def fit_static(amplitude, phase_rad, description=None) -> tuple[float, float]:
    """Static level Fs and amplitude a_s so that static friction + CAD gravity span the
    thesis's lowest and highest break-away torques."""
    data = thesis()["static_friction"]
    low, high = data["lowest_breakaway_arm_Nm"], data["highest_breakaway_arm_Nm"]

    def spread(static, static_amplitude):
        reduced = ReducedModel(Machine(description, MachineConfig(
            friction=_laws(amplitude, phase_rad, static, static_amplitude, description))))
        total = [reduced.static_friction(a) for a in reduced.tables.angle_rad] + reduced.tables.gravity_torque_Nm
        return float(np.min(total)), float(np.max(total))

    static = (low + high) / 2
    for _ in range(4):  # alternate: the amplitude fixes the ratio, the level fixes the scale
        a_s = brentq(lambda a: (lambda lo_hi: lo_hi[1] / lo_hi[0] - high / low)(spread(static, a)), 0.0, 0.5)
        lo, _ = spread(static, a_s)
        static *= low / lo
    return static, a_s


def main() -> None:
    amplitude, phase = fit_running()
    static, static_amplitude = fit_static(amplitude, phase)
    shaft = resolve_description(None).shaft_joint
    kinetic = thesis()["identified_parameters"]["kinetic_friction_arm_Nm"]
    print(f'[friction."{shaft}"]   # for the shipped description')
    print(f"static_Nm = {static:.4f}   # {(static / kinetic - 1) * 100:.1f} % above kinetic")
    print(f"position_amplitude = {amplitude:.3f}")
    print(f"static_position_amplitude = {static_amplitude:.4f}")
    print(f"position_phase_deg = {np.degrees(phase):.1f}")
    reduced = ReducedModel(Machine(None, MachineConfig(friction=_laws(amplitude, phase, static, static_amplitude))))
    for v, r in ripple_observations():
        amp, where = ripple(reduced.simulate(v, 8.0))
        print(f"  {v:5.1f} V: ripple +/-{amp:.2f} rad/s (thesis {r:.2f}), slowest at {where:.0f} deg")


if __name__ == "__main__":
    main()
