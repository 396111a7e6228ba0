"""A third truth model for the diagnosis: other reasonable engineering choices.

Test code only (the product never imports it). Written from the thesis and textbook physics,
independently of ``mechanism.testbench`` and ``tests/helpers/synthetic_truth.py``, to ask how the
diagnosis behaves when the held-out bench's authors chose differently:

- **equations on the motor shaft** (the arm is a load seen through the 8:1 belt), electrical
  state optional: no inductance (i = (U - Ke w)/R) or a winding L up to 3 mH;
- **integrators**: classical RK4 with a fixed step and smooth ``tanh`` Coulomb friction
  (no sticking: the shaft creeps under a torque below the friction level), or RK4 sub-steps
  with *event* stick-slip (a sign change of the speed is located inside the sub-step; the
  shaft stays stuck while the torque is below the static level);
- **motor constants** as the thesis prints them (Kt 0.017, Ke 0.021) or a consistent SI motor
  Kt = Ke = sqrt(0.017 x 0.021) = 0.0189;
- **the machine** drawn anywhere in plausible ranges (J 1.5e-5..4e-5 kg m^2 and viscous
  1e-5..4e-5 N m s/rad on the motor side, Coulomb 0.12..0.25 N m on the arm);
- **voltage profiles** of other shapes: short or long plateaus, ramps, a staircase, PWM duty
  quantised to 1 % of 24 V; first plateau anywhere, random rest angle;
- **sensors**: encoder counts by floor or round of angle / (2 pi / 20000), edge jitter,
  logged-voltage noise and a one-sample logging delay, with or without a ``current`` column;
- **effects** in several *flavours* each (:data:`FLAVOURS`), drawn per seed, with magnitudes
  in physically plausible ranges.

``make_case(effects, seed, variant)`` returns a :class:`Case` (the CSV columns, the truth,
the noise-free velocity); :func:`detectability` measures how much an effect changes the
measured speed against the same seed's clean twin (a real effect that changes nothing
measurable cannot be asked for).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

TWO_PI = 2 * math.pi
N = 8.0  # motor turns per arm turn
R_OHM = 1.1
ENCODER_STEP = TWO_PI / 20000
FS = 1000.0
G = 9.81

# Table 2 of the thesis: logged (theoretical, duty x 24 V) against measured motor voltage
TABLE2_LOGGED_V = (4.8, 7.2, 12.0, 16.8, 19.2, 24.0)
TABLE2_MOTOR_V = (4.48, 7.0, 12.49, 17.3, 19.6, 24.0)


@dataclass(frozen=True)
class Variant:
    """How a different team builds its truth model (see the module docstring)."""

    name: str
    integrator: str = "event"  # "event" (RK4 sub-steps + stick-slip) or "rk4_tanh"
    substeps: int = 4  # RK4 steps per 1 ms sample
    tanh_speed_arm_rad_s: float = 0.1  # smoothing speed of the tanh friction (rk4_tanh)
    inductance_H: float = 0.0
    motor_constants: str = "thesis"  # "thesis" (Kt 0.017, Ke 0.021) or "geometric" (both 0.0189)
    profile: str = "plateaus"  # plateaus | long | ramps | staircase | pwm
    quantiser: str = "floor"  # floor | round
    current_column: bool = True
    angle_jitter_counts: float = 0.0  # encoder edge jitter (sigma, counts) before quantisation
    voltage_noise_V: float = 0.0  # noise on the logged voltage (the motor sees the clean one)
    voltage_delay_samples: int = 0  # the logger stamps the voltage this many samples late
    time_offset_s: float = 0.0  # the logger's clock does not start at 0


VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        # RK4 at exactly 1 kHz, smooth friction, no inductance, consistent SI motor, no current
        Variant(
            "rk4_tanh",
            integrator="rk4_tanh",
            substeps=1,
            tanh_speed_arm_rad_s=0.1,
            inductance_H=0.0,
            motor_constants="geometric",
            profile="plateaus",
            quantiser="round",
            current_column=False,
        ),
        # event stick-slip, a large winding inductance, few long plateaus, floor quantiser
        Variant(
            "event_long_L",
            integrator="event",
            substeps=4,
            inductance_H=3e-3,
            motor_constants="thesis",
            profile="long",
            quantiser="floor",
            current_column=True,
            time_offset_s=12.5,
        ),
        # ramps instead of steps, SI motor, edge jitter
        Variant(
            "ramps",
            integrator="event",
            substeps=4,
            inductance_H=0.5e-3,
            motor_constants="geometric",
            profile="ramps",
            quantiser="floor",
            angle_jitter_counts=0.4,
            current_column=True,
        ),
        # a staircase, a noisy and late voltage log, sharper tanh friction with small steps
        Variant(
            "stairs_noisy",
            integrator="rk4_tanh",
            substeps=4,
            tanh_speed_arm_rad_s=0.02,
            inductance_H=1e-3,
            motor_constants="thesis",
            profile="staircase",
            quantiser="round",
            voltage_noise_V=0.03,
            voltage_delay_samples=1,
            angle_jitter_counts=0.3,
            current_column=False,
        ),
        # the duty cycle logged as 24 V x duty in 1 % steps, SI motor, event stick-slip
        Variant(
            "pwm_duty",
            integrator="event",
            substeps=4,
            inductance_H=0.2e-3,
            motor_constants="geometric",
            profile="pwm",
            quantiser="floor",
            current_column=True,
        ),
    )
}


# ----------------------------------------------------------------------------- effects

EFFECT_NAMES = (
    "torque_ripple",
    "linkage_dynamics",
    "position_friction",
    "stribeck",
    "thermal_drift",
    "needle_penetration",
    "belt_compliance",
    "voltage_nonlinearity",
    "encoder_eccentricity",
)

FLAVOURS: dict[str, tuple[str, ...]] = {
    "torque_ripple": ("once_per_motor_rev", "cogging_12", "speed_falling", "one_and_two"),
    "linkage_dynamics": ("slider_crank", "slider_crank_with_rod"),
    "position_friction": ("cosine", "broad_bump", "cos_1_3"),
    "stribeck": ("exponential", "gaussian", "lorentzian"),
    "thermal_drift": ("viscous_only", "coulomb_only", "both_time"),
    "needle_penetration": ("smooth_window", "sharp_pulse", "layers_geometry"),
    "belt_compliance": ("two_mass",),
    "voltage_nonlinearity": ("table2_curve", "dead_band", "quadratic_sag"),
    "encoder_eccentricity": ("once_per_rev",),
}


def _rng(seed: int, stream: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(stream.encode())])


def _draw_effect(name: str, flavour: str | None, seed: int) -> dict:
    """Physical parameters of one effect (its own random stream: switching another effect on
    does not change them)."""
    rng = _rng(seed, "effect:" + name)
    flavour = flavour or FLAVOURS[name][int(rng.integers(len(FLAVOURS[name])))]
    u = rng.uniform
    p: dict = {"flavour": flavour}
    if name == "torque_ripple":
        p["phase_rad"] = u(0, TWO_PI)
        p["phase2_rad"] = u(0, TWO_PI)
        if flavour == "once_per_motor_rev":
            p["amp_motor_Nm"] = u(0.008, 0.02)
        elif flavour == "cogging_12":
            # 12 per motor revolution is 96 per arm revolution: above the velocity filter at all
            # plateau speeds; a large cogging is the only one that shows (at starts and stops)
            p["amp_motor_Nm"] = u(0.015, 0.03)
        elif flavour == "speed_falling":  # thesis eq. 17: A(w) falls with speed
            p["amp_motor_Nm"] = u(0.015, 0.03)
            p["fall_speed_arm_rad_s"] = u(15, 50)
        else:  # once and twice per motor revolution (shaft distortion)
            p["amp_motor_Nm"] = u(0.006, 0.015)
            p["amp2_motor_Nm"] = u(0.004, 0.01)
    elif name == "linkage_dynamics":
        p["mass_kg"] = u(0.03, 0.15)
        p["crank_m"] = u(0.012, 0.018)
        p["rod_m"] = u(0.035, 0.07)
        # a connecting rod whose mass is split between crank pin (rotating) and bar (reciprocating)
        p["rod_mass_kg"] = u(0.02, 0.06) if flavour == "slider_crank_with_rod" else 0.0
    elif name == "position_friction":
        p["phase_rad"] = u(0, TWO_PI)
        if flavour == "cosine":
            p["amp_fraction"] = u(0.06, 0.12)  # 12-24 % peak to peak (thesis: 16 %)
        elif flavour == "broad_bump":
            # a bearing-load bump away from needle-down: one near bottom dead centre would be a
            # load window there, which no measurement on the arm shaft tells from a fabric load
            p["phase_rad"] = u(-1.75, 1.75)
            p["amp_fraction"] = u(0.2, 0.4)
            p["width_rad"] = u(0.5, 1.0)
        else:
            p["amp_fraction"] = u(0.06, 0.1)
            p["amp3_fraction"] = u(0.03, 0.06)
            p["phase3_rad"] = u(0, TWO_PI)
    elif name == "stribeck":
        p["static_excess_fraction"] = u(0.15, 0.6)
        p["stribeck_speed_arm_rad_s"] = u(0.5, 15.0)
    elif name == "thermal_drift":
        p["tau_s"] = u(15, 60)
        p["viscous_drop"] = u(0.3, 0.55) if flavour in ("viscous_only", "both_time") else 0.0
        p["coulomb_drop"] = u(0.2, 0.45) if flavour in ("coulomb_only", "both_time") else 0.0
    elif name == "needle_penetration":
        p["layers"] = int(rng.integers(3, 13))
        if flavour == "smooth_window":
            p["peak_arm_Nm_per_layer"] = u(0.008, 0.025)
            p["centre_rad"] = math.pi + u(-0.5, 0.15)
            p["half_width_rad"] = u(0.5, 1.2)
        elif flavour == "sharp_pulse":
            p["peak_arm_Nm_per_layer"] = u(0.015, 0.04)
            p["entry_rad"] = math.pi - u(0.4, 1.0)
            p["pulse_width_rad"] = u(0.08, 0.25)
        else:  # needle geometry: the tip below the fabric, force per layer through |dz/dtheta|
            p["force_N_per_layer"] = u(0.4, 1.2)
            p["crank_m"] = 0.016
            p["tip_depth_m"] = u(0.004, 0.012)  # how far the tip goes below the fabric top at BDC
            p["layer_thickness_m"] = u(0.25e-3, 0.45e-3)
    elif name == "belt_compliance":
        p["resonance_Hz"] = u(15, 120)
        p["rotor_share"] = u(0.2, 0.5)
        p["damping_ratio"] = u(0.02, 0.15)
    elif name == "voltage_nonlinearity":
        if flavour == "dead_band":
            p["dead_band_V"] = u(0.4, 1.2)
            p["gain"] = u(0.97, 1.03)
        elif flavour == "quadratic_sag":
            p["sag_per_V2"] = u(0.0025, 0.005)  # 1-2 V lost at 20 V
    elif name == "encoder_eccentricity":
        p["amp_rad"] = u(0.001, 0.01)
        p["phase_rad"] = u(0, TWO_PI)
    return p


# ----------------------------------------------------------------------------- machine and profile


def draw_machine(seed: int, variant: Variant) -> dict:
    rng = _rng(seed, "machine")
    if variant.motor_constants == "geometric":
        kt = ke = math.sqrt(0.017 * 0.021)
    else:
        kt, ke = 0.017, 0.021
    return {
        "J_motor_kgm2": rng.uniform(1.5e-5, 4e-5),
        "viscous_motor_Nm_s": rng.uniform(1e-5, 4e-5),
        "coulomb_arm_Nm": rng.uniform(0.12, 0.25),
        "Kt": kt,
        "Ke": ke,
        "R": R_OHM,
        "L": variant.inductance_H,
        "rest_angle_rad": rng.uniform(0, TWO_PI),
    }


def voltage_profile(kind: str, seed: int, duration_s: float) -> np.ndarray:
    """Commanded motor voltage at 1 kHz: levels 4-20 V with stops at 0 V."""
    rng = _rng(seed, "profile:" + kind)
    n = int(round(duration_s * FS))
    t = np.arange(n) / FS
    u = np.zeros(n)
    now = rng.uniform(0.2, 1.5)  # at rest first

    def hold(level, length):
        nonlocal now
        u[(t >= now) & (t < now + length)] = level
        now += length

    if kind in ("plateaus", "long", "pwm"):
        lengths = (1.5, 5.0) if kind != "long" else (7.0, 13.0)
        since_stop = 0
        while now < duration_s:
            level = rng.uniform(4.0, 20.0)
            if kind == "pwm":
                level = 24.0 * round(level / 24.0, 2)
            hold(level, rng.uniform(*lengths))
            since_stop += 1
            if since_stop >= rng.integers(2, 5):
                hold(0.0, rng.uniform(1.0, 3.0))
                since_stop = 0
    elif kind == "ramps":
        level = 0.0
        while now < duration_s:
            target = 0.0 if rng.random() < 0.15 else rng.uniform(4.0, 20.0)
            ramp = rng.uniform(0.8, 4.0)
            sel = (t >= now) & (t < now + ramp)
            u[sel] = level + (target - level) * (t[sel] - now) / ramp
            now += ramp
            level = target
            hold(level, rng.uniform(0.5, 3.0))
            if rng.random() < 0.2:  # an occasional hard stop and restart
                hold(0.0, rng.uniform(1.0, 2.0))
                level = 0.0
    elif kind == "staircase":
        first = rng.uniform(4.0, 6.0)
        steps = np.arange(first, 20.01, rng.uniform(1.5, 3.0))
        while now < duration_s:
            for level in (*steps, *steps[::-1]):
                hold(level, rng.uniform(1.5, 3.0))
            hold(0.0, rng.uniform(1.0, 2.5))
    else:
        raise ValueError(f"unknown profile {kind!r}")
    return u


# ----------------------------------------------------------------------------- the model


def _slider_crank(crank: float, rod: float):
    """Needle-bar height x(theta) (TDC at 0) and its first two derivatives by central
    differences of the exact position (no closed-form derivative to get wrong)."""

    def x(th):
        s = math.sin(th)
        return crank * math.cos(th) + math.sqrt(rod * rod - (crank * s) ** 2)

    step = 1e-4

    def derivatives(th):
        a, b, c = x(th - step), x(th), x(th + step)
        return (c - a) / (2 * step), (c - 2 * b + a) / (step * step)

    # tabulate once over a revolution (the simulation interpolates)
    grid = np.linspace(0.0, TWO_PI, 4097)
    d1 = np.empty_like(grid)
    d2 = np.empty_like(grid)
    for k, th in enumerate(grid):
        d1[k], d2[k] = derivatives(th)
    return grid, d1, d2


class _Table:
    """A periodic function of the arm angle, tabulated over one revolution."""

    def __init__(self, values: np.ndarray):
        self.values = np.asarray(values, float)
        self.n = len(self.values) - 1  # last equals first

    def __call__(self, theta: float) -> float:
        x = (theta % TWO_PI) * (self.n / TWO_PI)
        i = int(x)
        if i >= self.n:
            i = self.n - 1
        f = x - i
        v = self.values
        return v[i] + f * (v[i + 1] - v[i])


def _wrap(a):
    return (a + math.pi) % TWO_PI - math.pi


@dataclass
class Case:
    effects: tuple[str, ...]
    seed: int
    variant: Variant
    time_s: np.ndarray
    voltage_V: np.ndarray  # as logged
    arm_angle_rad: np.ndarray  # as the encoder reports it
    current_A: np.ndarray | None
    truth: dict = field(default_factory=dict)
    # what the sensor reports before jitter and quantisation
    sensed_angle_rad: np.ndarray | None = None

    def write_csv(self, path) -> None:
        cols = ["time", "voltage", "arm_angle"] + (
            ["current"] if self.current_A is not None else []
        )
        data = [self.time_s, self.voltage_V, self.arm_angle_rad] + (
            [self.current_A] if self.current_A is not None else []
        )
        with open(path, "w", encoding="utf-8") as f:
            f.write(f"# truth_variants: variant {self.variant.name}, seed {self.seed}\n")
            f.write(",".join(cols) + "\n")
            fmt = ",".join(["%.4f", "%.3f", "%.7f", "%.3f"][: len(cols)])
            np.savetxt(f, np.column_stack(data), fmt=fmt)

    def recording(self):
        from mechanism.sysid.recording import make_recording

        return make_recording(
            self.time_s,
            self.voltage_V,
            self.arm_angle_rad,
            self.current_A,
            source=f"variants:{self.variant.name}:{'+'.join(self.effects) or 'none'}:{self.seed}",
        )


def make_case(
    effects: Sequence[str] | str = (),
    seed: int = 0,
    variant: str | Variant = "rk4_tanh",
    duration_s: float = 60.0,
    flavours: dict | None = None,
    scale: float = 1.0,
) -> Case:
    """Simulate one recording. ``flavours`` pins an effect's flavour ({name: flavour});
    ``scale`` multiplies every effect's magnitude (for detectability studies)."""
    if isinstance(effects, str):
        effects = () if effects in ("", "none") else tuple(effects.split(","))
    effects = tuple(effects)
    for e in effects:
        if e not in FLAVOURS:
            raise ValueError(f"unknown effect {e!r}")
    variant = VARIANTS[variant] if isinstance(variant, str) else variant
    flavours = flavours or {}
    machine = draw_machine(seed, variant)
    params = {e: _draw_effect(e, flavours.get(e), seed) for e in effects}
    u_cmd = voltage_profile(variant.profile, seed, duration_s)
    theta, omega_arm, current = simulate_truth(machine, params, u_cmd, variant, scale)
    # sensors
    rng = _rng(seed, "noise")
    sensed = theta.copy()
    if "encoder_eccentricity" in params:
        p = params["encoder_eccentricity"]
        sensed = sensed + scale * p["amp_rad"] * np.sin(theta + p["phase_rad"])
    measured = sensed
    if variant.angle_jitter_counts > 0:
        measured = measured + rng.normal(
            0.0, variant.angle_jitter_counts * ENCODER_STEP, len(measured)
        )
    counts = (
        np.floor(measured / ENCODER_STEP)
        if variant.quantiser == "floor"
        else np.round(measured / ENCODER_STEP)
    )
    angle = counts * ENCODER_STEP
    logged = u_cmd.copy()
    if variant.voltage_delay_samples:
        d = variant.voltage_delay_samples
        logged = np.concatenate([np.full(d, logged[0]), logged[:-d]])
    if variant.voltage_noise_V > 0:
        logged = logged + rng.normal(0.0, variant.voltage_noise_V, len(logged))
    cur = None
    if variant.current_column:
        cur = np.round((current + rng.normal(0.0, 0.02, len(current))) / 0.001) * 0.001
    t = variant.time_offset_s + np.arange(len(u_cmd)) / FS
    truth = {"machine": machine, "effects": params, "variant": variant.name, "scale": scale}
    return Case(effects, seed, variant, t, logged, angle, cur, truth, sensed)


