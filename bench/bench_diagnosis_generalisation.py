"""Does the diagnosis generalise to truth models it was not tuned on?

Recordings come from ``tests/helpers/truth_variants.py``: a third truth model written apart from
``mechanism.testbench`` and ``tests/helpers/synthetic_truth.py``, with other integrators (RK4 + tanh
friction, event stick-slip), motor constants (Kt = Ke), inductances, voltage profiles
(ramps, staircase, PWM duty, long plateaus), sensors (round/floor, jitter, a late noisy
voltage log) and other flavours of every effect. Each case is diagnosed like the held-out
benchmark does (lumped baseline, 60 s); the table says whether the effects were named
exactly, the final/baseline rmse ratio, and how detectable the effect is (RMS speed change
against the same seed's clean recording in its most affected 2 s).

    python -m bench bench_diagnosis_generalisation
    MECHANISM_GEN_SEEDS=0,1 MECHANISM_GEN_VARIANTS=rk4_tanh,ramps python -m bench bench_diagnosis_generalisation
    python -m bench.bench_diagnosis_generalisation --seeds 0 1 2 --json out.json   # more options: --help
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from collections import defaultdict
from pathlib import Path

PAIRS = (
    "torque_ripple,thermal_drift",
    "needle_penetration,stribeck",
    "position_friction,encoder_eccentricity",
    "voltage_nonlinearity,linkage_dynamics",
    "belt_compliance,thermal_drift",
)
DETECTABLE_RAD_S = 0.2  # an effect changing the speed by less than this nowhere is not asked for


def cases(variants, seeds, effects=None, pairs=True):
    from tests.helpers.truth_variants import EFFECT_NAMES, FLAVOURS

    out = []
    for vi, variant in enumerate(variants):
        for seed in seeds:
            out.append((variant, seed, (), {}))
            for e in effects or EFFECT_NAMES:
                flavour = FLAVOURS[e][(seed + vi) % len(FLAVOURS[e])]
                out.append((variant, seed, (e,), {e: flavour}))
            if pairs:
                pair = PAIRS[(seed + vi) % len(PAIRS)].split(",")
                out.append((variant, seed, tuple(pair), {}))
    return out


def _load_or_make(cache: Path, variant, seed, effects, flavours, duration):
    import zlib

    import numpy as np
    from tests.helpers import truth_variants
    from tests.helpers.truth_variants import detectability, make_case

    # a changed truth model makes new files
    version = zlib.crc32(Path(truth_variants.__file__).read_bytes()) % 10**6
    key = f"{variant}_{seed}_{'+'.join(effects) or 'none'}_{'_'.join(flavours.get(e, '') for e in effects)}_{int(duration)}_{version}"
    path = cache / f"{key}.npz"
    if path.exists():
        z = np.load(path, allow_pickle=True)
        return z, key
    case = make_case(effects, seed, variant, duration, flavours)
    detect = float("nan")
    if len(effects) == 1:
        clean = _load_or_make(cache, variant, seed, (), {}, duration)[0]
        detect = detectability(case.sensed_angle_rad, clean["sensed_angle"], _window(effects[0]))
    np.savez(
        path,
        time=case.time_s,
        voltage=case.voltage_V,
        angle=case.arm_angle_rad,
        current=case.current_A if case.current_A is not None else np.array([]),
        sensed_angle=case.sensed_angle_rad,
        detect=detect,
        truth=json.dumps(case.truth, default=float),
    )
    return np.load(path, allow_pickle=True), key


def _window(effect: str) -> float:
    # the belt rings for a fraction of a second after steps
    return 0.2 if effect == "belt_compliance" else 2.0


def _member_detectability(cache, variant, seed, effects, member, truth, duration):
    """How much ``member`` changes the speed on top of the other effect(s) of a pair."""
    from tests.helpers.truth_variants import detectability

    others = tuple(e for e in effects if e != member)
    z_pair, _ = _load_or_make(cache, variant, seed, effects, {}, duration)
    z_rest, _ = _load_or_make(
        cache, variant, seed, others, {e: truth["effects"][e]["flavour"] for e in others}, duration
    )
    return detectability(z_pair["sensed_angle"], z_rest["sensed_angle"], _window(member))


def run(
    variants, seeds, effects=None, pairs=True, duration=60.0, cache=None, out_json=None, quiet=False
):
    from mechanism.api import drive_nominal
    from mechanism.sysid.diagnosis import diagnose
    from mechanism.sysid.recording import make_recording

    cache = Path(
        cache or os.environ.get("MECHANISM_GEN_CACHE") or tempfile.mkdtemp(prefix="gen-diagnosis-")
    )
    cache.mkdir(parents=True, exist_ok=True)
    rows = []
    header = f"{'variant':13s} {'seed':>4s} {'truth (flavour)':58s} {'detect':>6s} {'found':40s} {'ratio':>6s} {'s':>5s}"
    print(header)
    for variant, seed, case_effects, flavours in cases(variants, seeds, effects, pairs):
        z, key = _load_or_make(cache, variant, seed, case_effects, flavours, duration)
        truth = json.loads(str(z["truth"]))
        current = z["current"] if z["current"].size else None
        rec = make_recording(z["time"], z["voltage"], z["angle"], current, source=key)
        start = time.perf_counter()
        result = diagnose(rec, nominal=drive_nominal(None))
        seconds = time.perf_counter() - start
        found = result.effect_names
        ratio = result.final.rmse_val / result.baseline.rmse_val
        detect = float(z["detect"])
        if len(case_effects) > 1:
            # each member must be detectable on top of the other(s)
            detect = min(
                _member_detectability(cache, variant, seed, case_effects, e, truth, duration)
                for e in case_effects
            )
        exact = set(found) == set(case_effects) and len(found) == len(case_effects)
        ratio_ok = (not case_effects) or ratio <= 0.7
        detectable = (not case_effects) or detect >= DETECTABLE_RAD_S
        label = ", ".join(f"{e} ({truth['effects'][e]['flavour']})" for e in case_effects) or "none"
        mark = "ok " if exact and ratio_ok else ("-- " if not detectable else "NO ")
        print(
            f"{variant:13s} {seed:4d} {label:58s} {detect:6.2f} {mark + (', '.join(found) or '-'):40s} {ratio:6.2f} {seconds:5.1f}",
            flush=True,
        )
        rows.append(
            {
                "variant": variant,
                "seed": seed,
                "effects": list(case_effects),
                "flavours": {e: truth["effects"][e]["flavour"] for e in case_effects},
                "found": found,
                "exact": exact,
                "ratio": ratio,
                "ratio_ok": ratio_ok,
                "detectability_rad_s": detect,
                "detectable": detectable,
                "seconds": seconds,
                "baseline_rmse": result.baseline.rmse_val,
                "rounds": result.rounds,
                "baseline_params": result.baseline.values,
            }
        )
    _summary(rows)
    if out_json:
        Path(out_json).write_text(json.dumps(rows, indent=1, default=float))
    return rows


def _summary(rows):
    def tally(key):
        groups = defaultdict(lambda: [0, 0])
        for r in rows:
            if not r["detectable"]:
                continue
            for k in key(r):
                groups[k][0] += r["exact"] and r["ratio_ok"]
                groups[k][1] += 1
        return groups

    print()
    by_effect = tally(lambda r: r["effects"] or ["none"])
    by_variant = tally(lambda r: [r["variant"]])
    print("per effect (detectable cases, named exactly and ratio <= 0.7):")
    for k in sorted(by_effect):
        ok, n = by_effect[k]
        print(f"  {k:24s} {ok:3d}/{n:<3d}")
    print("per variant:")
    for k in sorted(by_variant):
        ok, n = by_variant[k]
        print(f"  {k:24s} {ok:3d}/{n:<3d}")
    det = [r for r in rows if r["detectable"]]
    ok = sum(r["exact"] and r["ratio_ok"] for r in det)
    clean = [r for r in rows if not r["effects"]]
    false_clean = sum(bool(r["found"]) for r in clean)
    seconds = sorted(r["seconds"] for r in rows)
    print(
        f"total: {ok}/{len(det)} detectable cases correct; clean recordings with a false finding: {false_clean}/{len(clean)}; "
        f"{len(rows) - len(det)} undetectable effect cases left out (< {DETECTABLE_RAD_S} rad/s)"
    )
    print(f"diagnose wall time: median {seconds[len(seconds) // 2]:.1f} s, max {seconds[-1]:.1f} s")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--variants",
        nargs="*",
        help="truth-model variants (default: all, or $MECHANISM_GEN_VARIANTS)",
    )
    parser.add_argument(
        "--seeds", nargs="*", type=int, help="seeds (default 0, or $MECHANISM_GEN_SEEDS)"
    )
    parser.add_argument("--effects", nargs="*", help="single effects to run (default all)")
    parser.add_argument("--no-pairs", action="store_true", help="skip the two-effect cases")
    parser.add_argument("--duration", type=float, default=60.0, help="recording length [s]")
    parser.add_argument("--cache", help="folder for generated recordings (reused between runs)")
    parser.add_argument("--json", help="write every row to this JSON file")
    args = parser.parse_args(argv if argv is not None else ([] if __name__ != "__main__" else None))
    from tests.helpers.truth_variants import VARIANTS

    variants = (
        args.variants
        or [v for v in os.environ.get("MECHANISM_GEN_VARIANTS", "").split(",") if v]
        or list(VARIANTS)
    )
    seeds = args.seeds or [int(s) for s in os.environ.get("MECHANISM_GEN_SEEDS", "0").split(",")]
    run(variants, seeds, args.effects, not args.no_pairs, args.duration, args.cache, args.json)


if __name__ == "__main__":
    main()
