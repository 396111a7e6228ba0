"""Dynamic design sweeps (`mechanism sweep`), each number a ratio against a reference run here.

- reduced model: N variants (flywheel inertia x voltage x motor resistance, 2 s simulated each)
  at 1 and 2 local workers: wall time, variants per second, speed-up 1 -> 2 workers, and the
  simulated-to-wall-time ratio of one worker;
- full model: M variants batched through ``mujoco.rollout`` on 2 threads against the same
  variants stepped by a Python loop of ``mj_step`` one after the other: time per variant and
  the ratio (the rows equal to rounding: same model, same steps).

Default N = 10000, M = 16. ``MECHANISM_BENCH_SWEEP=N``, ``MECHANISM_BENCH_SWEEP_FULL=M``.
``python -m bench bench_sweep``.
"""

from __future__ import annotations

import os
import time

import numpy as np


def _variants(count: int, shaft: str):
    from mechanism.inspection.variants import variants_from_document

    side = 10  # a 10 x 10 grid of flywheel and voltage, times count/100 motor resistances: count variants
    document = {
        "parameters": {
            "fly": f"inertia:{shaft}_kgm2",
            "V": "voltage_V",
            "R": "motor:resistance_ohm",
        },
        "sweep": {
            "fly": {"start": 0, "stop": 2e-3, "num": side},
            "V": {"start": 4, "stop": 14, "num": side},
            "R": {"start": -0.2, "stop": 0.4, "num": max(1, count // (side * side))},
        },
    }
    return variants_from_document(document)


def _reduced(machine, count: int) -> None:
    from mechanism.inspection.sweep import SweepOptions, run_sweep

    variants = _variants(count, machine.shaft_joint)
    options = SweepOptions(duration_s=2.0)
    from dataclasses import replace

    # warm-up: native library, caches
    run_sweep(
        machine,
        replace(variants, names=variants.names[:50], values=variants.values[:50]),
        options,
        progress=False,
    )
    times = {}
    for workers in (1, 2):
        start = time.perf_counter()
        result = run_sweep(machine, variants, options, workers=workers, progress=False)
        times[workers] = time.perf_counter() - start
    n = len(variants)
    notes = sum(1 for row in result.rows if row.get("note"))
    print(
        f"reduced model: {n} variants x {options.duration_s:g} s simulated; 1 worker {times[1]:.1f} s "
        f"({n / times[1]:.0f}/s, {n * options.duration_s / times[1]:.0f}x real time), 2 workers {times[2]:.1f} s "
        f"({n / times[2]:.0f}/s); speed-up 1 -> 2 workers {times[1] / times[2]:.2f}x; {notes} rows with a note"
    )


def _full(machine, count: int) -> None:
    import mujoco

    from mechanism.dynamics.simulation import simulate_batch
    from mechanism.inspection.sweep import variant_machine

    variants = _variants(count, machine.shaft_joint)
    chosen = np.linspace(0, len(variants) - 1, count).astype(int)
    built = [variant_machine(machine, variants.parameters, variants.values[i]) for i in chosen]
    duration_s = 2.0
    for (
        variant,
        _,
    ) in built:  # the linkage tables (tool height) outside the timing: both sides skip them
        variant.tables = machine.tables
    simulate_batch([m for m, _ in built[:2]], [v for _, v in built[:2]], 0.1, threads=2)  # warm-up
    start = time.perf_counter()
    results = simulate_batch([m for m, _ in built], [v for _, v in built], duration_s, threads=2)
    batched = time.perf_counter() - start
    start = time.perf_counter()
    speeds = []
    for variant, voltage in built:
        model, data = variant.model, variant.reset(0.0)
        data.ctrl[variant.actuator] = voltage
        for _ in range(int(round(duration_s / model.opt.timestep))):
            mujoco.mj_step(model, data)
        speeds.append(variant.shaft_velocity(data.qvel))
    looped = time.perf_counter() - start
    final = [r.shaft_velocity_rad_s[-1] for r in results]
    difference = float(np.max(np.abs(np.subtract(final, speeds))))
    print(
        f"full model: {count} variants x {duration_s:g} s; mujoco.rollout on 2 threads {batched / count * 1e3:.0f} ms per "
        f"variant, Python mj_step loop {looped / count * 1e3:.0f} ms per variant: rollout {looped / batched:.2f}x faster; "
        f"final speeds differ by {difference:.1e} rad/s"
    )


def main() -> None:
    import mechanism

    machine = mechanism.load_machine()
    _reduced(machine, int(os.environ.get("MECHANISM_BENCH_SWEEP", "10000")))
    _full(machine, int(os.environ.get("MECHANISM_BENCH_SWEEP_FULL", "16")))


if __name__ == "__main__":
    main()
