"""Batch clearance checks (the shaft of both models is `arm_shaft`) of design variants: throughput, parallel speed-up, cost per variant.

A batch of Monte Carlo variants (hook timing, needle height, crank radius tolerances) of
the needle-vs-hook clearance over one arm revolution at 0.5 deg:

- variants per second with 2 workers over the whole batch (1000 by default);
- speed-up from 1 to 2 workers on the same subset (target >= 1.7x on 2 idle cores);
- the cost of one variant relative to one simulated arm revolution: the same model
  stepped with ``mj_step`` through one turn at about 600 rpm.

Model: the shipped sewing machine (or ``MECHANISM_BENCH_MODEL``) when it has ``needle`` and
``hook`` parts, else the analytic needle/hook mechanism of the tests. ``python -m bench bench_clearance``
(``MECHANISM_BENCH_VARIANTS=N`` changes the batch size).
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

SPEED_RPM = 600.0


def _model():
    from mechanism.machine.models import DEFAULT_MODEL, load_model
    from mechanism.machine.parts import part_names

    path = Path(os.environ.get("MECHANISM_BENCH_MODEL", DEFAULT_MODEL))
    if path.exists():
        model = load_model(path)
        if {"needle", "hook"} <= set(part_names(model)):
            return model, f"sewing machine {path.name}", _sewing_timing(model)
    from tests.helpers import mechanisms

    return (
        mechanisms.needle_and_plate().compile(),
        "test needle/hook mechanism",
        "coupling:hook_drive:hook_deg",
    )


def _sewing_timing(model) -> str:
    import mechanism

    return mechanism.read_description(mechanism.load_machine().description.path).variant_presets[
        "hook_timing_deg"
    ]


def _variants(count: int, timing_target: str, scratch: Path):
    import json

    from mechanism.inspection.variants import read_variants

    doc = {
        "format": "mechanism-variants/1",
        "parameters": {
            "hook_timing_deg": timing_target,
            "needle_height_mm": "part:needle:z_mm",
            "crank_radius_mm": "joint:crank_pin:radial_mm",
        },
        "samples": {
            "count": count - 1,
            "seed": 1,
            "tolerances": {
                "hook_timing_deg": {"dist": "normal", "std": 1.0},
                "needle_height_mm": {"dist": "uniform", "low": -0.1, "high": 0.1},
                "crank_radius_mm": {"dist": "normal", "std": 0.02},
            },
        },
    }
    path = scratch / "variants.json"
    path.write_text(json.dumps(doc))
    return read_variants(path)  # the nominal design + count - 1 samples


def _subset(variants, count):
    from mechanism.inspection.variants import VariantSet

    return VariantSet(
        variants.parameters, variants.names[:count], variants.values[:count], variants.source
    )


def _timed(model, variants, pairs, workers):
    """A batch and the CPU seconds it used in this process and its workers."""
    from mechanism.inspection.variants import run_variants

    before = os.times()
    batch = run_variants(
        model, variants, pairs, driver="arm_shaft", workers=workers, progress=False
    )
    after = os.times()
    cpu = sum(
        getattr(after, f) - getattr(before, f)
        for f in ("user", "system", "children_user", "children_system")
    )
    return batch, cpu


def _revolution_seconds(model) -> tuple[float, int]:
    """Wall time of mj_step through one arm revolution at ~600 rpm (Python loop, as a user would)."""
    import mujoco
    import numpy as np

    from mechanism.kinematics.pose import solve_pose, velocity_ratios

    data = mujoco.MjData(model)
    omega = SPEED_RPM * 2 * np.pi / 60
    solve_pose(model, data, {"arm_shaft": 0.0})
    data.qvel[:] = omega * velocity_ratios(model, data, "arm_shaft")
    arm = model.joint("arm_shaft").qposadr[0]
    model.opt.gravity[:] = 0.0  # coast through the turn at nearly constant speed
    steps = 0
    started = time.perf_counter()
    while data.qpos[arm] < 2 * np.pi and steps < 1_000_000:
        mujoco.mj_step(model, data)
        steps += 1
    return time.perf_counter() - started, steps


def main() -> None:
    import copy

    from mechanism.inspection.clearance import Pair
    from mechanism.inspection.variants import run_variants

    count = int(os.environ.get("MECHANISM_BENCH_VARIANTS", "1000"))
    model, label, timing = _model()
    pairs = [Pair("needle", "hook")]
    from mechanism.files.limits import usable_cores

    cores = usable_cores()
    print(
        f"model: {label}; pair needle:hook; one revolution at 0.5 deg; {cores} CPU cores usable; "
        f"load average {os.getloadavg()[0]:.2f} (the machine may be shared: speed-ups are only meaningful when idle)"
    )
    with tempfile.TemporaryDirectory() as scratch:
        variants = _variants(count, timing, Path(scratch))
        subset = _subset(variants, min(len(variants), 60))
        # warm-up: imports, first calls
        run_variants(
            model, _subset(variants, 4), pairs, driver="arm_shaft", workers=1, progress=False
        )
        (one, cpu_one), (two, cpu_two) = (
            _timed(model, subset, pairs, workers) for workers in (1, 2)
        )
        print(
            f"{len(subset)} variants: 1 worker {one.seconds:.2f} s, 2 workers {two.seconds:.2f} s, "
            f"speed-up {one.seconds / two.seconds:.2f}x (target >= 1.7x on 2 idle cores); CPU time "
            f"{cpu_one:.2f} s vs {cpu_two:.2f} s (equal CPU = no parallel overhead: a lower speed-up means busy cores)"
        )
        batch = run_variants(model, variants, pairs, driver="arm_shaft", workers=2, progress=True)
        print(
            f"{len(variants)} variants with 2 workers: {batch.seconds:.1f} s, {len(variants) / batch.seconds:.1f} variants/s, "
            f"{batch.failed} fail (interfere)"
        )
    revolution, steps = _revolution_seconds(copy.deepcopy(model))
    per_variant = one.seconds / len(subset)
    print(
        f"one simulated revolution: {steps} mj_step calls in {revolution * 1e3:.1f} ms; one variant check "
        f"(1 worker): {per_variant * 1e3:.1f} ms = {per_variant / revolution:.2f} simulated revolutions"
    )


if __name__ == "__main__":
    main()
