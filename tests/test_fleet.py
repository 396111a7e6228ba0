"""Fleet diagnosis (mechanism diagnose REC... --out DIR): the shipped virtual-bench recordings
plus a broken one; what each recording conceals is in its truth file."""

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from mechanism.sysid.fleet import OUTLIER_Z, find_outliers, robust_z

RECORDINGS = Path(__file__).resolve().parent.parent / "assets" / "recordings"
EFFECTS = "torque_ripple,position_friction"  # two candidates keep the test short


def _rows(path):
    return list(
        csv.DictReader(line for line in path.read_text().splitlines() if not line.startswith("#"))
    )


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    for source in sorted(RECORDINGS.glob("*.csv")):
        shutil.copy(source, folder)
    (folder / "broken.csv").write_text("time,voltage\n0,1\n0.001,1\n")
    return folder


@pytest.mark.slow  # 7-16 s (idle to loaded): three 60 s recordings and one of them again alone
def test_a_fleet_gets_one_json_each_a_summary_and_survives_a_bad_recording(
    cli, fleet_dir, tmp_path
):
    out = tmp_path / "out"
    result = cli("diagnose", fleet_dir, "--workers", "2", "--effects", EFFECTS, "--out", out)
    assert result.returncode == 0, result.stderr
    assert "3 of 4 recordings diagnosed" in result.stdout
    rows = {row["recording"]: row for row in _rows(out / "summary.csv")}
    assert set(rows) == {"broken", "clean_seed1", "position_friction_seed3", "torque_ripple_seed3"}
    assert (
        rows["broken"]["status"] == "error"
        and "missing required column(s) arm_angle" in rows["broken"]["error"]
    )
    assert not (out / "broken.json").exists()
    for name in ("clean_seed1", "position_friction_seed3", "torque_ripple_seed3"):
        truth = json.loads((RECORDINGS / f"{name}.truth.json").read_text())
        concealed = truth["effects"]
        assert rows[name]["status"] == "ok"
        # found what the bench concealed
        assert rows[name]["effects"].split("+") == (concealed or [""])
        data = json.loads((out / f"{name}.json").read_text())
        assert data["final"]["effects"] == concealed
        assert float(rows[name]["final_rmse_rad_s"]) == pytest.approx(
            data["final"]["rmse"], rel=1e-8
        )
        assert float(rows[name]["coulomb_arm_Nm"]) == pytest.approx(
            data["final"]["params"]["coulomb_arm_Nm"], rel=1e-8
        )
    assert float(rows["torque_ripple_seed3"]["final_rmse_rad_s"]) < 0.3 * float(
        rows["torque_ripple_seed3"]["baseline_rmse_rad_s"]
    )
    # a parameter its model does not have
    assert rows["position_friction_seed3"]["ripple_motor_order1_cos_Nm"] == ""
    page = (out / "summary.html").read_text()
    # one strip plot per fitted parameter
    assert "robust z" in page and page.count("data:image/png;base64,") >= 4

    # the fleet's JSON of a recording is what a single `diagnose --json` writes
    single = tmp_path / "single.json"
    alone = cli(
        "diagnose", fleet_dir / "torque_ripple_seed3.csv", "--effects", EFFECTS, "--json", single
    )
    assert alone.returncode == 0, alone.stderr
    assert json.loads(single.read_text()) == json.loads(
        (out / "torque_ripple_seed3.json").read_text()
    )


def test_no_recording_diagnosed_is_exit_2(cli_here, tmp_path):
    for name in ("a", "b"):
        (tmp_path / f"{name}.csv").write_text("time,voltage\n0,1\n")
    result = cli_here("diagnose", tmp_path / "a.csv", tmp_path / "b.csv", "--out", tmp_path / "out")
    assert "none of the 2 recordings" in result.assert_bad_input()
    assert len(_rows(tmp_path / "out" / "summary.csv")) == 2  # the summary says why, per recording


