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

The thesis's steady speeds after warming (Table 2, 30 s and 2 min) and at the supply's full
24 V say what the thesis's viscous-only warm-up leaves out: warming lowers the Coulomb level,
and the supply cannot hold 24 V on the motor under load. :func:`fit_warming_and_supply` fits
both (``python -m mechanism.sysid.calibration --steady-speeds``).

``python -m mechanism.sysid.calibration`` prints the shaft's friction table for the shipped
description (assets/machines/sapphire870.toml); tests/test_dynamics.py checks
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
    """(half peak-to-peak of the phase-averaged shaft speed [rad/s], shaft angle of its minimum [deg])."""
    window = result.window(last_s)
    speed = result.shaft_velocity_rad_s[window]
    angle = np.mod(result.shaft_angle_rad[window], TWO_PI)
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
        reduced = ReducedModel(
            Machine(description, MachineConfig(friction=_laws(x[0], x[1], description=description)))
        )
        return [np.log(ripple(reduced.simulate(v, 8.0))[0] / r) for v, r in observations]

    fit = least_squares(residual, start, bounds=([0.0, 0.0], [0.6, TWO_PI]), diff_step=0.02)
    return float(fit.x[0]), float(fit.x[1])


def fit_static(amplitude, phase_rad, description=None) -> tuple[float, float]:
    """Static level Fs and amplitude a_s so that static friction + CAD gravity span the
    thesis's lowest and highest break-away torques."""
    data = thesis()["static_friction"]
    low, high = data["lowest_breakaway_arm_Nm"], data["highest_breakaway_arm_Nm"]

    def spread(static, static_amplitude):
        reduced = ReducedModel(
            Machine(
                description,
                MachineConfig(
                    friction=_laws(amplitude, phase_rad, static, static_amplitude, description)
                ),
            )
        )
        total = [
            reduced.static_friction(a) for a in reduced.tables.angle_rad
        ] + reduced.tables.gravity_torque_Nm
        return float(np.min(total)), float(np.max(total))

    static = (low + high) / 2
    for _ in range(4):  # alternate: the amplitude fixes the ratio, the level fixes the scale
        a_s = brentq(
            lambda a, level=static: (lambda lo_hi: lo_hi[1] / lo_hi[0] - high / low)(
                spread(level, a)
            ),
            0.0,
            0.5,
        )
        lo, _ = spread(static, a_s)
        static *= low / lo
    return static, a_s


def steady_speeds_table(description=None):
    """(motor V, warm s, measured rpm) rows of the machine's shipped steady-speed measurements."""
    from mechanism.files.tables import read_table

    description = resolve_description(description)
    table = read_table(
        description.model.parent / "measurements" / "steady_speeds.csv",
        required=["motor_voltage_V", "warm_s", "speed_rpm"],
    )
    return list(zip(table["motor_voltage_V"], table["warm_s"], table["speed_rpm"]))


def fit_warming_and_supply(description=None, start=(0.5, 0.05, 3.5e-5, 30.0)):
    """The supply's series resistance and the warm friction (shaft Coulomb, motor viscous, time
    constant) that best reproduce the steady speeds, cold friction kept; with 1-sigma errors.

    Reduced model, 6 s from rest, the mean speed of the last 2 s; log-ratio least squares over
    the warm columns and the cold point at the supply's full voltage (the cold column below it
    is the friction the description already has)."""
    from dataclasses import replace

    description = resolve_description(description)
    rows = steady_speeds_table(description)
    supply_V = description.section("supply")["voltage_V"]
    shaft, motor = description.shaft_joint, description.motor_joint
    cold = description.friction.get(shaft, {})
    static_ratio = cold.get("static_Nm", cold.get("coulomb_Nm", 1.0)) / max(
        cold.get("coulomb_Nm", 1.0), 1e-12
    )
    used = [row for row in rows if row[1] > 0 or row[0] >= supply_V]
    scales = np.array([1.0, 0.1, 1e-5, 30.0])

    def variant(x):
        rs, coulomb, viscous, tau = x * scales
        sections = {
            **description.sections,
            "supply": {**description.section("supply"), "series_resistance_ohm": rs},
            "warm": {"time_constant_s": tau},
        }
        warm = {
            motor: {"viscous_Nm_s_per_rad": viscous},
            shaft: {"coulomb_Nm": coulomb, "static_Nm": coulomb * static_ratio},
        }
        return replace(description, sections=sections, warm_friction=warm)

    def residual(x):
        changed = variant(x)
        out = []
        for volts, warm_s, measured in used:
            reduced = ReducedModel(
                Machine(changed, MachineConfig(needle=False, warm_s=float(warm_s)))
            )
            run = reduced.simulate(float(volts), 6.0)
            out.append(
                np.log(run.shaft_velocity_rad_s[run.window(2.0)].mean() * 60 / TWO_PI / measured)
            )
        return np.array(out)

    fit = least_squares(
        residual,
        np.array(start) / scales,
        bounds=([0, 0, 0.05, 0.03], [20, 2, 20, 20]),
        diff_step=1e-3,
    )
    dof = max(1, len(fit.fun) - len(fit.x))
    covariance = np.linalg.pinv(fit.jac.T @ fit.jac) * float(fit.fun @ fit.fun) / dof
    return fit.x * scales, np.sqrt(np.diag(covariance)) * scales, fit.fun


def main() -> None:
    import sys

    if "--steady-speeds" in sys.argv:
        values, errors, residual = fit_warming_and_supply()
        names = (
            "[supply] series_resistance_ohm",
            "[warm_friction.shaft] coulomb_Nm",
            "[warm_friction.motor] viscous_Nm_s_per_rad",
            "[warm] time_constant_s",
        )
        for name, value, error in zip(names, values, errors):
            print(f"{name} = {value:.4g}   # +/- {error:.2g}")
        print("residuals [%]:", " ".join(f"{100 * r:+.1f}" for r in residual))
        return
    amplitude, phase = fit_running()
    static, static_amplitude = fit_static(amplitude, phase)
    shaft = resolve_description(None).shaft_joint
    kinetic = thesis()["identified_parameters"]["kinetic_friction_arm_Nm"]
    print(f'[friction."{shaft}"]   # for the shipped description')
    print(f"static_Nm = {static:.4f}   # {(static / kinetic - 1) * 100:.1f} % above kinetic")
    print(f"position_amplitude = {amplitude:.3f}")
    print(f"static_position_amplitude = {static_amplitude:.4f}")
    print(f"position_phase_deg = {np.degrees(phase):.1f}")
    reduced = ReducedModel(
        Machine(None, MachineConfig(friction=_laws(amplitude, phase, static, static_amplitude)))
    )
    for v, r in ripple_observations():
        amp, where = ripple(reduced.simulate(v, 8.0))
        print(
            f"  {v:5.1f} V: ripple +/-{amp:.2f} rad/s (thesis {r:.2f}), slowest at {where:.0f} deg"
        )


if __name__ == "__main__":
    main()
