"""Running step sequences on the bare motor (``mujoco.rollout``): one sequence, rate sweeps,
the pull-out rate and the static torque curve."""

from __future__ import annotations

import math
import time as _time

import numpy as np

from mechanism.errors import UserError
from mechanism.steppers._actuator import build_model, default_timestep
from mechanism.steppers._callbacks import CallbackBackend, install, python_callbacks
from mechanism.steppers._drive import (
    DriveMode,
    StepperKind,
    _physical_current,
    drive,
    drive_mode,
    rest_angle_rad,
    user_data,
)
from mechanism.steppers._motor import StepperParams, pm25s048
from mechanism.steppers._report import StepperRun, analyse
from mechanism.steppers.step_profiles import StepProfile

MAX_STEPS = 2_500_000  # one run's states stay under ~200 MB


def _state_slices(model):
    """Where time, qpos, qvel and act sit in a full-physics state vector."""
    import mujoco

    sizes, offset = {}, 0
    full = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    bit = 1
    while bit <= full:
        if full & bit:
            n = mujoco.mj_stateSize(model, bit)
            sizes[bit] = slice(offset, offset + n)
            offset += n
        bit <<= 1
    s = mujoco.mjtState
    return (
        sizes[int(s.mjSTATE_TIME)],
        sizes[int(s.mjSTATE_QPOS)],
        sizes[int(s.mjSTATE_QVEL)],
        sizes[int(s.mjSTATE_ACT)],
    )


def initial_state(model, params: StepperParams, mode: DriveMode, kind: StepperKind):
    """The motor at rest at step 0, energised (currents at their references)."""
    import mujoco

    data = mujoco.MjData(model)
    start = float(rest_angle_rad(params, mode))
    data.qpos[0] = start
    if kind == "circuit":
        _, ref_a, ref_b = drive(params, mode, start)
        data.act[:2] = [float(ref_a), float(ref_b)]
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return data, state


def command_array(
    params: StepperParams, mode: DriveMode, profile: StepProfile, time_s: np.ndarray
) -> np.ndarray:
    """The actuator's control (commanded shaft angle, rad) at each step."""
    return rest_angle_rad(params, mode, profile.position_steps(time_s))


def run_rollout(
    model, states0: np.ndarray, controls: np.ndarray, backend: CallbackBackend = "auto"
):
    """Roll out ``controls`` (nbatch x nstep) from ``states0`` (nbatch x nstate); returns the
    states *before* each step and the sensor data of each step, aligned in time."""
    import mujoco

    installed = install(backend)
    nbatch, nstep = controls.shape
    data = mujoco.MjData(model)
    if installed == "native":
        from mujoco import rollout

        state, sensor = rollout.rollout(model, data, states0, controls[:, :, None])
    else:
        state = np.empty((nbatch, nstep, states0.shape[1]))
        sensor = np.empty((nbatch, nstep, model.nsensordata))
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        with python_callbacks():
            for b in range(nbatch):
                mujoco.mj_setState(model, data, states0[b], full)
                for k in range(nstep):
                    data.ctrl[0] = controls[b, k]
                    mujoco.mj_step(model, data)
                    mujoco.mj_getState(model, data, state[b, k], full)
                    sensor[b, k] = data.sensordata
    before = np.concatenate([states0[:, None, :], state[:, :-1, :]], axis=1)
    return before, sensor, installed


def simulate(
    profile: StepProfile,
    kind: StepperKind = "circuit",
    mode: str | DriveMode = "full",
    params: StepperParams | None = None,
    timestep: float | None = None,
    settle_s: float = 0.1,
    backend: CallbackBackend = "auto",
) -> StepperRun:
    """Run ``profile`` on the bare motor and analyse it (``run.summary``)."""
    params = params or pm25s048()
    mode = drive_mode(mode) if isinstance(mode, str) else mode
    model = build_model(params, kind, mode, timestep)
    h = model.opt.timestep
    nstep = int(math.ceil((profile.duration_s + settle_s) / h))
    if nstep > MAX_STEPS:
        raise UserError(
            f"{profile.name}: {profile.duration_s + settle_s:g} s is too long for one run of the {kind} model "
            f"(at most {MAX_STEPS * h:g} s, {MAX_STEPS} steps of {h:g} s)"
        )
    time_s = np.arange(nstep) * h
    controls = command_array(params, mode, profile, time_s)
    _, state0 = initial_state(model, params, mode, kind)
    started = _time.perf_counter()
    before, sensor, installed = run_rollout(model, state0[None], controls[None], backend)
    wall = _time.perf_counter() - started
    run = _make_run(model, params, kind, mode, profile, time_s, controls, before[0], sensor[0])
    run.backend, run.wall_s = installed, wall
    run.summary = analyse(run)
    return run


