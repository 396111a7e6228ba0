"""The truth model's parameters: the thesis's lumped machine, randomised per seed, and the
concealed effects, each a small physical model with its own plausible ranges.

Every random draw comes from its own stream keyed by (seed, component), so switching an
effect on never changes the baseline, the voltage profile or another effect of the same
seed: a recording with an effect and the clean one of the same seed differ only by it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from mechanism.errors import UserError, close_matches

TWO_PI = 2.0 * math.pi
GRAVITY_M_S2 = 9.81
# the bench's default encoder (5000 lines, quadrature); an option per recording
ENCODER_COUNTS_PER_REV = 20000
ANGLE_STEP_RAD = TWO_PI / ENCODER_COUNTS_PER_REV


def stream(seed: int, component: str) -> np.random.Generator:
    """An independent random stream for one part of a recording."""
    key = [int(b) for b in component.encode()]
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, *key])


# --- geometry of the needle-bar slider-crank (own analytic form) ----------------------


def slider_height(theta, crank_m: float, rod_m: float):
    """Needle-bar (slider) height above the arm-shaft axis [m]; theta = 0 is top dead centre."""
    theta = np.asarray(theta, dtype=float)
    return crank_m * np.cos(theta) + np.sqrt(rod_m**2 - (crank_m * np.sin(theta)) ** 2)


def mean_square_slider_speed(crank_m: float, rod_m: float, samples: int = 4096) -> float:
    """Mean over a revolution of (dz/dtheta)^2 [m^2]: the linkage's share of the constant inertia."""
    theta = np.linspace(0.0, TWO_PI, samples, endpoint=False)
    s, c = np.sin(theta), np.cos(theta)
    dz = -crank_m * s - crank_m**2 * s * c / np.sqrt(rod_m**2 - (crank_m * s) ** 2)
    return float(np.mean(dz**2))


# --- baseline ------------------------------------------------------------------------


def draw_baseline(seed: int, nominal, randomize: bool = True) -> dict:
    """The lumped machine of the thesis (eq. 15-16) with the described drive's numbers
    (``nominal``, a :class:`~mechanism.dynamics.lumped.DriveNominal`), scattered per seed.

    Motor constants vary by a datasheet-like +-3 % (identification holds them at the
    datasheet values); inertia, viscous and Coulomb friction, which identification fits,
    vary by -25..+30 %. ``randomize=False`` gives the described values exactly (plus a
    winding time constant L/R of 6/11 ms, which the thesis neglects).
    """
    motor = nominal.motor
    n = nominal.ratio
    rng = stream(seed, "baseline")

    def scatter(low: float, high: float) -> float:
        value = rng.uniform(low, high)  # drawn even when not randomising: fixed stream layout
        return value if randomize else 1.0

    return {
        "resistance_ohm": motor.resistance_ohm * scatter(0.97, 1.03),
        "torque_constant_Nm_per_A": motor.torque_constant_Nm_per_A * scatter(0.97, 1.03),
        "back_emf_constant_V_s_per_rad": motor.back_emf_V_s_per_rad * scatter(0.97, 1.03),
        "inductance_H": 6 / 11 * 1e-3 * motor.resistance_ohm * scatter(0.35, 1.65),
        "belt_ratio": float(n),
        "inertia_motor_side_kgm2": nominal.inertia_motor_side_kgm2 * scatter(0.75, 1.3),
        "viscous_motor_side_Nm_s_per_rad": nominal.viscous_motor_side * scatter(0.75, 1.3),
        "coulomb_arm_Nm": nominal.torque_scale_Nm * scatter(0.75, 1.3),
        "supply_V": float(nominal.supply_V or 24.0),
        # the described (unscattered) scales that the effects' magnitudes are drawn against
        "nominal_coulomb_shaft_Nm": nominal.torque_scale_Nm,
        "nominal_inertia_shaft_kgm2": nominal.inertia_kgm2,
        "crank_radius_m": 0.016 * scatter(15 / 16, 17 / 16),
        "rod_length_m": 0.050 * scatter(0.8, 1.2),
    }


# --- concealed effects ------------------------------------------------------------------


