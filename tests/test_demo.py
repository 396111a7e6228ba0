"""`make demo` end to end: every shipped machine's steps write their files, the index links
only files that exist, and each diagnosis names the effect concealed in its bench recording."""

import json
import re

import pytest

import mechanism


@pytest.mark.slow
def test_demo_writes_a_complete_linked_folder(cli, tmp_path):
    out = tmp_path / "out"
    result = cli("demo", "--out", out)
    assert result.returncode == 0, result.stderr
    index = (out / "index.html").read_text()
    targets = {t for t in re.findall(r'(?:href|src)="([^"]+)"', index) if not t.startswith("#")}
    facts = json.loads((out / "demo.json").read_text())
    assert set(facts) == set(mechanism.shipped_machines())
    sapphire = facts["sapphire870"]
    assert {f"sapphire870/{name}" for name in ("machine.html", "tool.png", "steady_speeds.csv", "diagnosis/index.html",
                                               "probes.csv")} <= targets
    for target in targets:
        assert (out / target).is_file(), target
    for machine in facts.values():
        assert machine["diagnosis"]["found"] == machine["diagnosis"]["concealed"] == ["torque_ripple"]
        assert machine["diagnosis"]["final_rmse"] < 0.7 * machine["diagnosis"]["baseline_rmse"]
    assert all(abs(row["error_percent"]) < 5 for row in sapphire["simulation"]["steady_speeds"])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], "no temporary folder left behind"
