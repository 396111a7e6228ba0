"""Integrate the truth model: compiled C (``mechanism/native/testbench.c``) or its Python twin.

Both follow the same fixed-sub-step scheme (see the C file's header): the current
implicitly in R/L, velocities semi-implicitly with the set-valued Coulomb friction solved
exactly (a stuck arm stays exactly still, no creep), then angles from the new
velocities. The Python twin exists for machines without a C compiler; it is 20-40 times slower (a few seconds
per 60 s recording), and a test checks that the two agree.
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

SUBSTEPS_PER_MS = 20  # 50 us: belt resonances up to ~100 Hz, 1 ms electrical time constants

# Field order mirrors ``tb_params`` in mechanism/native/testbench.c (all doubles).
PARAM_FIELDS = (
    "dt",
    "n_sub",
    "belt",
    "R",
    "L",
    "Kt",
    "Ke",
    "ratio",
    "J_motor",
    "J_arm0",
    "d_motor",
    "coulomb",
    "pf_a1",
    "pf_p1",
    "pf_a2",
    "pf_p2",
    "st_model",
    "st_excess",
    "st_velocity",
    "st_exponent",
    "th_coulomb_drop",
    "th_viscous_drop",
    "th_tau_warm",
    "th_tau_cool",
    "rp_a1",
    "rp_p1",
    "rp_ac",
    "rp_pc",
    "rp_nc",
    "motor_phase0",
    "lk_mass",
    "lk_r",
    "lk_l",
    "gravity",
    "nd_force_per_m",
    "nd_fabric",
    "nd_point",
    "nd_sliding",
    "nd_depth_bdc",
    "belt_k",
    "belt_c",
    "bl_gap",
    "stop_on",
    "stop_lo",
    "stop_hi",
    "tb_n",
    "tb_lo",
    "tb_hi",
)
STATE_FIELDS = ("theta_arm", "omega_arm", "theta_motor", "omega_motor", "current", "warmth")
TRACE_NAMES = (
    "arm_angle_rad",
    "arm_velocity_rad_s",
    "motor_angle_rad",
    "motor_velocity_rad_s",
    "current_A",
    "warmth",
)
STRIBECK_MODELS = {"none": 0.0, "tustin": 1.0, "hess_soom": 2.0}


class _Params(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in PARAM_FIELDS]


@dataclass
class Solver:
    """The integrator in use: ``native`` (C) or ``python``."""

    name: str
    # the C tb_simulate (through ctypes) or _simulate_python; their results are unused
    function: Callable[..., object]


_SOLVER: Solver | None = None


def solver(prefer: str = "native") -> Solver:
    """The compiled integrator when a C compiler exists, else the Python twin."""
    global _SOLVER
    if prefer == "python":
        return Solver("python", _simulate_python)
    if _SOLVER is None:
        from mechanism import native

        library = native.load("testbench")
        if library is None:  # native.load has said why
            _SOLVER = Solver("python", _simulate_python)
        else:
            function = library.tb_simulate
            pointer = ctypes.POINTER(ctypes.c_double)
            function.argtypes = (
                ctypes.POINTER(_Params),
                ctypes.c_int,
                pointer,
                pointer,
                *(pointer,) * 7,
            )
            function.restype = ctypes.c_int
            _SOLVER = Solver("native", function)
    return _SOLVER


def simulate(
    params: dict[str, float],
    applied_voltage: np.ndarray,
    state: dict[str, float],
    prefer: str = "native",
    table: np.ndarray | None = None,
    end: dict[str, float] | None = None,
) -> dict[str, np.ndarray]:
    """Integrate from ``state`` with ``applied_voltage[k]`` held over sample k.

    ``params`` holds every name in PARAM_FIELDS. Returns the state at each sample time
    (before that sample's voltage acts) as arrays named in TRACE_NAMES. ``table``: the
    linkage table (``tb_n`` rows of J_var, J'/2, G over ``tb_lo``..``tb_hi``) when ``tb_n`` > 0.
    ``end``: filled with the state after the last sample (where the next call starts).
    """
    missing = [name for name in PARAM_FIELDS if name not in params]
    if missing:
        raise ValueError(f"truth-model parameters missing: {missing}")
    u = np.ascontiguousarray(applied_voltage, dtype=float)
    n = len(u)
    outputs = [np.zeros(n) for _ in TRACE_NAMES]
    state_array = np.array([float(state[name]) for name in STATE_FIELDS])
    rows = int(params["tb_n"])
    if rows > 0 and (table is None or np.shape(table) != (rows, 3) or rows < 2):
        raise ValueError(f"the linkage table needs {rows} rows of 3 values (at least 2)")
    flat = np.ascontiguousarray(table if rows > 0 else np.zeros((1, 3)), dtype=float).ravel()
    chosen = solver(prefer)
    if chosen.name == "native":
        struct = _Params(**{name: float(params[name]) for name in PARAM_FIELDS})
        pointer = ctypes.POINTER(ctypes.c_double)
        chosen.function(
            ctypes.byref(struct),
            n,
            u.ctypes.data_as(pointer),
            state_array.ctypes.data_as(pointer),
            *(array.ctypes.data_as(pointer) for array in outputs),
            flat.ctypes.data_as(pointer),
        )
    else:
        _simulate_python(params, u, state_array, outputs, flat)
    if end is not None:
        end.update(zip(STATE_FIELDS, (float(v) for v in state_array)))
    return dict(zip(TRACE_NAMES, outputs))


# --- the Python twin of testbench.c (same operations in the same order) ---------------


def _slider(p, th):
    s, c, r = math.sin(th), math.cos(th), p["lk_r"]
    big_s = math.sqrt(p["lk_l"] * p["lk_l"] - r * r * s * s)
    g = r * r * s * c
    return (
        r * c + big_s,
        -r * s - g / big_s,
        -r * c - r * r * (c * c - s * s) / big_s - g * g / (big_s * big_s * big_s),
    )


def _overlap(a, b, total):
    lo = a if a > 0.0 else 0.0
    hi = b if b < total else total
    return hi - lo if hi > lo else 0.0


def _needle_torque(p, th):
    if p["nd_force_per_m"] <= 0.0:
        return 0.0
    z, dz, _ = _slider(p, th)
    tip = z - (p["lk_l"] - p["lk_r"]) - p["nd_depth_bdc"]
    depth = p["nd_fabric"] - tip
    if depth <= 0.0:
        return 0.0
    shank = _overlap(-1e9, depth - p["nd_point"], p["nd_fabric"])
    force = p["nd_sliding"] * shank
    phase = th - 2.0 * math.pi * math.floor(th / (2.0 * math.pi))
    if phase < math.pi:
        force += _overlap(depth - p["nd_point"], depth, p["nd_fabric"])
    return p["nd_force_per_m"] * force * abs(dz)


def _friction_levels(p, th, speed, warmth):
    level = p["coulomb"] * (1.0 - p["th_coulomb_drop"] * warmth)
    level *= (
        1.0 + p["pf_a1"] * math.cos(th - p["pf_p1"]) + p["pf_a2"] * math.cos(2.0 * th - p["pf_p2"])
    )
    decay = 0.0
    if p["st_model"] == 1.0:
        decay = math.exp(-math.pow(speed / p["st_velocity"], p["st_exponent"]))
    elif p["st_model"] == 2.0:
        decay = 1.0 / (1.0 + (speed / p["st_velocity"]) * (speed / p["st_velocity"]))
    fabric = _needle_torque(p, th)
    return level * (1.0 + p["st_excess"] * decay) + fabric, level * (1.0 + p["st_excess"]) + fabric


def _belt_torque(p, twist, rate):
    gap = p["bl_gap"]
    if twist > gap:
        return p["belt_k"] * (twist - gap) + p["belt_c"] * rate
    if twist < -gap:
        return p["belt_k"] * (twist + gap) + p["belt_c"] * rate
    return 0.0


def _ripple(p, thm):
    return p["rp_a1"] * math.sin(thm + p["rp_p1"]) + p["rp_ac"] * math.sin(
        p["rp_nc"] * thm + p["rp_pc"]
    )


def _linkage_table(p, table, th):
    n = int(p["tb_n"])
    x = (th - p["tb_lo"]) / (p["tb_hi"] - p["tb_lo"]) * (n - 1)
    x = min(max(x, 0.0), float(n - 1))
    i = min(int(x), n - 2)
    f = x - i
    row, nxt = table[3 * i : 3 * i + 3], table[3 * i + 3 : 3 * i + 6]
    return tuple(float(a + f * (b - a)) for a, b in zip(row, nxt))


def _friction_step(inertia, v, h, tau, c, kinetic, static):
    level = static if v == 0.0 else kinetic
    impulse = inertia * v / h + tau
    if abs(impulse) <= level:
        return 0.0
    return (impulse - math.copysign(level, impulse)) / (inertia / h + c)


def _simulate_python(p, u, state, outputs, table=None):
    tha, wa, thm, wm, cur, x = (float(v) for v in state)
    n_sub = int(p["n_sub"])
    h = p["dt"] / n_sub
    ratio = p["ratio"]
    out_tha, out_wa, out_thm, out_wm, out_cur, out_x = outputs
    mass = p["lk_mass"]
    for k in range(len(u)):
        uk = float(u[k])
        if p["L"] <= 0.0:
            cur = (uk - p["Ke"] * wm) / p["R"]
        out_tha[k], out_wa[k], out_thm[k], out_wm[k], out_cur[k], out_x[k] = (
            tha,
            wa,
            thm,
            wm,
            cur,
            x,
        )
        for _ in range(n_sub):
            if mass > 0.0:
                _, dz, ddz = _slider(p, tha)
                inertia = p["J_arm0"] + mass * dz * dz
                tau_link = -mass * dz * ddz * wa * wa - mass * p["gravity"] * dz
            else:
                inertia, tau_link = p["J_arm0"], 0.0
            if p["tb_n"] > 0.0:
                jv, hdj, g = _linkage_table(p, table, tha)
                inertia += jv
                tau_link += -hdj * wa * wa - g
            d = p["d_motor"] * (1.0 - p["th_viscous_drop"] * x)
            kinetic, static = _friction_levels(p, tha, abs(wa), x)
            if p["L"] > 0.0:
                cur = (cur + h / p["L"] * (uk - p["Ke"] * wm)) / (1.0 + h * p["R"] / p["L"])
                drive, damping = p["Kt"] * cur, d
            else:
                drive, damping = p["Kt"] * uk / p["R"], d + p["Kt"] * p["Ke"] / p["R"]
            if p["belt"] == 0.0:
                tau = ratio * (drive - _ripple(p, thm)) + tau_link
                wa = _friction_step(inertia, wa, h, tau, ratio * ratio * damping, kinetic, static)
                wm = ratio * wa
            else:
                belt = _belt_torque(p, thm / ratio - tha, wm / ratio - wa)
                tau_m = drive - _ripple(p, thm) - belt / ratio
                wm = (p["J_motor"] * wm / h + tau_m) / (p["J_motor"] / h + damping)
                wa = _friction_step(inertia, wa, h, belt + tau_link, 0.0, kinetic, static)
            tha += h * wa
            thm += h * wm
            if p["stop_on"] != 0.0 and (tha > p["stop_hi"] or tha < p["stop_lo"]):
                # inelastic: the arm stops at the stop
                tha = p["stop_hi"] if tha > p["stop_hi"] else p["stop_lo"]
                if (tha == p["stop_hi"] and wa > 0.0) or (tha == p["stop_lo"] and wa < 0.0):
                    wa = 0.0
                if p["belt"] == 0.0:
                    thm, wm = ratio * tha, ratio * wa
            if p["L"] <= 0.0:
                cur = (uk - p["Ke"] * wm) / p["R"]
            if p["th_tau_warm"] > 0.0:
                if wa != 0.0:
                    x += h * (1.0 - x) / p["th_tau_warm"]
                else:
                    x -= h * x / p["th_tau_cool"]
    state[:] = (tha, wa, thm, wm, cur, x)
