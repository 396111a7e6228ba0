"""Virtual test bench: time to generate a 60 s recording, against the Python twin of the
integrator and against the 60 s of bench time it stands for (same run, same machine)."""

from __future__ import annotations

import time

from functools import partial

from mechanism.api import drive_nominal
from mechanism.testbench import EFFECTS
from mechanism.testbench import make_recording as _make_recording

make_recording = partial(_make_recording, nominal=drive_nominal(None))


def _best_of(repeats, function):
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    make_recording([], duration_s=0.1)  # compile/load the C integrator outside the timing
    cases = {
        "clean": [],
        "all but belt (rigid)": [n for n in EFFECTS if n != "belt_compliance"],
        "belt + linkage + needle": ["belt_compliance", "linkage_dynamics", "needle_penetration"],
    }
    python_1s = _best_of(1, lambda: make_recording([], duration_s=1.0, integrator="python"))
    print(f"{'case':28s} {'60 s recording [s]':>18s} {'x real time':>12s} {'vs Python twin':>15s}")
    for label, effects in cases.items():
        native = _best_of(3, lambda: make_recording(effects, seed=1, duration_s=60.0))
        print(f"{label:28s} {native:18.3f} {60.0 / native:12.0f} {60 * python_1s / native:14.0f}x")
    print(f"(Python twin, clean: {60 * python_1s:.1f} s per 60 s recording, extrapolated from 1 s)")


if __name__ == "__main__":
    main()
