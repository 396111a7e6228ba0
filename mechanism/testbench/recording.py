"""Bench recordings from the truth model: voltage profile, simulation, sensors, files."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mechanism import __version__
from mechanism.errors import UserError, close_matches
from mechanism.files.formats import WriteFormat
from mechanism.files.outputs import atomic_file, transaction
from mechanism.machine.description import refuse_without_fabric
from mechanism.testbench import rocking
from mechanism.testbench import simulate as sim
from mechanism.testbench.truth import (
    ENCODER_COUNTS_PER_REV,
    TWO_PI,
    draw_baseline,
    draw_effects,
    mean_square_slider_speed,
    needle_entry_angle,
    parse_effects,
    position_friction_shape,
    stream,
)

SAMPLE_RATE_HZ = 1000
TRUTH_FORMAT = "mechanism-testbench-truth/1"
CURRENT_RESOLUTION_A = 1e-3
ZERO_MEANING = "needle top dead centre"  # shaft angle 0 of the shipped machine's recordings (no description given)
VOLTAGE_BANDS_V = ((4.0, 7.0), (7.0, 11.0), (11.0, 15.0), (15.0, 20.0))


@dataclass
class Recording:
    """What the bench logged (the CSV columns) and the concealed truth behind it.

    ``traces`` holds the true, noise-free signals at the sample times (arm angle and
    velocity, motor angle and velocity, current, applied voltage, warmth) for tests and
    plots; none of it is written to the CSV.
    """

    time: np.ndarray
    voltage: np.ndarray
    arm_angle: np.ndarray
    current: np.ndarray
    truth: dict
    traces: dict[str, np.ndarray] = field(default_factory=dict)
    zero_meaning: str = ZERO_MEANING  # what shaft angle 0 is (the header says it)

    @property
    def effects(self) -> list[str]:
        return list(self.truth["effects"])

    def columns(self) -> dict[str, np.ndarray]:
        return {
            "time": self.time,
            "voltage": self.voltage,
            "arm_angle": self.arm_angle,
            "current": self.current,
        }


# --- voltage profile --------------------------------------------------------------------


def draw_plateaus(seed: int, duration_s: float) -> list[tuple[float, float]]:
    """(duration [s], commanded voltage [V]) steps: rest, then 4-20 V plateaus of 2-6 s in a
    shuffled order that visits every voltage band, with 0 V stops every 2-4 plateaus."""
    rng = stream(seed, "profile")
    plateaus = [(round(rng.uniform(0.3, 1.0), 3), 0.0)]
    elapsed = plateaus[0][0]
    bands: list[int] = []
    since_stop, next_stop = 0, int(rng.integers(2, 5))
    while elapsed < duration_s:
        if since_stop >= next_stop:
            step = (round(rng.uniform(1.0, 2.5), 3), 0.0)
            since_stop, next_stop = 0, int(rng.integers(2, 5))
        else:
            if not bands:
                bands = list(rng.permutation(len(VOLTAGE_BANDS_V)))
            low, high = VOLTAGE_BANDS_V[bands.pop()]
            step = (round(rng.uniform(2.0, 6.0), 3), round(rng.uniform(low, high), 1))
            since_stop += 1
        plateaus.append(step)
        elapsed += step[0]
    return plateaus


def voltage_samples(plateaus, n: int, rate_hz: float = SAMPLE_RATE_HZ) -> np.ndarray:
    """Commanded voltage at each sample (held from each plateau's start)."""
    edges = np.round(np.cumsum([0.0] + [d for d, _ in plateaus]) * rate_hz).astype(np.int64)
    levels = np.array([v for _, v in plateaus] + [plateaus[-1][1]], dtype=float)
    index = np.searchsorted(edges, np.arange(n), side="right") - 1
    return levels[np.clip(index, 0, len(levels) - 1)]


def applied_voltage(logged: np.ndarray, params: dict | None) -> np.ndarray:
    """The voltage the motor gets: the logged one, or through the PWM switch's distortion
    (odd in the voltage: a negative voltage is distorted as its magnitude)."""
    logged = np.asarray(logged, dtype=float)
    if params is None:
        return logged.copy()
    magnitude = np.abs(logged)  # an H-bridge distorts both polarities alike
    duty = np.clip(magnitude / params["supply_V"], 0.0, 1.0)
    distorted = (
        magnitude
        + params["mid_duty_gain_V"] * duty * (1.0 - duty)
        - params["low_duty_loss_V"] * (1.0 - duty) ** params["low_duty_loss_exponent"]
    )
    return np.sign(logged) * np.where(magnitude > 0.0, np.maximum(distorted, 0.0), 0.0)


# --- truth model assembly ------------------------------------------------------------------


def _model_parameters(
    base: dict, effects: dict[str, dict], substeps: int, rate_hz: float = SAMPLE_RATE_HZ
) -> tuple[dict, dict]:
    """Integrator parameters (simulate.PARAM_FIELDS) and the derived truth values."""
    ratio = base["belt_ratio"]
    total = base["inertia_motor_side_kgm2"]
    r, rod = base["crank_radius_m"], base["rod_length_m"]
    p = dict.fromkeys(sim.PARAM_FIELDS, 0.0)
    p.update(
        dt=1.0 / rate_hz,
        n_sub=float(substeps),
        R=base["resistance_ohm"],
        L=base["inductance_H"],
        Kt=base["torque_constant_Nm_per_A"],
        Ke=base["back_emf_constant_V_s_per_rad"],
        ratio=ratio,
        d_motor=base["viscous_motor_side_Nm_s_per_rad"],
        coulomb=base["coulomb_arm_Nm"],
        lk_r=r,
        lk_l=rod,
        rp_nc=12.0,
        st_velocity=1.0,
        st_exponent=1.0,
        th_tau_cool=1.0,
    )
    derived: dict[str, dict] = {}
    # backlash: a belt with free play
    belt = effects.get("belt_compliance") or effects.get("backlash")
    motor_share = belt["motor_inertia_fraction"] if belt else 0.0
    arm_side = ratio**2 * (1.0 - motor_share) * total  # mean inertia carried by the arm shaft
    link = effects.get("linkage_dynamics")
    p["J_arm0"] = arm_side
    if link:
        p["lk_mass"], p["gravity"] = link["reciprocating_mass_kg"], link["gravity_m_s2"]
        p["J_arm0"] = arm_side - link["reciprocating_mass_kg"] * mean_square_slider_speed(r, rod)
        if p["J_arm0"] <= 0:
            raise UserError(
                "linkage_dynamics: the reciprocating mass carries more inertia than the whole machine"
            )
    if belt:
        motor = ratio**2 * motor_share * total  # rotor inertia seen from the arm
        stiffness = (TWO_PI * belt["resonance_Hz"]) ** 2 / (1.0 / motor + 1.0 / arm_side)
        reduced = motor * arm_side / (motor + arm_side)
        p.update(
            belt=1.0,
            J_motor=motor_share * total,
            belt_k=stiffness,
            belt_c=2.0 * belt["damping_ratio"] * math.sqrt(stiffness * reduced),
        )
        derived["belt_compliance" if "belt_compliance" in effects else "backlash"] = {
            "stiffness_arm_side_Nm_per_rad": stiffness,
            "damping_arm_side_Nm_s_per_rad": p["belt_c"],
            "rotor_inertia_arm_side_kgm2": motor,
            "arm_inertia_kgm2": arm_side,
        }
    if "backlash" in effects:
        p["bl_gap"] = 0.5 * effects["backlash"]["free_play_rad"]
    if "torque_ripple" in effects:
        e = effects["torque_ripple"]
        p.update(
            rp_a1=e["once_per_motor_rev_Nm"],
            rp_p1=e["once_per_motor_rev_phase_rad"],
            rp_ac=e["cogging_Nm"],
            rp_pc=e["cogging_phase_rad"],
            rp_nc=float(e["cogging_per_motor_rev"]),
        )
    if "position_friction" in effects:
        e = effects["position_friction"]
        p.update(
            pf_a1=e["first_harmonic_fraction"],
            pf_p1=e["first_harmonic_phase_rad"],
            pf_a2=e["second_harmonic_fraction"],
            pf_p2=e["second_harmonic_phase_rad"],
        )
        derived["position_friction"] = position_friction_shape(e)
    if "stribeck" in effects:
        e = effects["stribeck"]
        if e["model"] not in ("tustin", "hess_soom"):
            raise UserError(f"stribeck model must be tustin or hess_soom, not {e['model']!r}")
        p.update(
            st_model=sim.STRIBECK_MODELS[e["model"]],
            st_excess=e["static_over_kinetic_fraction"],
            st_velocity=e["stribeck_velocity_arm_rad_s"],
            st_exponent=e["tustin_exponent"],
        )
    if "thermal_drift" in effects:
        e = effects["thermal_drift"]
        p.update(
            th_coulomb_drop=e["coulomb_drop_fraction"],
            th_viscous_drop=e["viscous_drop_fraction"],
            th_tau_warm=e["warm_up_time_constant_s"],
            th_tau_cool=e["cool_down_time_constant_s"],
        )
    if "needle_penetration" in effects:
        e = effects["needle_penetration"]
        p.update(
            nd_force_per_m=e["force_per_layer_N"] / e["layer_thickness_m"],
            nd_fabric=e["layers"] * e["layer_thickness_m"],
            nd_point=e["point_length_m"],
            nd_sliding=e["sliding_fraction"],
            nd_depth_bdc=e["needle_depth_below_plate_at_bdc_m"],
        )
        derived["needle_penetration"] = {"entry_arm_angle_rad": needle_entry_angle(e, r, rod)}
    return p, derived


def _rocking_truth(params: dict, nominal, derived: dict) -> np.ndarray | None:
    """Stops at the ends of the travel and the machine's linkage table (its angle-dependent
    inertia and gravity torque) into the integrator's parameters; returns the table.

    With a belt (or backlash), the rotor's share of the inertia is taken of the machine's
    lowest inertia over the travel, not of its mean: the arm side keeps the CAD's variation
    on top of what is left, and must stay positive at every angle (a rocker's inertia can
    vary several-fold over its travel). Resonance and damping ratio are kept."""
    lo, hi = nominal.travel_rad
    params.update(stop_on=1.0, stop_lo=float(lo), stop_hi=float(hi))
    found = rocking.linkage_table(nominal)
    if found is None:
        return None
    params.update(tb_n=float(len(found[2])), tb_lo=found[0], tb_hi=found[1])
    if params["belt"]:
        n = params["ratio"]
        rotor, arm = n * n * params["J_motor"], params["J_arm0"]
        share, total = rotor / (rotor + arm), rotor + arm
        omega2 = params["belt_k"] * (1.0 / rotor + 1.0 / arm)
        zeta = params["belt_c"] / (2.0 * math.sqrt(params["belt_k"] * rotor * arm / (rotor + arm)))
        rotor = share * (total + float(found[2][:, 0].min()))
        arm = total - rotor
        stiffness = omega2 / (1.0 / rotor + 1.0 / arm)
        params.update(
            J_motor=rotor / (n * n),
            J_arm0=arm,
            belt_k=stiffness,
            belt_c=2.0 * zeta * math.sqrt(stiffness * rotor * arm / (rotor + arm)),
        )
        for values in derived.values():
            if "stiffness_arm_side_Nm_per_rad" in values:
                values.update(
                    stiffness_arm_side_Nm_per_rad=stiffness,
                    damping_arm_side_Nm_s_per_rad=params["belt_c"],
                    rotor_inertia_arm_side_kgm2=rotor,
                    arm_inertia_kgm2=arm,
                )
    return found[2]


def _chunk_stepper(
    params: dict, solver_name: str, table, nonlinearity: dict | None, heat: dict | None, rate: float
):
    """step(logged voltage chunk, state, end) for the rocking bench's controller: the truth over
    one control period (the winding's resistance held over it when it heats)."""
    kelvin = [0.0]

    def step(logged: np.ndarray, state: dict, end: dict) -> dict:
        applied = applied_voltage(logged, nonlinearity)
        chunk = params
        if heat is not None:
            chunk = {
                **params,
                "R": params["R"] * (1.0 + heat["copper_coefficient_per_K"] * kelvin[0]),
            }
        out = sim.simulate(chunk, applied, state, prefer=solver_name, table=table, end=end)
        if heat is not None:
            power = float(np.mean(out["current_A"] ** 2)) * chunk["R"]
            decay = math.exp(-len(logged) / rate / heat["thermal_time_constant_s"])
            kelvin[0] = kelvin[0] * decay + power * heat["thermal_resistance_K_per_W"] * (
                1.0 - decay
            )
            out["winding_resistance_ohm"] = np.full(len(logged), chunk["R"])
        out["applied_voltage_V"] = applied
        return out

    return step


# the copper's temperature is held over a chunk (thermal time constants are >= 20 s)
HEATING_CHUNK_S = 0.1


def _simulate_heating(
    params: dict,
    voltage: np.ndarray,
    state: dict,
    solver_name: str,
    heat: dict,
    rate: float,
    table: np.ndarray | None = None,
) -> dict:
    """The truth model with the winding's resistance following its copper temperature:
    dT/dt = (I^2 R - T / R_th) / C_th, R = R0 (1 + alpha T), integrated chunk by chunk (the
    resistance held over each 0.1 s chunk, the temperature updated from the chunk's I^2 R)."""
    n = len(voltage)
    chunk = max(1, int(round(HEATING_CHUNK_S * rate)))
    r0, rth, tau, alpha = (
        params["R"],
        heat["thermal_resistance_K_per_W"],
        heat["thermal_time_constant_s"],
        heat["copper_coefficient_per_K"],
    )
    kelvin = 0.0
    parts: list[dict] = []
    resistance = np.empty(n)
    for k0 in range(0, n, chunk):
        k1 = min(n, k0 + chunk)
        r = r0 * (1.0 + alpha * kelvin)
        # one sample more than the chunk: its first trace row is the state the next chunk starts from
        u = voltage[k0 : k1 + 1]
        out = sim.simulate({**params, "R": r}, u, state, prefer=solver_name, table=table)
        if k1 < n:
            state = {
                name: float(out[trace][k1 - k0])
                for name, trace in zip(sim.STATE_FIELDS, sim.TRACE_NAMES)
            }
        parts.append({key: value[: k1 - k0] for key, value in out.items()})
        resistance[k0:k1] = r
        power = float(np.mean(out["current_A"][: k1 - k0] ** 2)) * r
        decay = math.exp(-(k1 - k0) / rate / tau)
        kelvin = kelvin * decay + power * rth * (1.0 - decay)
    traces = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    traces["winding_resistance_ohm"] = resistance
    return traces


def _apply_overrides(effects: dict[str, dict], base: dict, overrides: dict) -> dict:
    """Merge user overrides into baseline and effect parameters; return the remaining options."""
    options = {}
    for key, value in overrides.items():
        if key in base:
            base[key] = float(value)
        elif key in effects:
            if not isinstance(value, dict):
                raise UserError(f"override for effect '{key}' must be a dict of its parameters")
            unknown = set(value) - set(effects[key])
            if unknown:
                raise UserError(
                    f"{key} has no parameter {sorted(unknown)[0]!r}; it has {', '.join(effects[key])}"
                )
            effects[key].update(value)
        elif key in OPTIONS:
            options[key] = value
        else:
            known = list(base) + list(effects) + list(OPTIONS)
            raise UserError(f"unknown override '{key}'; did you mean {close_matches(key, known)}?")
    return options


OPTIONS = (
    "randomize_baseline",
    "voltage_plateaus",
    "start_angle_rad",
    "current_noise_A",
    "substeps_per_ms",
    "integrator",
    "sample_rate_hz",
    "encoder_counts_per_rev",
)


def make_recording(
    effects=(), seed: int = 0, duration_s: float = 60.0, *, nominal, **overrides
) -> Recording:
    """A bench recording (1 kHz unless ``sample_rate_hz``) of the truth model of the described
    drive ``nominal`` (a :class:`~mechanism.dynamics.lumped.DriveNominal`) with the named
    concealed effects.

    ``effects``: names from :data:`mechanism.testbench.EFFECTS` (a list or ``"a,b"``;
    ``()`` or ``"none"`` is the clean machine). Overrides (keyword arguments):

    - any baseline parameter by name (``coulomb_arm_Nm=0.18``); ``randomize_baseline=False``
      uses the thesis's values;
    - an effect's parameters as a dict (``torque_ripple={"cogging_Nm": 0.0}``);
    - ``voltage_plateaus=[(duration_s, volts), ...]`` instead of the drawn profile,
      ``start_angle_rad``, ``current_noise_A`` (sensor standard deviation),
      ``substeps_per_ms`` (integrator, default 20), ``integrator="python"`` (skip the C build),
      ``sample_rate_hz`` (100-10000), ``encoder_counts_per_rev`` (default 20000).

    A drive whose shaft rocks (``nominal.travel_rad``) is moved point to point inside its travel
    (:mod:`mechanism.testbench.rocking`) instead of the 4-20 V plateaus, with its linkage table
    and stops in the truth; given ``voltage_plateaus`` (of either sign) it is driven open loop.
    """
    names = parse_effects(effects)
    seed = int(seed)
    duration_s = float(duration_s)
    if not math.isfinite(duration_s) or not 0.01 <= duration_s <= 3600:
        raise UserError(f"duration must be between 0.01 and 3600 s, not {duration_s}")
    randomize = bool(overrides.pop("randomize_baseline", True))
    rocks = getattr(nominal, "travel_rad", None) is not None
    if rocks:
        rocking.refuse_effects(names, nominal)
    refuse_without_fabric(names, nominal)
    base = draw_baseline(seed, nominal, randomize=randomize)
    effect_params = draw_effects(seed, names, base)
    options = _apply_overrides(effect_params, base, overrides)
    rate = float(options.get("sample_rate_hz", SAMPLE_RATE_HZ))
    if not 100 <= rate <= 10000:
        raise UserError(f"sample rate must be between 100 Hz and 10 kHz, not {rate:g}")
    counts = int(options.get("encoder_counts_per_rev", ENCODER_COUNTS_PER_REV))
    if counts < 16:
        raise UserError(f"an encoder needs at least 16 counts per revolution, not {counts}")
    step = TWO_PI / counts
    substeps_per_ms = int(options.get("substeps_per_ms", sim.SUBSTEPS_PER_MS))
    substeps = max(1, int(round(substeps_per_ms * 1000.0 / rate)))
    params, derived = _model_parameters(base, effect_params, substeps, rate)
    table = _rocking_truth(params, nominal, derived) if rocks else None
    for name, values in derived.items():
        effect_params[name].update(values)

    n = int(round(duration_s * rate))
    time = np.arange(n) / rate
    plateaus = options.get("voltage_plateaus") or ([] if rocks else draw_plateaus(seed, duration_s))
    plateaus = [(float(d), float(v)) for d, v in plateaus]
    if any(d <= 0 or not math.isfinite(v) or (v < 0 and not rocks) for d, v in plateaus):
        raise UserError(
            "voltage plateaus need positive durations and non-negative voltages"
            + ("" if rocks else " (a shaft that turns whole revolutions runs forward)")
        )

    sensors = stream(seed, "sensors")
    if rocks:
        start = float(options.get("start_angle_rad", rocking.start_angle(nominal, sensors)))
    else:
        start = float(options.get("start_angle_rad", sensors.uniform(0.0, TWO_PI)))
    noise = float(options.get("current_noise_A", sensors.uniform(0.01, 0.03)))
    state = dict(
        theta_arm=start,
        omega_arm=0.0,
        theta_motor=base["belt_ratio"] * start,
        omega_motor=0.0,
        current=0.0,
        warmth=0.0,
    )
    solver_name = options.get("integrator", "native")
    nonlinearity = effect_params.get("voltage_nonlinearity")
    moves: list[dict] = []
    if rocks and not plateaus:
        stepper = _chunk_stepper(
            params, solver_name, table, nonlinearity, effect_params.get("winding_heating"), rate
        )
        logged_voltage, chunks, moves = rocking.run(
            stepper, n, rate, state, stream(seed, "profile"), nominal, base["supply_V"]
        )
        traces = {key: np.concatenate([c[key] for c in chunks]) for key in chunks[0]}
        motor_voltage = traces.pop("applied_voltage_V")
    else:
        logged_voltage = voltage_samples(plateaus, n, rate)
        motor_voltage = applied_voltage(logged_voltage, nonlinearity)
        if "winding_heating" in effect_params:
            traces = _simulate_heating(
                params,
                motor_voltage,
                state,
                solver_name,
                effect_params["winding_heating"],
                rate,
                table,
            )
        else:
            traces = sim.simulate(params, motor_voltage, state, prefer=solver_name, table=table)
    traces["applied_voltage_V"] = motor_voltage

    sensed = traces["arm_angle_rad"]
    if "encoder_eccentricity" in effect_params:
        e = effect_params["encoder_eccentricity"]
        # the count is reset at the index pulse (needle TDC), so the error vanishes there
        sensed = sensed + e["amplitude_rad"] * (
            np.sin(sensed + e["phase_rad"]) - math.sin(e["phase_rad"])
        )
    if "sensor_delay" in effect_params:
        # the log shows what the sensor read delay_s ago (linear interpolation; the rest angle
        # before the start): the eccentric reading too, where the encoder has both
        sensed = np.interp(time - effect_params["sensor_delay"]["delay_s"], time, sensed)
    arm_angle = np.floor(sensed / step) * step
    current = (
        np.round((traces["current_A"] + sensors.normal(0.0, noise, n)) / CURRENT_RESOLUTION_A)
        * CURRENT_RESOLUTION_A
    )

    truth = {
        "format": TRUTH_FORMAT,
        "generator": f"mechanism {__version__} testbench",
        "seed": seed,
        "duration_s": duration_s,
        "sample_rate_Hz": rate,
        "effects": names,
        "effect_params": effect_params,
        "baseline": base,
        "baseline_randomized": randomize,
        "start_arm_angle_rad": start,
        "voltage_plateaus": [[d, v] for d, v in plateaus],
        "sensors": {
            "encoder_counts_per_rev": counts,
            "angle_step_rad": step,
            "current_noise_std_A": noise,
            "current_resolution_A": CURRENT_RESOLUTION_A,
        },
        "integrator": {"substeps_per_ms": substeps_per_ms, "solver": sim.solver(solver_name).name},
    }
    if rocks:
        lo, hi = nominal.travel_rad
        truth["rocking"] = {
            "stops_rad": [lo, hi],
            "safe_band_rad": list(rocking.safe_band(nominal)),
            "linkage_table": table is not None,
            "moves": moves,
        }
    return Recording(
        time,
        logged_voltage,
        arm_angle,
        current,
        truth,
        traces,
        zero_meaning=getattr(nominal, "zero_meaning", ZERO_MEANING),
    )


RECORDING_ENDINGS: dict[str, WriteFormat] = {
    ".csv": "csv",
    ".csv.gz": "csv.gz",
    ".parquet": "parquet",
    ".mat": "mat",
}


def recording_format(path: str | Path) -> tuple[WriteFormat, str]:
    """(format, ending) of a recording file name the bench writes; UserError for another."""
    name = Path(path).name.lower()
    for ending in sorted(RECORDING_ENDINGS, key=len, reverse=True):
        if name.endswith(ending) and len(name) > len(ending):
            return RECORDING_ENDINGS[ending], ending
    raise UserError(f"recording file name must end in {', '.join(RECORDING_ENDINGS)}: {path}")


def truth_path_for(csv_path: str | Path) -> Path:
    """``REC.csv`` (or ``.csv.gz``, ``.parquet``, ``.mat``) -> ``REC.truth.json`` next to it;
    UserError for another ending."""
    csv_path = Path(csv_path)
    _, ending = recording_format(csv_path)
    return csv_path.with_name(csv_path.name[: -len(ending)] + ".truth.json")


def write_recording(
    recording: Recording, csv_path: str | Path, fmt: WriteFormat | None = None
) -> tuple[Path, Path]:
    """Write the recording (contract columns only) in the format its name ends in (``fmt``,
    when given, must agree) and its truth JSON next to it, atomically."""
    from mechanism.files.formats import write_columns

    csv_path = Path(csv_path)
    truth_path = truth_path_for(csv_path)
    named = recording_format(csv_path)[0]
    if fmt is not None and fmt != named:
        raise UserError(f"--format {fmt} but the file name {csv_path.name} ends as a {named} file")
    truth = dict(recording.truth, recording=csv_path.name)
    counts = recording.truth["sensors"]["encoder_counts_per_rev"]
    comments = [
        f"mechanism virtual test bench recording ({recording.truth['sample_rate_Hz']:g} Hz); what is concealed in it is in {truth_path.name}",
        f"columns: time [s], voltage [V, commanded], arm_angle [rad, unwrapped, 0 = {recording.zero_meaning}, "
        f"{counts} counts/rev], current [A]",
        f"counts_per_rev: {counts}",
    ]
    with transaction():  # both files or neither; a failure never touches the previous pair
        write_columns(
            csv_path,
            recording.columns(),
            comments=comments,
            fmt=named,
            metadata={"counts_per_rev": str(counts)},
        )
        with atomic_file(truth_path) as handle:
            json.dump(_jsonable(truth), handle, indent=2)
            handle.write("\n")
    return csv_path, truth_path


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