def simulate_truth(m: dict, params: dict, u_cmd: np.ndarray, variant: Variant, scale: float = 1.0):
    """Motor-shaft equations, RK4 sub-steps; returns arm angle, arm speed, current per sample."""
    kt, ke, r_ohm, ind = m["Kt"], m["Ke"], m["R"], m["L"]
    j_total = m["J_motor_kgm2"]  # motor side, everything reflected
    d_total = m["viscous_motor_Nm_s"]
    fc_arm = m["coulomb_arm_Nm"]

    # -- voltage the motor sees
    vn = params.get("voltage_nonlinearity")
    if vn is not None:
        if vn["flavour"] == "table2_curve":
            ratio_at = np.interp(
                np.abs(u_cmd), TABLE2_LOGGED_V, np.array(TABLE2_MOTOR_V) / TABLE2_LOGGED_V
            )
            applied = u_cmd * (1 + scale * (ratio_at - 1))
        elif vn["flavour"] == "dead_band":
            applied = np.sign(u_cmd) * np.maximum(
                np.abs(u_cmd) * (1 + scale * (vn["gain"] - 1)) - scale * vn["dead_band_V"], 0.0
            )
        else:
            applied = u_cmd - scale * vn["sag_per_V2"] * u_cmd * np.abs(u_cmd)
    else:
        applied = u_cmd

    # -- position-dependent tables on the arm angle (coulomb scale, fabric load, linkage)
    grid = np.linspace(0.0, TWO_PI, 4097)
    coulomb_shape = np.ones_like(grid)
    pf = params.get("position_friction")
    if pf is not None:
        a = scale * pf["amp_fraction"]
        if pf["flavour"] == "cosine":
            coulomb_shape = 1 + a * np.cos(grid - pf["phase_rad"])
        elif pf["flavour"] == "broad_bump":
            rel = (grid - pf["phase_rad"] + math.pi) % TWO_PI - math.pi
            coulomb_shape = 1 + a * np.exp(-0.5 * (rel / pf["width_rad"]) ** 2)
        else:
            coulomb_shape = (
                1
                + a * np.cos(grid - pf["phase_rad"])
                + scale * pf["amp3_fraction"] * np.cos(3 * grid - pf["phase3_rad"])
            )
    coulomb_table = _Table(fc_arm * coulomb_shape)
    fabric = np.zeros_like(grid)
    nd = params.get("needle_penetration")
    if nd is not None:
        layers = nd["layers"]
        # thesis fig. 37: 12 layers take ~5 of ~20 rad/s while the needle is in the fabric
        # (about a quarter turn), i.e. about 0.1-0.3 N m on the arm at its peak
        if nd["flavour"] == "smooth_window":
            rel = (grid - nd["centre_rad"] + math.pi) % TWO_PI - math.pi
            inside = np.abs(rel) < nd["half_width_rad"]
            fabric = (
                np.where(inside, 0.5 * (1 + np.cos(math.pi * rel / nd["half_width_rad"])), 0.0)
                * nd["peak_arm_Nm_per_layer"]
                * layers
            )
        elif nd["flavour"] == "sharp_pulse":
            rel = (grid - nd["entry_rad"]) % TWO_PI
            w = nd["pulse_width_rad"]
            fabric = (
                np.where(rel < w, np.sin(math.pi * rel / w) ** 2, 0.0)
                * nd["peak_arm_Nm_per_layer"]
                * layers
            )
        else:
            rc = nd["crank_m"]
            z_tip = rc * (1 + np.cos(grid))  # tip height above its lowest point (pure crank)
            depth = nd["tip_depth_m"] - z_tip  # how far below the fabric top the tip is
            fabric_thickness = layers * nd["layer_thickness_m"]
            in_fabric = np.clip(depth, 0.0, None)
            # layers the shank is in
            engaged = np.minimum(in_fabric, fabric_thickness) / nd["layer_thickness_m"]
            lever = rc * np.abs(np.sin(grid))  # |dz/dtheta|
            fabric = nd["force_N_per_layer"] * engaged * lever
        fabric = scale * fabric
    fabric_table = _Table(fabric)

    ld = params.get("linkage_dynamics")
    if ld is not None:
        _, d1, d2 = _slider_crank(ld["crank_m"], ld["rod_m"])
        # rod mass: about half reciprocates
        mass = scale * (ld["mass_kg"] + 0.5 * ld["rod_mass_kg"])
        # the rest turns with the pin
        rotating = scale * 0.5 * ld["rod_mass_kg"] * ld["crank_m"] ** 2
        link_j = _Table(mass * d1 * d1 + rotating)
        link_q = _Table(mass * d1 * d2)  # 1/2 dJ/dtheta
        link_g = _Table(mass * G * d1)
        # the rod's rotating half at the crank pin (height r cos theta): its gravity torque dV/dtheta
        pin_g = _Table(-scale * 0.5 * ld["rod_mass_kg"] * G * ld["crank_m"] * np.sin(grid))
    else:
        link_j = link_q = link_g = pin_g = None

    st = params.get("stribeck")
    tr = params.get("torque_ripple")
    th = params.get("thermal_drift")
    belt = params.get("belt_compliance")

    def friction_level(theta_arm, w_arm, t):
        """Kinetic + Stribeck friction on the arm [N m], >= 0, and its static level."""
        base = coulomb_table(theta_arm)
        if th is not None:
            base *= 1 - scale * th["coulomb_drop"] * (1 - math.exp(-t / th["tau_s"]))
        level = base + fabric_table(theta_arm)
        static = level
        if st is not None:
            excess = scale * st["static_excess_fraction"] * base
            x = abs(w_arm) / st["stribeck_speed_arm_rad_s"]
            if st["flavour"] == "exponential":
                g = math.exp(-x)
            elif st["flavour"] == "gaussian":
                g = math.exp(-x * x)
            else:
                g = 1 / (1 + x * x)
            level += excess * g
            static += excess
        return level, static

    def viscous(t):
        if th is None:
            return d_total
        return d_total * (1 - scale * th["viscous_drop"] * (1 - math.exp(-t / th["tau_s"])))

    def ripple(phi_motor, w_motor):
        if tr is None:
            return 0.0
        a = scale * tr["amp_motor_Nm"]
        fl = tr["flavour"]
        if fl == "once_per_motor_rev":
            return a * math.sin(phi_motor + tr["phase_rad"])
        if fl == "cogging_12":
            return a * math.sin(12 * phi_motor + tr["phase_rad"])
        if fl == "speed_falling":
            w_arm = abs(w_motor) / N
            return (
                a
                * tr["fall_speed_arm_rad_s"]
                / (tr["fall_speed_arm_rad_s"] + w_arm)
                * math.sin(phi_motor + tr["phase_rad"])
            )
        return a * math.sin(phi_motor + tr["phase_rad"]) + scale * tr["amp2_motor_Nm"] * math.sin(
            2 * phi_motor + tr["phase2_rad"]
        )

    # belt: rotor (motor side, its own share of the inertia) and arm side joined by a spring
    if belt is not None:
        j_rotor = belt["rotor_share"] * j_total
        j_load = j_total - j_rotor  # motor-side equivalent of everything behind the belt
        reduced = j_rotor * j_load / j_total
        k_belt = reduced * (TWO_PI * belt["resonance_Hz"]) ** 2  # motor-side stiffness [N m/rad]
        c_belt = 2 * belt["damping_ratio"] * math.sqrt(k_belt * reduced)
    smooth = variant.integrator == "rk4_tanh"
    eps_motor = variant.tanh_speed_arm_rad_s * N
    rotor_viscous_share = 0.3  # the motor's own bearings; the rest is in the machine

    # State: [phi_load (motor-side angle of the machine, = N arm angle), w_load, i, phi_rotor, w_rotor]
    def deriv(s, u, t, stuck):
        phi, w, i, phr, wr = s
        theta = phi / N
        w_arm = w / N
        jl = j_total if belt is None else j_load
        quad = grav = 0.0
        if link_j is not None:
            jl = jl + link_j(theta) / (N * N)
            quad = link_q(theta) * w_arm * w_arm / N
            grav = (link_g(theta) + pin_g(theta)) / N  # dV/dtheta, resisting
        d = viscous(t)
        w_motor = w if belt is None else wr
        i_now = i if ind > 0 else (u - ke * w_motor) / r_ohm
        di = (u - r_ohm * i - ke * w_motor) / ind if ind > 0 else 0.0
        t_motor = kt * i_now - ripple(phr if belt is not None else phi, w_motor)
        if belt is None:
            drive = t_motor - d * w
            dwr = 0.0
        else:
            fb = k_belt * (phr - phi) + c_belt * (wr - w)
            dwr = (t_motor - rotor_viscous_share * d * wr - fb) / j_rotor
            drive = fb - (1 - rotor_viscous_share) * d * w
        drive -= quad + grav
        level, static = friction_level(theta, w_arm, t)
        f_motor = level / N
        if smooth:
            dw = (drive - f_motor * math.tanh(w / eps_motor)) / jl
        elif stuck:
            dw = 0.0
        else:
            dw = (drive - math.copysign(f_motor, w)) / jl
        return (w, dw, di, wr, dwr), drive, static / N

    n = len(u_cmd)
    h = 1.0 / FS / variant.substeps
    phi0 = m["rest_angle_rad"] * N
    s = [phi0, 0.0, 0.0, phi0, 0.0]
    stuck = not smooth
    theta_out = np.empty(n)
    w_out = np.empty(n)
    i_out = np.empty(n)
    t = 0.0
    for k in range(n):
        u = applied[k]
        theta_out[k] = s[0] / N
        w_out[k] = s[1] / N
        w_motor = s[1] if belt is None else s[4]
        i_out[k] = s[2] if ind > 0 else (u - ke * w_motor) / r_ohm
        for _ in range(variant.substeps):
            if stuck:
                _, drive, static = deriv(s, u, t, True)
                if abs(drive) > static:
                    stuck = False
                    s[1] = 1e-9 * math.copysign(1.0, drive)
            k1, _, _ = deriv(s, u, t, stuck)
            s2 = [a + 0.5 * h * b for a, b in zip(s, k1)]
            k2, _, _ = deriv(s2, u, t + 0.5 * h, stuck)
            s3 = [a + 0.5 * h * b for a, b in zip(s, k2)]
            k3, _, _ = deriv(s3, u, t + 0.5 * h, stuck)
            s4 = [a + h * b for a, b in zip(s, k3)]
            k4, _, _ = deriv(s4, u, t + h, stuck)
            new = [
                a + h / 6.0 * (b1 + 2 * b2 + 2 * b3 + b4)
                for a, b1, b2, b3, b4 in zip(s, k1, k2, k3, k4)
            ]
            if stuck:
                new[0], new[1] = s[0], 0.0
            elif not smooth and s[1] != 0.0 and new[1] * s[1] <= 0.0:
                # the speed crosses zero inside the step: stop there, then stick or reverse
                frac = s[1] / (s[1] - new[1])
                new[0] = s[0] + 0.5 * frac * h * s[1]
                new[1] = 0.0
                _, drive, static = deriv(new, u, t + h, True)
                stuck = abs(drive) <= static
                if not stuck:
                    new[1] = 1e-9 * math.copysign(1.0, drive)
            s = new
            t += h
    return theta_out, w_out, i_out


# ----------------------------------------------------------------------------- detectability


def detectability(sensed_a: np.ndarray, sensed_b: np.ndarray, window_s: float = 2.0) -> float:
    """RMS difference [rad/s] of the speed the sensor reports (noise-free, unquantised,
    through the tool's differentiator) between two recordings of the same seed, over the most
    affected ``window_s`` (use 0.2 s for the belt's ringing after steps)."""
    from mechanism.sysid.recording import smoothed_velocity

    diff = smoothed_velocity(sensed_a, 1 / FS) - smoothed_velocity(sensed_b, 1 / FS)
    k = max(1, int(window_s * FS))
    power = np.convolve(diff * diff, np.ones(k) / k, mode="valid")
    return float(np.sqrt(power.max()))


__all__ = [
    "Case",
    "EFFECT_NAMES",
    "FLAVOURS",
    "VARIANTS",
    "Variant",
    "detectability",
    "draw_machine",
    "make_case",
    "simulate_truth",
    "voltage_profile",
]