@dataclass(frozen=True)
class Effect:
    """One concealed effect: its physics in a line, the ranges its magnitudes are drawn from
    (uniformly, per seed) and how a draw becomes its parameters."""

    name: str
    physics: str
    ranges: dict[str, tuple[float, float]]
    build: Callable[[Callable[[str], float], np.random.Generator, dict], dict]

    def draw(self, rng: np.random.Generator, baseline: dict) -> dict:
        return self.build(lambda key: float(rng.uniform(*self.ranges[key])), rng, baseline)


def _motor_side_coulomb(base: dict) -> float:
    return base["nominal_coulomb_shaft_Nm"] / base["belt_ratio"]


def _torque_ripple(u, rng, base):
    return {
        "once_per_motor_rev_Nm": u("once_per_motor_rev_per_motor_coulomb")
        * _motor_side_coulomb(base),
        "once_per_motor_rev_phase_rad": u("phase_rad"),
        "cogging_Nm": u("cogging_per_motor_coulomb") * _motor_side_coulomb(base),
        "cogging_per_motor_rev": 12,  # the Domel 482.501 has 12 poles (thesis 3.1.2)
        "cogging_phase_rad": u("phase_rad"),
    }


def _linkage_dynamics(u, rng, base):
    return {
        "reciprocating_mass_kg": u("reciprocating_mass_kg_per_kgm2")
        * base["nominal_inertia_shaft_kgm2"],
        "gravity_m_s2": GRAVITY_M_S2,
    }


def _position_friction(u, rng, base):
    peak_to_peak, second_share = u("peak_to_peak_fraction"), u("second_harmonic_share")
    params = {
        "first_harmonic_fraction": 1 - second_share,
        "first_harmonic_phase_rad": u("phase_rad"),
        "second_harmonic_fraction": second_share,
        "second_harmonic_phase_rad": u("phase_rad"),
    }
    scale = peak_to_peak / position_friction_shape(params)["peak_to_peak_fraction"]
    params["first_harmonic_fraction"] *= scale
    params["second_harmonic_fraction"] *= scale
    return params


def position_friction_shape(params: dict) -> dict:
    """Peak-to-peak fraction of the Coulomb level over a revolution and where it is highest."""
    theta = np.linspace(0, TWO_PI, 3600, endpoint=False)
    shape = params["first_harmonic_fraction"] * np.cos(
        theta - params["first_harmonic_phase_rad"]
    ) + params["second_harmonic_fraction"] * np.cos(2 * theta - params["second_harmonic_phase_rad"])
    return {
        "peak_to_peak_fraction": float(shape.max() - shape.min()),
        "highest_friction_arm_angle_rad": float(theta[np.argmax(shape)]),
    }


def _stribeck(u, rng, base):
    model = "tustin" if rng.uniform() < 0.5 else "hess_soom"
    return {
        "model": model,
        "static_over_kinetic_fraction": u("static_over_kinetic_fraction"),
        "stribeck_velocity_arm_rad_s": u("stribeck_velocity_arm_rad_s"),
        "tustin_exponent": u("tustin_exponent") if model == "tustin" else 2.0,
    }


def _thermal_drift(u, rng, base):
    warm = u("warm_up_time_constant_s")
    return {
        "coulomb_drop_fraction": u("coulomb_drop_fraction"),
        "viscous_drop_fraction": u("viscous_drop_fraction"),
        "warm_up_time_constant_s": warm,
        "cool_down_time_constant_s": warm * u("cool_down_over_warm_up"),
    }


def _needle_penetration(u, rng, base):
    low, high = EFFECTS["needle_penetration"].ranges["layers"]
    return {
        "layers": int(rng.integers(int(low), int(high) + 1)),
        "force_per_layer_N": u("force_per_layer_N_per_Nm") * base["nominal_coulomb_shaft_Nm"],
        **{
            key: u(key)
            for key in (
                "layer_thickness_m",
                "point_length_m",
                "sliding_fraction",
                "needle_depth_below_plate_at_bdc_m",
            )
        },
    }


