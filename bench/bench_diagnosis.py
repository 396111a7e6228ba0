"""Diagnosis benchmark: wall time against one baseline simulation, and accuracy side by side
with a plain sparse-regression (SINDy-style) discovery on virtual test-bench recordings.

    python -m bench bench_diagnosis                       # each effect, clean, 3 pairs; seed 0
    MECHANISM_BENCH_SEEDS=0,1,2 python -m bench bench_diagnosis   # more seeds

Timings are printed as ratios to one simulation of the fitted baseline over every segment
of the same 60 s recording, measured in the same run (the machines are shared and noisy).
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path

PAIRS = (
    "torque_ripple,thermal_drift",
    "linkage_dynamics,needle_penetration",
    "position_friction,encoder_eccentricity",
    "stribeck,voltage_nonlinearity",
    "belt_compliance,torque_ripple",
)


def _cases(seeds: list[int]) -> list[tuple[str, int]]:
    from mechanism.api import drive_nominal
    from mechanism.sysid.effects import library

    # the bench machine's candidates
    cases = [(name, seed) for seed in seeds for name in library(drive_nominal(None))]
    cases += [("none", seed) for seed in seeds] + [("none", seeds[-1] + 100)]
    cases += [
        (pair, seed) for seed in seeds for pair in PAIRS[: 3 if len(seeds) == 1 else len(PAIRS)]
    ]
    return cases


def _timed(fn, repeat: int = 1):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return out, statistics.median(times)


def main() -> None:
    from functools import partial

    from mechanism.api import drive_nominal
    from mechanism.sysid import diagnosis, identification
    from mechanism.sysid.identification import ModelStructure, Problem
    from mechanism.sysid.recording import read_recording
    from mechanism.testbench import make_recording, write_recording

    nominal = drive_nominal(None)
    diagnose = partial(diagnosis.diagnose, nominal=nominal)
    identify = partial(identification.identify, nominal=nominal)

    from bench.sindy_baseline import discover

    seeds = [int(s) for s in os.environ.get("MECHANISM_BENCH_SEEDS", "0").split(",")]
    folder = Path(tempfile.mkdtemp(prefix="bench-diagnosis-"))

    def recording(effects: str, seed: int):
        path = folder / f"{effects.replace(',', '+')}_{seed}.csv"
        if not path.exists():
            write_recording(
                make_recording(effects, seed=seed, duration_s=60.0, nominal=nominal), path
            )
        return read_recording(path)

    # --- timing --------------------------------------------------------------------
    rec = recording("torque_ripple", seeds[0])
    ident, t_identify = _timed(lambda: identify(rec))
    problem = Problem(rec, nominal)
    structure = ModelStructure(ident.fit.structure.baseline)
    _, t_sim = _timed(lambda: problem.simulate(structure, ident.params, "all"), repeat=20)
    _, t_diag = _timed(lambda: diagnose(rec))
    print(f"recording: 60 s at 1 kHz ({len(rec)} samples), {os.cpu_count()} CPU(s)")
    print(f"reference: one baseline simulation of all segments  {t_sim * 1e3:8.2f} ms   1")
    print(
        f"identify (baseline fit, uncertainties)               {t_identify:8.2f} s  {t_identify / t_sim:8.0f} x reference"
    )
    from mechanism.sysid.effects import library

    print(
        f"diagnose ({len(library(nominal))} candidates, rounds, report)        {t_diag:8.2f} s  {t_diag / t_sim:8.0f} x reference"
    )

    # --- accuracy ------------------------------------------------------------------
    print()
    print(f"{'truth':42s} {'diagnose':44s} {'rmse ratio':>10s}  {'sparse regression (STLSQ)':40s}")
    ours_ok = sindy_ok = ratio_ok = with_effects = 0
    cases = _cases(seeds)
    for effects, seed in cases:
        truth = set() if effects == "none" else set(effects.split(","))
        rec = recording(effects, seed)
        result = diagnose(rec)
        found = result.effect_names
        ratio = result.final.rmse_val / result.baseline.rmse_val
        sparse = discover(rec, nominal)
        ok = set(found) == truth and len(found) == len(truth)
        ok_ratio = (not truth) or ratio <= 0.7
        ok_sparse = set(sparse) == truth
        ours_ok += ok
        ratio_ok += ok_ratio and bool(truth)
        with_effects += bool(truth)
        sindy_ok += ok_sparse
        label = f"{effects} (seed {seed})"
        print(
            f"{label:42s} {('ok ' if ok else 'NO ') + (', '.join(found) or '-'):44s} {ratio:10.2f}  "
            f"{('ok ' if ok_sparse else 'NO ') + (', '.join(sparse) or '-'):40s}",
            flush=True,
        )
    n = len(cases)
    print(
        f"\nnamed correctly: diagnose {ours_ok}/{n}, sparse regression {sindy_ok}/{n}; "
        f"effect recordings improved to <= 0.7 of the baseline rmse: {ratio_ok}/{with_effects}"
    )


if __name__ == "__main__":
    main()
