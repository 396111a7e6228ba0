"""Diagnosis accuracy on the harness of bench recordings (``diagnosis_cases.txt``: single
effects, clean recordings, pairs and four-effect mixes, 60 s each): how many are named exactly,
what the others found, and the time, as a multiple of one baseline simulation measured in the
same run.

    python -m bench bench_diagnosis_mixes                                # all 85: ~16 min on 2 cores
    MECHANISM_BENCH_MIN_EFFECTS=4 python -m bench bench_diagnosis_mixes  # the four-effect mixes only
    MECHANISM_BENCH_CACHE=/tmp/harness python -m bench bench_diagnosis_mixes  # keep the recordings

The recordings run one per usable core, each diagnosis on one core (``MECHANISM_CORES=1``), as a
batch of independent runs would.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

CASES = Path(__file__).with_name("diagnosis_cases.txt")


def _cases() -> list[tuple[str, int]]:
    least = int(os.environ.get("MECHANISM_BENCH_MIN_EFFECTS", "0"))
    cases = []
    for line in CASES.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            effects, seed = line.split()
            count = 0 if effects == "none" else len(effects.split(","))
            if count >= least:
                cases.append((effects, int(seed)))
    return cases


def _diagnose(case: tuple[str, int], folder: str) -> dict:
    os.environ["MECHANISM_CORES"] = "1"
    from mechanism.api import drive_nominal
    from mechanism.sysid.diagnosis import diagnose
    from mechanism.sysid.recording import read_recording
    from mechanism.testbench import make_recording, write_recording

    effects, seed = case
    nominal = drive_nominal(None)
    path = Path(folder) / f"{effects.replace(',', '+')}_{seed}.csv"
    if not path.exists():
        made = make_recording(
            "" if effects == "none" else effects, seed=seed, duration_s=60.0, nominal=nominal
        )
        write_recording(made, path)
    recording = read_recording(path)
    start = time.perf_counter()
    result = diagnose(recording, nominal=nominal)
    seconds = time.perf_counter() - start
    truth = set() if effects == "none" else set(effects.split(","))
    found = list(result.effect_names)
    return {
        "exact": set(found) == truth and len(found) == len(truth),
        "found": found,
        "baseline_rad_s": result.baseline.rmse_val,
        "final_rad_s": result.final.rmse_val,
        "noise_rad_s": result.noise.rmse if result.noise else float("nan"),
        "seconds": seconds,
    }


def _reference_s(folder: str) -> float:
    """One simulation of the identified baseline over every segment of a 60 s recording."""
    from mechanism.api import drive_nominal
    from mechanism.sysid.identification import ModelStructure, Problem, identify
    from mechanism.sysid.recording import read_recording
    from mechanism.testbench import make_recording, write_recording

    nominal = drive_nominal(None)
    path = Path(folder) / "reference_torque_ripple_0.csv"
    if not path.exists():
        write_recording(
            make_recording("torque_ripple", seed=0, duration_s=60.0, nominal=nominal), path
        )
    rec = read_recording(path)
    ident = identify(rec, nominal=nominal)
    problem = Problem(rec, nominal)
    structure = ModelStructure(ident.fit.structure.baseline)
    times = []
    for _ in range(40):
        start = time.perf_counter()
        problem.simulate(structure, ident.params, "all")
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    from mechanism.files.limits import usable_cores

    folder = os.environ.get("MECHANISM_BENCH_CACHE") or tempfile.mkdtemp(prefix="bench-mixes-")
    Path(folder).mkdir(parents=True, exist_ok=True)
    cases = _cases()
    workers = usable_cores()
    before = _reference_s(folder)
    start = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        results = list(pool.map(_diagnose, cases, [folder] * len(cases)))
    wall = time.perf_counter() - start
    reference = statistics.median([before, _reference_s(folder)])
    print(
        f"{len(cases)} recordings of 60 s, {workers} at a time, one core each; reference = one "
        f"baseline simulation of all segments ({reference * 1e3:.2f} ms)"
    )
    for (effects, seed), r in zip(cases, results):
        mark = "exact" if r["exact"] else "MISS "
        print(
            f"  {mark} {effects} (seed {seed}): found {', '.join(r['found']) or 'nothing'}; "
            f"{r['baseline_rad_s']:.4f} -> {r['final_rad_s']:.4f} rad/s "
            f"({r['final_rad_s'] / r['noise_rad_s']:.1f}x the noise), {r['seconds']:.1f} s"
        )
    total = sum(r["seconds"] for r in results)
    mixes = [r["seconds"] for (e, _), r in zip(cases, results) if len(e.split(",")) >= 4]
    print(
        f"named exactly: {sum(r['exact'] for r in results)} of {len(results)}; diagnosis time "
        f"{total:.0f} s in all = {total / reference:.0f} x reference, wall {wall:.0f} s"
        + (f"; four-effect mixes median {statistics.median(mixes):.1f} s" if mixes else "")
    )


if __name__ == "__main__":
    main()