def needle_entry_angle(params: dict, crank_m: float, rod_m: float) -> float:
    """Arm angle where the needle tip reaches the fabric top on its way down [rad]."""
    theta = np.linspace(0, math.pi, 20001)
    tip = (
        slider_height(theta, crank_m, rod_m)
        - (rod_m - crank_m)
        - params["needle_depth_below_plate_at_bdc_m"]
    )
    fabric = params["layers"] * params["layer_thickness_m"]
    return float(theta[np.argmax(tip <= fabric)])


def _belt_compliance(u, rng, base):
    return {key: u(key) for key in ("motor_inertia_fraction", "resonance_Hz", "damping_ratio")}


# Table 2's PWM conversion error is anchored at two duties: error at 4.5 V and at 12 V.
PWM_ANCHORS_V = (4.5, 12.0)


def _voltage_nonlinearity(u, rng, base):
    supply = base["supply_V"]
    exponent = u("low_duty_loss_exponent")
    errors = (u("error_at_4.5V_fraction"), u("error_at_12V_fraction"))
    # applied - logged = gain x (1 - x) - loss (1 - x)^exponent, x = duty; solved for both anchors
    duty = np.array(PWM_ANCHORS_V) / supply
    matrix = np.column_stack([duty * (1 - duty), -((1 - duty) ** exponent)])
    gain, loss = np.linalg.solve(matrix, np.array(PWM_ANCHORS_V) * np.array(errors))
    return {
        "supply_V": supply,
        "mid_duty_gain_V": float(gain),
        "low_duty_loss_V": float(loss),
        "low_duty_loss_exponent": exponent,
        "error_at_4.5V_fraction": errors[0],
        "error_at_12V_fraction": errors[1],
    }


COPPER_PER_KELVIN = 0.00393  # temperature coefficient of copper's resistance


def _winding_heating(u, rng, base):
    # a winding's thermal resistance scales with the motor: per watt of a reference loss, the
    # motor stalled at a tenth of the supply voltage
    reference_W = (0.1 * base["supply_V"]) ** 2 / base["resistance_ohm"]
    return {
        "thermal_resistance_K_per_W": u("kelvin_per_reference_watt") / reference_W,
        "thermal_time_constant_s": u("thermal_time_constant_s"),
        "copper_coefficient_per_K": COPPER_PER_KELVIN,
    }


def _encoder_eccentricity(u, rng, base):
    return {"amplitude_rad": u("amplitude_rad"), "phase_rad": u("phase_rad")}


_PHASE = (0.0, TWO_PI)

