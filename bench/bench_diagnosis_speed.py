"""Diagnosis speed on 60 s recordings at 1 kHz (issue 23's goal: at most 3 s median on two
cores, a four-effect recording in at most 10 s).

    python -m bench bench_diagnosis_speed
    MECHANISM_BENCH_SEEDS=0,1 python -m bench bench_diagnosis_speed

Every time is also given as a multiple of a reference run in the same process: one
simulation of the fitted baseline over every segment of the same recording (the machines
are shared and their speed varies from minute to minute; the ratio is what compares across
runs).
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path

SINGLES = ("none", "torque_ripple", "stribeck", "thermal_drift", "sensor_delay")
FOUR = "torque_ripple,position_friction,thermal_drift,encoder_eccentricity"


def main() -> None:
    from mechanism.api import drive_nominal
    from mechanism.sysid.diagnosis import diagnose
    from mechanism.sysid.identification import ModelStructure, Problem, identify
    from mechanism.sysid.recording import read_recording
    from mechanism.testbench import make_recording, write_recording

    nominal = drive_nominal(None)
    seeds = [int(s) for s in os.environ.get("MECHANISM_BENCH_SEEDS", "0").split(",")]
    folder = Path(tempfile.mkdtemp(prefix="bench-diagnosis-speed-"))

    def recording(effects: str, seed: int):
        path = folder / f"{effects.replace(',', '+')}_{seed}.csv"
        write_recording(make_recording(effects, seed=seed, duration_s=60.0, nominal=nominal), path)
        return read_recording(path)

    def reference(rec):
        """Timings of one baseline simulation: each call of the function returned adds 20 and
        gives all so far."""
        ident = identify(rec, nominal=nominal)
        problem = Problem(rec, nominal)
        structure = ModelStructure(ident.fit.structure.baseline)
        times: list[float] = []

        def sample() -> list[float]:
            for _ in range(20):
                start = time.perf_counter()
                problem.simulate(structure, ident.params, "all")
                times.append(time.perf_counter() - start)
            return times

        return sample

    def timed(rec) -> tuple[float, list[str], float]:
        """The diagnosis's wall time, its findings, and the reference: sampled just before and
        just after it (the machine's speed drifts over seconds; one side alone moved 2x)."""
        sample = reference(rec)
        sample()
        start = time.perf_counter()
        result = diagnose(rec, nominal=nominal)
        seconds = time.perf_counter() - start
        return seconds, result.effect_names, statistics.median(sample())

    from mechanism.files.limits import usable_cores

    print(
        f"60 s recordings at 1 kHz, {usable_cores()} CPU core(s) usable; reference = one baseline simulation of all segments, timed before and after each diagnosis"
    )
    singles, ratios = [], []
    for seed in seeds:
        for effects in SINGLES:
            rec = recording(effects, seed)
            seconds, names, ref = timed(rec)
            singles.append(seconds)
            ratios.append(seconds / ref)
            print(
                f"  {effects:<16} seed {seed}: {seconds:6.2f} s = {seconds / ref:7.0f} x reference ({ref * 1e3:.2f} ms); "
                f"found {', '.join(names) or 'nothing'}"
            )
    print(
        f"median over {len(singles)} recordings: {statistics.median(singles):.2f} s "
        f"({statistics.median(ratios):.0f} x reference; goal 3 s)"
    )
    rec = recording(FOUR, seeds[0])
    seconds, names, ref = timed(rec)
    print(
        f"four effects ({FOUR}): {seconds:.2f} s = {seconds / ref:.0f} x reference; found {', '.join(names)} (goal 10 s)"
    )
    _compiled_against_numpy(rec, nominal)
    _lag_on_stretches_against_the_whole(rec, nominal)


def _compiled_against_numpy(rec, nominal) -> None:
    """One fit-part simulation of the fitted baseline: the angle and the differentiator compiled
    (lumped.c) against their numpy fallback, in the same run."""
    from mechanism.dynamics import lumped
    from mechanism.sysid.identification import ModelStructure, Problem, identify

    ident = identify(rec, nominal=nominal)
    problem = Problem(rec, nominal)
    structure = ModelStructure(ident.fit.structure.baseline)

    def median_ms() -> float:
        times = []
        for _ in range(100):
            start = time.perf_counter()
            problem.simulate(structure, ident.params, "fit")
            times.append(time.perf_counter() - start)
        return statistics.median(times) * 1e3

    compiled = median_ms()
    kernels = lumped._signal_kernels
    lumped._signal_kernels = lambda: None  # the numpy fallback
    try:
        fallback = median_ms()
    finally:
        lumped._signal_kernels = kernels
    print(
        f"one fit simulation of the baseline: {compiled:.2f} ms with the compiled angle and "
        f"differentiator, {fallback:.2f} ms with numpy ({fallback / compiled:.2f}x)"
    )


def _lag_on_stretches_against_the_whole(rec, nominal) -> None:
    """A screening evaluation that changes the winding's time constant (as a fit's steps do):
    the lag filtered on stretches around the part's windows (``Signals.lag_filtered``) against the
    whole recording filtered and read there, in the same run."""
    from mechanism.dynamics import lumped
    from mechanism.sysid.identification import ModelStructure, Problem, identify

    ident = identify(rec, nominal=nominal)
    problem = Problem(rec, nominal)
    structure = ModelStructure(ident.fit.structure.baseline)
    tau = ident.params["electrical_time_constant_s"]

    def median_ms() -> float:
        times = []
        for i in range(100):
            values = {**ident.params, "electrical_time_constant_s": tau * (1 + 1e-4 * (i + 1))}
            start = time.perf_counter()
            problem.simulate(structure, values, "screen")
            times.append(time.perf_counter() - start)
        return statistics.median(times) * 1e3

    stretches = median_ms()
    share = lumped.STRETCH_SHARE
    lumped.STRETCH_SHARE = 0.0  # every part filters the whole recording
    try:
        whole = median_ms()
    finally:
        lumped.STRETCH_SHARE = share
    print(
        f"one screening simulation with a new winding time constant: {stretches:.2f} ms with the lag "
        f"on the part's stretches, {whole:.2f} ms on the whole recording ({whole / stretches:.2f}x)"
    )
