"""Speed of the sewing-machine dynamics, as ratios measured in one run.

- our step: the machine (native <dcmotor>, friction constraints, compiled passive
  callback) stepped by mujoco.rollout at 12 V;
- reference: a raw mj_step of the same converted MJCF without actuator or callbacks,
  coasting at the same speed (so the constraint solver has the same work);
- real-time factor of the full model, and of the reduced 1-DOF model.
Targets (issue 4): full model >= 20x real time on one core with <= 30 % callback overhead;
reduced model >= 1000x real time.
"""

from __future__ import annotations

import time

import mujoco
import mujoco.rollout
import numpy as np

from mechanism.kinematics.pose import solve_pose, velocity_ratios
from mechanism.machine.machine import Machine
from mechanism.machine.models import DEFAULT_MODEL, load_model
from mechanism.dynamics.reduced import ReducedModel
from mechanism.dynamics.simulation import simulate

SIM_SECONDS = 10.0


def best_of(fn, repeats=5):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def raw_step_seconds(model_path, arm_speed, nstep):
    model = load_model(model_path)
    model.opt.timestep = Machine().model.opt.timestep
    data = mujoco.MjData(model)
    solve_pose(model, data, {"arm_shaft": 0.3})
    data.qvel[:] = arm_speed * velocity_ratios(model, data, "arm_shaft")
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    control = np.zeros((1, nstep, model.nu))
    return (
        best_of(lambda: mujoco.rollout.rollout(model, data, state[None], control, nstep=nstep))
        / nstep
    )


def main() -> None:
    machine = Machine()
    dt = machine.model.opt.timestep
    nstep = int(SIM_SECONDS / dt)
    run = simulate(12.0, SIM_SECONDS, machine=machine)
    arm_speed = float(run.shaft_velocity_rad_s[-1000:].mean())
    full = best_of(lambda: simulate(12.0, SIM_SECONDS, machine=machine), repeats=3)
    ours_per_step = full / nstep
    raw_per_step = raw_step_seconds(DEFAULT_MODEL, arm_speed, nstep)
    reduced = ReducedModel(machine)
    reduced.simulate(12.0, 1.0)  # compile the kernel outside the timing
    red = best_of(lambda: reduced.simulate(12.0, SIM_SECONDS))
    print(
        f"model: {DEFAULT_MODEL.name}, time step {dt * 1e3:g} ms, {SIM_SECONDS:g} s simulated at 12 V "
        f"(arm {arm_speed * 60 / (2 * np.pi):.0f} rpm), native callbacks: {machine.native}"
    )
    print(f"full model real-time factor            {SIM_SECONDS / full:8.1f} x   (target >= 20)")
    print(
        f"our step / raw mj_step (same MJCF)      {ours_per_step / raw_per_step:8.2f}     (target <= 1.30)"
    )
    print(f"  our step {ours_per_step * 1e6:.2f} us, raw step {raw_per_step * 1e6:.2f} us")
    print(f"reduced model real-time factor         {SIM_SECONDS / red:8.0f} x   (target >= 1000)")
    print(f"reduced speed-up over the full model   {full / red:8.0f} x")


if __name__ == "__main__":
    main()
