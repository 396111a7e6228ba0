"""Reading a recording CSV: the compiled reader of a body of numbers only against the general
reader (the csv module, which also takes decimal commas, text columns, quotes and comments), on
the same bytes in the same run.

    python -m bench bench_recording_read

A 60 s bench recording at 1 kHz (four columns), the median of five reads each; the ratio is what
compares across machines.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path
from unittest import mock


def main() -> None:
    import mechanism
    from mechanism.files import formats

    path = Path(tempfile.mkdtemp(prefix="bench-recording-read-")) / "r.csv"
    mechanism.write_bench_recording(mechanism.load_machine("sapphire870"), [], 0, path)
    raw = path.read_bytes()

    def median_read_s() -> float:
        times = []
        for _ in range(5):
            start = time.perf_counter()
            formats._read_csv(raw, path.name)
            times.append(time.perf_counter() - start)
        return statistics.median(times)

    fast = median_read_s()
    with mock.patch.object(formats, "_numeric_body", lambda *args: None):
        general = median_read_s()
    lines = raw.count(b"\n")
    print(f"{len(raw) / 1e6:.1f} MB, {lines} lines")
    print(f"general reader (reference): {general:.3f} s")
    print(f"numbers-only reader:        {fast:.3f} s  ({general / fast:.1f}x faster)")


if __name__ == "__main__":
    main()
