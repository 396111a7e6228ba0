"""Stepper models: cost of the actuator callbacks against a raw MuJoCo step of the same model.

The thesis's thread cut (0.7 s + 0.1 s settling) on each model, rolled out with
``mujoco.rollout``: with the stepper callbacks, and with no callbacks installed (the same
model, its actuator then does nothing). Prints the ratio and the real-time factor
(simulated seconds per wall-clock second). The Python fallback is timed on a short
stretch and reported per step against the native callbacks.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np
from mujoco import rollout

from mechanism import steppers
from mechanism.steppers import step_profiles


def _best_of(function, repeats=3):
    best = np.inf
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - started)
    return best


def main() -> None:
    params = steppers.pm25s048()
    profile = step_profiles.thread_cut()
    for kind in steppers.KINDS:
        mode = steppers.drive_mode("full")
        model = steppers.build_model(params, kind, mode)
        h = model.opt.timestep
        time_s = np.arange(int(np.ceil((profile.duration_s + 0.1) / h))) * h
        controls = steppers.command_array(params, mode, profile, time_s)[None, :, None]
        _, state0 = steppers.initial_state(model, params, mode, kind)
        data = mujoco.MjData(model)

        def roll():
            rollout.rollout(model, data, state0[None], controls)

        saved = mujoco.get_mjcb_act_dyn(), mujoco.get_mjcb_act_bias()
        mujoco.set_mjcb_act_dyn(None)
        mujoco.set_mjcb_act_bias(None)
        raw = _best_of(roll)
        backend = steppers.install()
        if backend != "native":
            print(f"{kind}: no C compiler, native callbacks unavailable")
            continue
        with_callbacks = _best_of(roll)
        whole = _best_of(lambda: steppers.simulate(profile, kind, mode, params), repeats=2)
        n_short = 4000
        states, short_controls = state0[None], controls[:, :n_short, 0]
        native_short = _best_of(
            lambda: steppers.run_rollout(model, states, short_controls, "native")
        )
        python_short = _best_of(
            lambda: steppers.run_rollout(model, states, short_controls, "python"), 1
        )
        simulated = time_s.size * h
        print(f"{kind} model, thread cut ({time_s.size} steps of {h * 1e6:g} us):")
        print(f"  raw mj_step rollout, no callbacks : {raw:.3f} s")
        print(
            f"  with stepper callbacks            : {with_callbacks:.3f} s  = {with_callbacks / raw:.2f}x raw, "
            f"{simulated / with_callbacks:.1f}x real time"
        )
        print(
            f"  steppers.simulate (with analysis)  : {whole:.3f} s  = {whole / raw:.2f}x raw, "
            f"{simulated / whole:.1f}x real time"
        )
        print(
            f"  Python fallback, {n_short} steps      : {python_short / native_short:.0f}x the native rollout "
            f"({python_short / n_short * 1e6:.0f} us per step)"
        )
        mujoco.set_mjcb_act_dyn(saved[0])
        mujoco.set_mjcb_act_bias(saved[1])


if __name__ == "__main__":
    main()
