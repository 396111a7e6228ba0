"""Batch work (mechanism.batch) from 1 to 2 workers: fleet diagnosis and clearance variants.

- fleet diagnosis of N recordings at 1 and at 2 local workers: speed-up of the fleet, and
  its wall time per recording relative to a single ``diagnose`` run (the 1-worker fleet
  runs them one by one in this process, so its per-recording times are those single runs);
- clearance variants (needle vs hook, Monte Carlo tolerances as in bench_clearance) at 1
  and at 2 workers.

Default: the 3 shipped virtual-bench recordings and 40 variants (about a minute on 2
cores). ``MECHANISM_BENCH_FLEET=100`` diagnoses 100 recordings of 60 s generated on the
virtual bench (seeds 1..100, cycling through clean, torque ripple, position friction);
``MECHANISM_BENCH_FLEET_REFERENCE=K`` times single runs of the first K only;
``MECHANISM_BENCH_BATCH_VARIANTS=N`` changes the variant count. ``python -m bench bench_batch``.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
EFFECT_CYCLE = ((), ("torque_ripple",), ("position_friction",))


def _recordings(count: int, folder: Path) -> list[Path]:
    """The shipped recordings, or ``count`` generated ones when more are asked for."""
    shipped = sorted((REPO / "assets" / "recordings").glob("*.csv"))
    if count <= len(shipped):
        return shipped[:count]
    from mechanism.api import drive_nominal
    from mechanism.testbench.recording import make_recording, write_recording

    nominal = drive_nominal(None)  # the thesis's lumped drive, as the shipped recordings
    paths = []
    for seed in range(1, count + 1):
        path = folder / f"bench_seed{seed}.csv"
        write_recording(
            make_recording(
                EFFECT_CYCLE[seed % len(EFFECT_CYCLE)], seed=seed, duration_s=60.0, nominal=nominal
            ),
            path,
        )
        paths.append(path)
    return paths


def _fleet(paths, scratch: Path, reference: int | None = None) -> None:
    """The 1-worker fleet runs each diagnosis alone in this process: its per-recording times
    are single runs, the reference for the per-recording cost in the 2-worker fleet (the time
    each recording took in its worker). ``reference``: single runs of the first N recordings only."""
    import numpy as np

    from mechanism.api import drive_nominal
    from mechanism.sysid.fleet import diagnose_fleet

    singles = paths[: reference or len(paths)]
    results = {}
    for workers, batch in ((1, singles), (2, paths)):
        results[workers] = diagnose_fleet(
            batch,
            scratch / f"fleet{workers}",
            workers=workers,
            progress=False,
            nominal=drive_nominal(None),
        )
        shutil.rmtree(scratch / f"fleet{workers}")
        failed = [row for row in results[workers].rows if row["status"] != "ok"]
        assert not failed, f"{len(failed)} recordings failed: {failed[0].get('error')}"
    n, k = len(paths), len(singles)
    single = float(np.mean([row["time_s"] for row in results[1].rows]))
    # the same single runs on one thread: what a fleet worker on its one core has
    import time

    from mechanism.sysid.diagnosis import diagnose
    from mechanism.sysid.recording import read_recording

    one_thread = []
    for path in singles:
        start = time.perf_counter()
        diagnose(read_recording(path), workers=1, nominal=drive_nominal(None))
        one_thread.append(time.perf_counter() - start)
    single_1 = float(np.mean(one_thread))
    in_fleet = float(np.mean([row["time_s"] for row in results[2].rows]))
    one, two = results[1].seconds, results[2].seconds
    same = [row["effects"] for row in results[1].rows] == [
        row["effects"] for row in results[2].rows[:k]
    ]
    print(
        f"fleet diagnosis of {n} recordings on 2 workers: {two:.1f} s, {two / n:.2f} s per recording of wall time; "
        f"each recording took {in_fleet:.2f} s in its worker against {single:.2f} s for a single run ({k} alone, "
        f"{one:.1f} s): {in_fleet / single:.2f} x single, {in_fleet / single_1:.2f} x a single run on one thread "
        f"({single_1:.2f} s, the core a fleet worker has); speed-up 1 -> 2 workers {single / (two / n):.2f}x "
        f"(a single diagnosis already fits on threads: the gain is what whole processes add); same effects: {same}"
    )


def _variants(count: int, scratch: Path) -> None:
    import numpy as np

    from bench.bench_clearance import _model, _subset, _variants as monte_carlo
    from mechanism.inspection.clearance import Pair
    from mechanism.inspection.variants import run_variants

    model, label, timing = _model()
    variants = monte_carlo(count, timing, scratch)
    pairs = [Pair("needle", "hook")]
    run_variants(model, _subset(variants, 2), pairs, driver="arm_shaft", progress=False)  # warm-up
    one, two = (
        run_variants(model, variants, pairs, driver="arm_shaft", workers=w, progress=False)
        for w in (1, 2)
    )
    # each worker's pose solver starts from the variant it solved last: equal to rounding
    difference = np.nanmax(
        np.abs(
            np.subtract(*([r["needle_vs_hook_min_mm"] for r in batch.rows] for batch in (one, two)))
        )
    )
    print(
        f"clearance variants ({label}): {len(variants)} variants, 1 worker {one.seconds:.2f} s, 2 workers "
        f"{two.seconds:.2f} s, speed-up {one.seconds / two.seconds:.2f}x; largest difference in the minima {difference:.1e} mm"
    )


def main() -> None:
    count = int(os.environ.get("MECHANISM_BENCH_FLEET", "3"))
    variants = int(os.environ.get("MECHANISM_BENCH_BATCH_VARIANTS", "40"))
    from mechanism.files.limits import usable_cores

    cores = usable_cores()
    print(
        f"{cores} CPU cores usable; load average {os.getloadavg()[0]:.2f} (ratios are only meaningful on idle cores)"
    )
    with tempfile.TemporaryDirectory() as scratch:
        reference = int(os.environ.get("MECHANISM_BENCH_FLEET_REFERENCE", "0")) or None
        _fleet(_recordings(count, Path(scratch)), Path(scratch), reference)
        _variants(variants, Path(scratch))


if __name__ == "__main__":
    main()
