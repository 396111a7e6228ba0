"""`mechanism stepper` and `mechanism zigzag` as a user runs them."""

from __future__ import annotations

import csv
import json

import pytest

REQUIRED = [
    "time_s",
    "commanded_position_deg",
    "rotor_position_deg",
    "rotor_speed_rad_s",
    "phase_a_current_A",
    "phase_b_current_A",
    "torque_Nm",
]


def read_csv(path):
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    return {name: [float(row[name]) for row in rows] for name in rows[0]}


@pytest.mark.slow
def test_thread_cut_csv_plot_and_summary(cli, tmp_path):
    out = tmp_path / "tc.csv"
    result = cli(
        "stepper",
        "--sequence",
        "thread-cut",
        "--csv",
        out,
        "--plot",
        tmp_path / "tc.png",
        "--json",
        tmp_path / "tc.json",
    )
    assert result.returncode == 0, result.stderr
    table = read_csv(out)
    assert all(name in table for name in REQUIRED)
    assert table["rotor_position_deg"][0] == 0.0 and max(
        table["commanded_position_deg"]
    ) == pytest.approx(2625.0)
    assert abs(table["rotor_position_deg"][-1]) < 7.5
    summary = json.loads((tmp_path / "tc.json").read_text())
    assert summary["lost_steps"] == 0 and summary["reversals"][0]["overshoot_deg"] > 0
    assert (tmp_path / "tc.png").stat().st_size > 10_000
    assert "lost steps 0" in result.stdout and "overshoot" in result.stdout


@pytest.mark.parametrize(
    "args",
    [
        ["--sequence", "thread-cutt"],
        ["--sequence", "missing.csv"],
        ["--sequence", "thread-cut", "--rate", "-1000"],
        ["--sequence", "thread-cut", "--mode", "quarter"],
        ["--sequence", "thread-cut", "--model", "both"],
        ["--sweep", "3000:1000:100"],
    ],
)
def test_bad_input_is_one_error_line(cli_here, tmp_path, args):
    out = tmp_path / "out.csv"
    cli_here("stepper", *args, "--csv", out).assert_bad_input()
    assert not out.exists()


def test_malformed_sequence_file(cli_here, tmp_path):
    bad = tmp_path / "seq.csv"
    bad.write_text("time_s,rate_steps_s\n0,100\n0.1,fast\n")
    line = cli_here("stepper", "--sequence", bad, "--csv", tmp_path / "out.csv").assert_bad_input()
    assert "seq.csv" in line and "line 3" in line
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.slow
def test_machine_option_takes_the_described_stepper_and_thread_cut(cli, tmp_path):
    from mechanism.machine.models import DEFAULT_DESCRIPTION

    machine = tmp_path / "fast_cut.toml"
    text = (
        DEFAULT_DESCRIPTION.read_text()
        .replace("forward_s = 0.35", "forward_s = 0.05")
        .replace("back_s = 0.35", "back_s = 0.05")
    )
    machine.write_text(
        text.replace("pole_pairs = 12", "pole_pairs = 6").replace(
            "step_angle_deg = 7.5", "step_angle_deg = 15.0"
        )
    )
    out = tmp_path / "tc.csv"
    result = cli(
        "stepper",
        "--sequence",
        "thread-cut",
        "--machine",
        machine,
        "--model",
        "physical",
        "--csv",
        out,
    )
    assert result.returncode == 0, result.stderr
    # 0.05 s at 1000 steps/s = 50 steps of 15 deg
    assert max(read_csv(out)["commanded_position_deg"]) == pytest.approx(750.0)
    broken = tmp_path / "broken.toml"
    broken.write_text(text.replace("chopper_hz = 20e3", "chopper_hz = 0"))
    line = cli(
        "stepper", "--sequence", "thread-cut", "--machine", broken, "--csv", tmp_path / "b.csv"
    ).assert_bad_input()
    assert "chopper_hz" in line and "broken.toml" in line


@pytest.mark.slow
def test_zigzag_exit_status_says_flagged(cli, tmp_path):
    flagged = cli("zigzag", "--spm", "1000", "--rate", "1000", "--csv", tmp_path / "z.csv")
    assert flagged.returncode == 1 and "FLAGGED" in flagged.stdout
    assert "needle_in_fabric" in (tmp_path / "z.csv").read_text()
    fits = cli("zigzag", "--spm", "1000", "--rate", "1500")
    assert fits.returncode == 0 and "fits" in fits.stdout
    cli("zigzag", "--spm", "-1").assert_bad_input()
    cli("zigzag", "--spm", "1000", "--machine-model", tmp_path / "missing.xml").assert_bad_input()
