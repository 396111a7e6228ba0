"""`make demo` end to end: every step writes its files, the index links only files that
exist, and the diagnosis names the effect concealed in the shipped recording."""

import json
import re

import pytest


@pytest.mark.slow
def test_demo_writes_a_complete_linked_folder(cli, tmp_path):
    out = tmp_path / "out"
    result = cli("demo", "--out", out)
    assert result.returncode == 0, result.stderr
    index = (out / "index.html").read_text()
    targets = set(re.findall(r'(?:href|src)="([^"]+)"', index))
    assert {"machine.html", "needle.png", "table2.csv", "diagnosis/index.html", "probes.csv"} <= targets
    for target in targets:
        assert (out / target).is_file(), target
    facts = json.loads((out / "demo.json").read_text())
    assert facts["diagnosis"]["found"] == facts["diagnosis"]["concealed"] == ["torque_ripple"]
    assert facts["diagnosis"]["final_rmse"] < 0.7 * facts["diagnosis"]["baseline_rmse"]
    assert all(abs(row["cold_error_percent"]) < 5 for row in facts["simulation"]["table2"][:5])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], "no temporary folder left behind"
