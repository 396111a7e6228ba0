"""How the fixtures in this folder were made from the public sources (see README.md). Not
run by the tests; kept so that every number in the fixtures can be traced back.

    python tests/data/real/make_fixtures.py BAM_REPO SYSID_NEURAL_CONTINUOUS_REPO

where the two arguments are git checkouts of github.com/Rhoban/bam and
github.com/forgi86/sysid-neural-continuous.
"""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
BAM_COMMIT = "af2260462471ff45ac18af159b1327ea51d8db15"  # branch xl330: "new identification values"
BAM_LOGS = [
    "2026-01-15_10h28m10",
    "2026-01-15_10h28m49",
    "2026-01-15_10h29m37",
    "2026-01-15_10h30m02",
]
EMPS_COMMIT = "93afc131780fb1d5477472935a18ac8405683890"
EMPS_SECONDS = 12.4  # the first half of the estimation experiment
EMPS_RADIUS_M = 0.01  # the linear axis as a virtual shaft: angle = position / radius


def show(repo: str, commit: str, path: str) -> bytes:
    return subprocess.run(
        ["git", "-C", repo, "show", f"{commit}:{path}"], check=True, capture_output=True
    ).stdout


def xl330(repo: str) -> None:
    out = HERE / "xl330"
    out.mkdir(exist_ok=True)
    for name in BAM_LOGS:
        log = json.loads(show(repo, BAM_COMMIT, f"bam/data.bak/processed/{name}.json"))
        entries = log["entries"]
        t = np.array([e["timestamp"] for e in entries])
        q = np.array([e["position"] for e in entries])
        raw = np.array([e["load"] for e in entries], dtype=float)  # the present PWM, raw counts
        # 885 counts = full duty
        duty = np.clip(np.where(raw > 2**15 - 1, raw - 2**16, raw) / 885.0, -1.0, 1.0)
        volts = duty * np.array([e["input_volts"] for e in entries])
        header = (
            f"# source: github.com/Rhoban/bam@{BAM_COMMIT} bam/data.bak/processed/{name}.json (Apache-2.0)\n"
            f"# motor: {log['motor']}; pendulum mass_kg: {log['mass']}; length_m: {log['length']}; "
            f"kp: {log['kp']}; trajectory: {log['trajectory']}\n"
            "# voltage = present PWM duty x measured supply voltage; arm_angle = output shaft, 0 = pendulum down\n"
        )
        with open(out / f"{name}.csv", "w") as handle:
            handle.write(header + "time,voltage,arm_angle\n")
            for row in zip(t, volts, q):
                handle.write("%.4f,%.5g,%.6f\n" % row)


def emps(repo: str) -> None:
    from scipy.io import loadmat

    data = loadmat(io.BytesIO(show(repo, EMPS_COMMIT, "examples/EMPS/data/DATA_EMPS.mat")))
    t, q, vir = (data[k].ravel() for k in ("t", "qm", "vir"))
    keep = t <= EMPS_SECONDS
    header = (
        f"# source: github.com/forgi86/sysid-neural-continuous@{EMPS_COMMIT} examples/EMPS/data/DATA_EMPS.mat "
        f"(Apache-2.0; data set: Janot, Gautier, Brunot, EMPS, nonlinearbenchmark.org, 2019)\n"
        f"# first {EMPS_SECONDS:g} s; voltage = vir (force = gtau vir, gtau = {float(data['gtau'][0, 0]):.8g} N/V); "
        f"arm_angle = qm / {EMPS_RADIUS_M:g} m (the axis as a virtual shaft)\n"
    )
    with open(HERE / "emps.csv", "w") as handle:
        handle.write(header + "time,voltage,arm_angle\n")
        for row in zip(t[keep], vir[keep], q[keep] / EMPS_RADIUS_M):
            handle.write("%.5f,%.6g,%.8f\n" % row)


if __name__ == "__main__":
    xl330(sys.argv[1])
    emps(sys.argv[2])
