"""Diagnose time and memory against recording length (10 s to 1 hour, 1 kHz) and at other
sample rates: time must grow at most linearly with length (a long recording is scored on
segments spread over it), and an hour must stay within 4 GiB.

Run: ``python -m bench bench_diagnosis_long`` (an hour's recording takes a few minutes on
2 shared cores; ``MECHANISM_BENCH_LONG_S`` sets the longest length, default 3600).
"""

from __future__ import annotations

import os
import resource
import time


def main() -> None:
    from mechanism.api import drive_nominal
    from mechanism.sysid.diagnosis import diagnose
    from mechanism.sysid.recording import make_recording as as_recording
    from mechanism.testbench import make_recording

    nominal = drive_nominal(None)
    longest = float(os.environ.get("MECHANISM_BENCH_LONG_S", "3600"))
    cases = [(d, 1000.0) for d in (10.0, 60.0, 600.0, longest) if d <= longest] + [
        (60.0, 5000.0),
        (60.0, 250.0),
    ]
    print(
        f"{'length [s]':>10s} {'rate [Hz]':>9s} {'diagnose [s]':>12s} {'per minute [s]':>14s} {'peak RSS [GiB]':>14s}  found"
    )
    for duration, rate in cases:
        bench = make_recording(
            ["torque_ripple"], seed=1, duration_s=duration, nominal=nominal, sample_rate_hz=rate
        )
        rec = as_recording(
            bench.time, bench.voltage, bench.arm_angle, bench.current, source=f"{duration:g} s"
        )
        start = time.perf_counter()
        result = diagnose(rec, nominal=nominal)
        seconds = time.perf_counter() - start
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
        print(
            f"{duration:10.0f} {rate:9.0f} {seconds:12.1f} {60 * seconds / duration:14.2f} {peak:14.2f}  "
            f"{', '.join(result.effect_names) or '-'}",
            flush=True,
        )


if __name__ == "__main__":
    main()