EFFECTS: dict[str, Effect] = {
    effect.name: effect
    for effect in (
        Effect(
            "torque_ripple",
            "motor-angle-periodic torque: once per motor turn (shaft distortion) plus 12-per-turn cogging, "
            "0.27-0.8 and 0.04-0.18 of the Coulomb level seen at the motor",
            {
                "once_per_motor_rev_per_motor_coulomb": (4 / 15, 0.8),
                "cogging_per_motor_coulomb": (2 / 45, 8 / 45),
                "phase_rad": _PHASE,
            },
            _torque_ripple,
        ),
        Effect(
            "linkage_dynamics",
            "needle-bar slider-crank: inertia varying with arm angle, its gravity torque and the 1/2 J'(theta) omega^2 term",
            {"reciprocating_mass_kg_per_kgm2": (28.1025, 84.3075)},
            _linkage_dynamics,
        ),
        Effect(
            "position_friction",
            "Coulomb level varying over the arm revolution (first and second harmonic, 12-22 % peak to peak)",
            {
                "peak_to_peak_fraction": (0.12, 0.22),
                "second_harmonic_share": (0.0, 0.4),
                "phase_rad": _PHASE,
            },
            _position_friction,
        ),
        Effect(
            "stribeck",
            "static friction 20-45 % above kinetic, decaying with speed (Tustin or Hess-Soom); breakaway needs more torque",
            {
                "static_over_kinetic_fraction": (0.2, 0.45),
                "stribeck_velocity_arm_rad_s": (4.0, 20.0),
                "tustin_exponent": (0.7, 2.0),
            },
            _stribeck,
        ),
        Effect(
            "thermal_drift",
            "Coulomb and viscous friction fall while the machine runs and its sintered bearings warm (time constant 20-120 s)",
            {
                "coulomb_drop_fraction": (0.10, 0.35),
                "viscous_drop_fraction": (0.20, 0.55),
                "warm_up_time_constant_s": (20.0, 120.0),
                "cool_down_over_warm_up": (3.0, 6.0),
            },
            _thermal_drift,
        ),
        Effect(
            "needle_penetration",
            "fabric (3-12 layers) resists the needle: piercing force before bottom dead centre, shank friction while it is through",
            {
                "layers": (3, 12),
                "force_per_layer_N_per_Nm": (25 / 3, 200 / 9),
                "layer_thickness_m": (0.25e-3, 0.45e-3),
                "point_length_m": (1.2e-3, 2.5e-3),
                "sliding_fraction": (0.2, 0.5),
                "needle_depth_below_plate_at_bdc_m": (9e-3, 13e-3),
            },
            _needle_penetration,
        ),
        Effect(
            "belt_compliance",
            "elastic motor belt between rotor and arm shaft: a two-inertia resonance at 25-70 Hz",
            {
                "motor_inertia_fraction": (0.25, 0.4),
                "resonance_Hz": (25.0, 70.0),
                "damping_ratio": (0.03, 0.12),
            },
            _belt_compliance,
        ),
        Effect(
            "voltage_nonlinearity",
            "the PWM switch's applied voltage differs from the logged one: 3-10 % below it at 4.5 V, 2-6 % above it at 12 V",
            {
                "error_at_4.5V_fraction": (-0.10, -0.03),
                "error_at_12V_fraction": (0.02, 0.06),
                "low_duty_loss_exponent": (2.0, 4.0),
            },
            _voltage_nonlinearity,
        ),
        Effect(
            "backlash",
            "free play of 0.5-2 deg (at the shaft) in the belt or gear between motor and shaft: a dead zone the "
            "motor crosses unloaded whenever the torque through the transmission reverses",
            {
                "free_play_rad": (0.009, 0.035),
                "motor_inertia_fraction": (0.25, 0.4),
                "resonance_Hz": (60.0, 120.0),
                "damping_ratio": (0.05, 0.12),
            },
            lambda u, rng, base: {
                key: u(key)
                for key in (
                    "free_play_rad",
                    "motor_inertia_fraction",
                    "resonance_Hz",
                    "damping_ratio",
                )
            },
        ),
        Effect(
            "sensor_delay",
            "the angle reaches the log 2-15 ms late (a filtering encoder interface, a buffering logger); the machine is unaffected",
            {"delay_s": (2e-3, 15e-3)},
            lambda u, rng, base: {"delay_s": u("delay_s")},
        ),
        Effect(
            "winding_heating",
            "the copper warms under I^2 R (thermal time constant 20-90 s): its resistance rises at 0.39 %/K, "
            "the motor gives less torque per volt and less back-emf damping",
            {"kelvin_per_reference_watt": (25.0, 60.0), "thermal_time_constant_s": (20.0, 90.0)},
            _winding_heating,
        ),
        Effect(
            "encoder_eccentricity",
            "the arm encoder's disc is off-centre: a once-per-revolution angle error of 2.5-8 mrad in the log only",
            {"amplitude_rad": (2.5e-3, 8e-3), "phase_rad": _PHASE},
            _encoder_eccentricity,
        ),
    )
}


def parse_effects(effects) -> list[str]:
    """Effect names from a list or a comma-separated string; ``none`` (or nothing) is clean."""
    if isinstance(effects, str):
        effects = [effects]
    names: list[str] = []
    for item in effects or ():
        for name in str(item).split(","):
            name = name.strip()
            if not name or name == "none":
                continue
            if name not in EFFECTS:
                raise UserError(
                    f"unknown effect '{name}'; did you mean {close_matches(name, EFFECTS)}? (none, or one or more of: {', '.join(EFFECTS)})"
                )
            if name in names:
                raise UserError(f"effect '{name}' named twice")
            names.append(name)
    return names


def draw_effects(seed: int, names: list[str], baseline: dict) -> dict[str, dict]:
    return {name: EFFECTS[name].draw(stream(seed, f"effect:{name}"), baseline) for name in names}
