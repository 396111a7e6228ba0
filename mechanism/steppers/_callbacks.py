"""The actuator callbacks: the compiled ones (``mechanism/native/stepper.c``) and their Python
twin, used where no C compiler exists."""

from __future__ import annotations

import contextlib
import ctypes
import functools
import math
import warnings
from typing import Literal

from mechanism.errors import UserError
from mechanism.steppers._drive import (
    CIRCUIT_ACTDIM,
    KIND_CODES,
    MARKER,
    USER_CHOP_HZ,
    USER_CURRENT,
    USER_DECAY_MARGIN,
    USER_FLUX,
    USER_INDUCTANCE,
    USER_KIND,
    USER_MARKER,
    USER_POLE_PAIRS,
    USER_RESISTANCE,
    USER_SIZE,
    USER_SUPPLY,
    _circuit_torque,
    _drive,
    _physical_torque,
)


@functools.lru_cache(maxsize=None)
def _native():
    from mechanism import native

    lib = native.load("stepper")
    if lib is not None:
        lib.stepper_set_next.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    return lib


def _address(callback) -> int | None:
    try:
        return ctypes.cast(callback, ctypes.c_void_p).value
    except (ctypes.ArgumentError, TypeError):
        return None


CallbackBackend = Literal["auto", "native", "python"]  # auto: native where a C compiler is


def install(backend: CallbackBackend = "auto") -> Literal["native", "python"]:
    """Install the stepper callbacks; returns the backend installed: ``native`` (the C
    callbacks, kept installed; idempotent) or, with ``backend="python"`` or where no C
    compiler exists, ``python``. A callback of another part installed before ours as a C
    function pointer keeps serving its own actuators (ours forward to it).

    Python callbacks must not stay installed while models are compiled (MuJoCo's compiler
    calls them with a model the bindings cannot wrap): use :func:`python_callbacks` around
    a stepping loop instead of installing them for good."""
    import mujoco

    lib = _native() if backend in ("auto", "native") else None
    if backend == "native" and lib is None:
        raise UserError("the compiled stepper callbacks are not available (no C compiler)")
    if lib is None:
        return "python"
    ours_dyn, ours_bias = _address(lib.stepper_act_dyn), _address(lib.stepper_act_bias)
    current_dyn, current_bias = mujoco.get_mjcb_act_dyn(), mujoco.get_mjcb_act_bias()
    if _address(current_dyn) == ours_dyn and _address(current_bias) == ours_bias:
        return "native"
    if (
        callable(current_dyn)
        and _address(current_dyn) is None
        or callable(current_bias)
        and _address(current_bias) is None
    ):
        warnings.warn(
            "replacing a Python MuJoCo actuator callback with the compiled stepper callbacks"
        )
    next_dyn, next_bias = _address(current_dyn), _address(current_bias)
    lib.stepper_set_next(
        None if next_dyn == ours_dyn else next_dyn, None if next_bias == ours_bias else next_bias
    )
    mujoco.set_mjcb_act_dyn(lib.stepper_act_dyn)
    mujoco.set_mjcb_act_bias(lib.stepper_act_bias)
    return "native"


@contextlib.contextmanager
def python_callbacks():
    """The Python stepper callbacks installed for the duration of a stepping loop; the
    callbacks installed before are restored afterwards."""
    import mujoco

    previous = mujoco.get_mjcb_act_dyn(), mujoco.get_mjcb_act_bias()
    mujoco.set_mjcb_act_dyn(_py_act_dyn)
    mujoco.set_mjcb_act_bias(_py_act_bias)
    try:
        yield
    finally:
        mujoco.set_mjcb_act_dyn(previous[0])
        mujoco.set_mjcb_act_bias(previous[1])


def _py_params(m, actuator_id: int):
    if m.nuser_actuator < USER_SIZE:
        return None
    u = m.actuator_user[actuator_id]
    return u if u[USER_MARKER] == MARKER else None


def _sgn(x: float) -> float:
    return math.copysign(1.0, x) if x else 0.0


def _py_chopper_phase(u, i, ref, emf, tick, h, on):
    supply, r, l = u[USER_SUPPLY], u[USER_RESISTANCE], u[USER_INDUCTANCE]
    margin = u[USER_DECAY_MARGIN] * u[USER_CURRENT]
    reached = ref != 0 and i * _sgn(ref) >= abs(ref)
    if ref == 0:
        on = 0.0
    elif tick:
        on = 0.0 if reached else 1.0
    elif on and reached:
        on = 0.0
    if on:
        return (supply * _sgn(ref) - r * i - emf) / l, on
    must_fall = i != 0 and (ref == 0 or i * ref < 0 or abs(i) > abs(ref) + margin)
    if not must_fall:
        return (0.0 if ref == 0 else (-r * i - emf) / l), on
    di = (-supply * _sgn(i) - r * i - emf) / l
    if (i + h * di) * i < 0:
        di = -i / h
    return di, on


def _py_act_dyn(m, d, actuator_id):
    u = _py_params(m, actuator_id)
    if (
        u is None
        or u[USER_KIND] != KIND_CODES["circuit"]
        or m.actuator_actnum[actuator_id] != CIRCUIT_ACTDIM
    ):
        return 0.0
    out, adr = m.actuator_outadr[actuator_id], m.actuator_actadr[actuator_id]
    theta, omega = d.actuator_length[out], d.actuator_velocity[out]
    p, psi, h, t, f = u[USER_POLE_PAIRS], u[USER_FLUX], m.opt.timestep, d.time, u[USER_CHOP_HZ]
    tick = math.floor(t * f + 1e-6) != math.floor((t - h) * f + 1e-6)
    _, ref_a, ref_b = (float(x) for x in _drive(u, d.ctrl[m.actuator_ctrladr[actuator_id]]))
    emf_a = -p * psi * math.sin(p * theta) * omega
    emf_b = -p * psi * math.sin(p * theta - 0.5 * math.pi) * omega
    act = d.act[adr : adr + CIRCUIT_ACTDIM].copy()
    on_a, on_b = float(act[2] > 0.5), float(act[3] > 0.5)
    di_a, on_a = _py_chopper_phase(u, act[0], ref_a, emf_a, tick, h, on_a)
    di_b, on_b = _py_chopper_phase(u, act[1], ref_b, emf_b, tick, h, on_b)
    d.act_dot[adr : adr + CIRCUIT_ACTDIM] = [di_a, di_b, (on_a - act[2]) / h, (on_b - act[3]) / h]
    return 0.0


def _py_act_bias(m, d, actuator_id):
    u = _py_params(m, actuator_id)
    if u is None:
        return 0.0
    out = m.actuator_outadr[actuator_id]
    theta, omega = d.actuator_length[out], d.actuator_velocity[out]
    if u[USER_KIND] == KIND_CODES["circuit"] and m.actuator_actnum[actuator_id] == CIRCUIT_ACTDIM:
        adr = m.actuator_actadr[actuator_id]
        return float(_circuit_torque(u, theta, d.act[adr], d.act[adr + 1]))
    if u[USER_KIND] == KIND_CODES["physical"]:
        return float(_physical_torque(u, theta, omega, d.ctrl[m.actuator_ctrladr[actuator_id]]))
    return 0.0
