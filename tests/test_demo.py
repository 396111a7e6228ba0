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
    assert {
        f"sapphire870/{name}"
        for name in (
            "machine.html",
            "tool.png",
            "steady_speeds.csv",
            "diagnosis/index.html",
            "probes.csv",
        )
    } <= targets
    for target in targets:
        assert (out / target).is_file(), target
    for machine in facts.values():
        assert (
            machine["diagnosis"]["found"] == machine["diagnosis"]["concealed"] == ["torque_ripple"]
        )
        assert machine["diagnosis"]["final_rmse"] < 0.7 * machine["diagnosis"]["baseline_rmse"]
    assert all(abs(row["error_percent"]) < 5 for row in sapphire["simulation"]["steady_speeds"])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], (
        "no temporary folder left behind"
    )
    _check_outputs_name_real_files(out)
    _check_readme_tour_is_this_runs(out)


def _paths_in(value):
    if isinstance(value, dict):
        for item in value.values():
            yield from _paths_in(item)
    elif isinstance(value, list):
        for item in value:
            yield from _paths_in(item)
    elif isinstance(value, str) and re.fullmatch(r"[\w./-]+\.(csv|json|xml|html|png|toml)", value):
        yield value


def _check_outputs_name_real_files(out):
    """Every file a JSON output names exists (beside that JSON, under the output or as given),
    and no output mentions the temporary folder the run was assembled in."""
    for document in out.rglob("*.json"):
        text = document.read_text()
        assert ".tmp/" not in text and f"/.{out.name}." not in text, document
        for path in _paths_in(json.loads(text)):
            places = [
                document.parent / path,
                out / path,
                *(folder / path for folder in out.iterdir() if folder.is_dir()),
            ]
            assert any(p.exists() for p in places), (
                f"{document.relative_to(out)} names {path}, which is not there"
            )


def _check_readme_tour_is_this_runs(out):
    """The README's Tour table is the one this demo run wrote (tour.md), number for number."""
    from pathlib import Path

    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    found = re.search(r"<!-- tour: (\w+) .*?-->\n(.*?)<!-- /tour -->", readme, re.S)
    assert found, "README has no generated Tour table"
    assert found.group(2) == (out / found.group(1) / "tour.md").read_text()


@pytest.mark.parametrize("name", mechanism.shipped_machines())
def test_each_demo_step_says_what_this_machines_section_does(name):
    from mechanism.demo import _flywheel_step, _simulate_step, _tool_step

    machine = mechanism.load_machine(name)
    tool, simulate, flywheel = _tool_step(machine), _simulate_step(machine), _flywheel_step(machine)
    assert ("revolution" in tool) == (machine.rotates and bool(machine.tool_site)), tool
    assert ("sewing" in simulate) == machine.fabric_capable, simulate
    kind = machine.description.drive_tables[machine.motor_joint]["type"]
    assert ("voltage steps" in simulate) == (kind == "dc"), simulate
    described = bool(machine.description.section("inspect").get("flywheel_voltages_V"))
    assert ("none" not in flywheel) == described, flywheel