def _make_run(model, params, kind, mode, profile, time_s, controls, before, sensor) -> StepperRun:
    _, qpos, qvel, act = _state_slices(model)
    start = float(rest_angle_rad(params, mode))
    phi, _, _ = drive(params, mode, controls)
    rotor = before[:, qpos][:, 0]
    if kind == "circuit":
        currents = before[:, act][:, :2]
        current_a, current_b = currents[:, 0].copy(), currents[:, 1].copy()
    else:  # the physical model's one current (eq. 25), reported on the driver's phase pattern
        _, ref_a, ref_b = drive(params, mode, controls)
        scale = (
            _physical_current(user_data(params, kind, mode), before[:, qvel][:, 0])
            / params.rated_current_A
        )
        current_a, current_b = ref_a * scale, ref_b * scale
    return StepperRun(
        kind=kind,
        mode=mode,
        params=params,
        profile=profile,
        time_s=time_s,
        command_deg=np.degrees(phi / params.pole_pairs - start),
        rotor_deg=np.degrees(rotor - start),
        speed_rad_s=before[:, qvel][:, 0].copy(),
        current_a_A=current_a,
        current_b_A=current_b,
        torque_Nm=sensor[:, 0].copy(),
    )


def sweep_rates(
    rates,
    kind: StepperKind = "circuit",
    mode: str | DriveMode = "full",
    params: StepperParams | None = None,
    ramp_s: float = 0.1,
    hold_s: float = 0.05,
    settle_s: float = 0.05,
    backend: CallbackBackend = "auto",
    progress: bool = False,
) -> list[dict]:
    """Ramp up to each rate, hold, ramp down and settle; report the slips. The rate at
    which slips start is the pull-out rate (the ramps keep pull-in effects out)."""
    from mechanism.steppers.step_profiles import from_rates

    params = params or pm25s048()
    mode = drive_mode(mode) if isinstance(mode, str) else mode
    model = build_model(params, kind, mode)
    h = model.opt.timestep
    total = 2 * ramp_s + hold_s + settle_s
    time_s = np.arange(int(math.ceil(total / h))) * h
    _, state0 = initial_state(model, params, mode, kind)
    results = []
    iterator = rates
    if progress:
        from tqdm import tqdm

        iterator = tqdm(rates, desc=f"{kind} sweep", unit="rate", leave=False)
    for rate in iterator:
        rate = float(rate)
        profile = from_rates(
            f"ramp to {rate:g} steps/s",
            [0, ramp_s, ramp_s + hold_s, 2 * ramp_s + hold_s],
            [0, rate, rate, 0],
        )
        controls = command_array(params, mode, profile, time_s)
        before, sensor, installed = run_rollout(model, state0[None], controls[None], backend)
        run = _make_run(model, params, kind, mode, profile, time_s, controls, before[0], sensor[0])
        summary = analyse(run)
        results.append(
            {
                "rate_steps_s": rate,
                "lost_steps": summary["lost_steps"],
                "slips": len(summary["slips"]),
                "final_error_deg": summary["final_error_deg"],
            }
        )
    return results


def pull_out_rate(
    kind: StepperKind = "circuit",
    mode: str | DriveMode = "full",
    params: StepperParams | None = None,
    low: float = 250.0,
    high: float = 6000.0,
    resolution: float = 25.0,
    **kwargs,
) -> float | None:
    """The lowest step rate [steps/s] at which the motor loses steps on a ramped move,
    found by bisection between ``low`` (must hold) and ``high``; None if ``high`` holds."""

    def loses(rate):
        result = sweep_rates([rate], kind, mode, params, **kwargs)[0]
        return result["lost_steps"] > 0 or result["slips"] > 0

    if not loses(high):
        return None
    if loses(low):
        return low
    while high - low > resolution:
        middle = 0.5 * (low + high)
        if loses(middle):
            high = middle
        else:
            low = middle
    return high


def holding_torque(
    displacement_rad,
    kind: StepperKind = "circuit",
    mode: str | DriveMode = "full",
    params: StepperParams | None = None,
    hold_s: float = 0.004,
    backend: CallbackBackend = "auto",
) -> np.ndarray:
    """Static torque [N m] with the rotor held at ``displacement_rad`` from the rest position
    of step 0, motor energised (the data sheet's torque-displacement curve). The rotor is
    held by giving it a huge inertia; the torque is averaged over the second half of
    ``hold_s`` (whole chopper periods), after the currents have settled."""
    params = params or pm25s048()
    mode = drive_mode(mode) if isinstance(mode, str) else mode
    displacement = np.atleast_1d(np.asarray(displacement_rad, dtype=float))
    held = params.replace(rotor_inertia_kg_m2=1e6, load_inertia_kg_m2=0.0)
    model = build_model(held, kind, mode, timestep=default_timestep(params, kind))
    h = model.opt.timestep
    nstep = int(round(hold_s / h))
    _, qpos, _, _ = _state_slices(model)
    _, state0 = initial_state(model, params, mode, kind)
    states = np.repeat(state0[None], displacement.size, axis=0)
    states[:, qpos.start] += displacement
    controls = np.full((displacement.size, nstep), float(rest_angle_rad(params, mode)))
    _, sensor, _ = run_rollout(model, states, controls, backend)
    return sensor[:, nstep // 2 :, 0].mean(axis=1)