@pytest.mark.slow
@pytest.mark.parametrize(
    "args, message",
    [
        (["REC", "REC"], "need --out"),
        (["REC", "--workers", "2"], "apply to a fleet"),
        (["REC", "REC", "--out", "OUT", "--json", "x.json"], "for one recording"),
        (["REC", "--backend", "ray", "--out", "OUT", "--ray-address", "1.2.3.4:5"], None),
    ],
)
def test_fleet_options_are_checked(cli, cli_here, tmp_path, args, message):
    if message is None:  # --ray-address without Ray's cluster there: one line, quickly
        args = [
            a.replace("REC", str(RECORDINGS / "clean_seed1.csv")).replace(
                "OUT", str(tmp_path / "o")
            )
            for a in args
        ]
        args[args.index("1.2.3.4:5")] = "127.0.0.1:1"
        pytest.importorskip("ray")
        assert (
            "cannot connect to the Ray cluster at 127.0.0.1:1"
            in cli("diagnose", *args).assert_bad_input()
        )
        return
    args = [
        a.replace("REC", str(RECORDINGS / "clean_seed1.csv")).replace("OUT", str(tmp_path / "o"))
        for a in args
    ]
    # refused before any work: in this process (a fresh one only adds its start)
    assert message in cli_here("diagnose", *args).assert_bad_input()


def test_robust_z_and_outliers():
    values = np.array([1.0, 1.1, 0.9, 1.05, 0.95, 1.0, 3.0])
    # median 1.0, absolute deviations 0, .1, .1, .05, .05, 0, 2 -> MAD 0.05
    assert robust_z(values) == pytest.approx(0.6745 * (values - 1.0) / 0.05)
    rows = [
        {"recording": f"r{i}", "status": "ok", "coulomb_arm_Nm": v} for i, v in enumerate(values)
    ]
    rows.append({"recording": "bad", "status": "error"})
    found = find_outliers(rows)
    assert [(o["recording"], o["parameter"]) for o in found] == [("r6", "coulomb_arm_Nm")]
    assert (
        found[0]["robust_z"] == pytest.approx(0.6745 * 2.0 / 0.05)
        and found[0]["robust_z"] > OUTLIER_Z
    )
    assert find_outliers(rows[-4:]) == []  # too few recordings to call anything an outlier


@pytest.mark.slow  # two 60 s recordings, two candidates
def test_a_fleet_of_mat_files_with_a_recording_map_finds_what_the_csvs_conceal(cli, tmp_path):
    import scipy.io

    from mechanism.sysid.recording import read_recording

    folder = tmp_path / "mats"
    folder.mkdir()
    names = ("clean_seed1", "torque_ripple_seed3")
    for name in names:
        rec = read_recording(RECORDINGS / f"{name}.csv")
        # the bench counts the other way
        counts = -np.round(rec.arm_angle_rad / (2 * np.pi / 20000))
        scipy.io.savemat(
            folder / f"{name}.mat",
            {"t": rec.time_s, "u": rec.voltage_V, "enc": counts, "i": rec.current_A},
        )
        # JSON beside the recordings is not taken for one
        shutil.copy(RECORDINGS / f"{name}.truth.json", folder)
    mapping = tmp_path / "map.toml"
    mapping.write_text(
        '[recording]\ntime = "t"\nvoltage = "u"\nshaft_angle = "enc"\nshaft_angle_unit = "counts"\n'
        'counts_per_rev = 20000\ndirection = -1\ncurrent = "i"\n'
    )
    out = tmp_path / "out"
    result = cli("diagnose", folder, "--recording-map", mapping, "--effects", EFFECTS, "--out", out)
    assert result.returncode == 0, result.stderr
    assert "2 of 2 recordings diagnosed" in result.stdout
    for name in names:
        data = json.loads((out / f"{name}.json").read_text())
        assert (
            data["final"]["effects"]
            == json.loads((RECORDINGS / f"{name}.truth.json").read_text())["effects"]
        )
        assert (
            data["reading"]["shaft_angle_rad"]["direction"] == -1
            and data["reading"]["file_format"] == "mat"
        )
