"""probe / clearance / view through the CLI: outputs with units, one-line errors on bad input."""

import csv
import json

import pytest

from tests.helpers import mechanisms as M


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("cli") / "needle.xml"
    path.write_text(M.needle_and_plate().to_xml())
    return path


def _rows(path):
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    return list(csv.DictReader(lines))


@pytest.mark.slow
def test_probe_cycle_writes_units_and_a_plot(cli, model_file, tmp_path):
    out, plot = tmp_path / "probe.csv", tmp_path / "probe.png"
    result = cli(
        "probe",
        "--model",
        model_file,
        "--part",
        "needle_tip",
        "--quantity",
        "position,velocity",
        "--part",
        "crank_pin",
        "--quantity",
        "force",
        "--cycle",
        "--resolution",
        "5",
        "--csv",
        out,
        "--plot",
        plot,
    )
    assert result.returncode == 0, result.stderr
    rows = _rows(out)
    assert len(rows) == 72
    assert {
        "time_s",
        "arm_shaft_angle_rad",
        "needle_tip_z_mm",
        "needle_tip_vz_m_s",
        "crank_pin_F_N",
    } <= set(rows[0])
    assert float(rows[0]["needle_tip_z_mm"]) == pytest.approx(M.needle_tip_z(0.0) * 1e3, abs=0.01)
    assert plot.stat().st_size > 1000


@pytest.mark.slow
def test_clearance_single_model_and_variants(cli, model_file, tmp_path):
    out, report = tmp_path / "c.csv", tmp_path / "c.json"
    result = cli(
        "clearance",
        "--model",
        model_file,
        "--pairs",
        "needle:hook",
        "--required",
        "0.05",
        "--csv",
        out,
        "--json",
        report,
    )
    assert result.returncode == 0, result.stderr
    row = _rows(out)[0]
    assert float(row["min_distance_mm"]) == pytest.approx(0.1, abs=0.01) and row["pass"] == "1"
    assert json.loads(report.read_text())["pairs"][0]["angle_deg"] == pytest.approx(
        M.HOOK_PASS_DEG, abs=0.1
    )

    variants = tmp_path / "v.csv"
    variants.write_text("name,coupling:hook_drive:hook_deg\nlate hook,-30\n")
    out = tmp_path / "v_out.csv"
    result = cli(
        "clearance",
        "--model",
        model_file,
        "--pairs",
        "needle:hook",
        "--variants",
        variants,
        "--workers",
        "2",
        "--required",
        "0.05",
        "--csv",
        out,
    )
    assert result.returncode == 0, result.stderr
    assert "variants" in result.stderr  # progress bar
    rows = {row["variant"]: row for row in _rows(out)}
    assert rows["nominal"]["pass"] == "1" and rows["late hook"]["pass"] == "0"
    assert float(rows["late hook"]["needle_vs_hook_min_mm"]) < 0


@pytest.mark.parametrize(
    "args, message",
    [
        (
            ["probe", "--part", "needle_tpi", "--quantity", "position", "--cycle"],
            "close matches: needle_tip",
        ),
        (
            ["probe", "--part", "needle_tip", "--quantity", "speed", "--cycle"],
            "unknown probe quantity",
        ),
        (["clearance", "--pairs", "needle:needle"], "same part twice"),
        (["clearance", "--pairs", "needle:hokk"], "close matches: hook"),
        (["view", "--frames", "1"], "frames"),
    ],
)
def test_bad_input_is_one_error_line(cli_here, model_file, tmp_path, args, message):
    out = tmp_path / "out.csv"
    result = cli_here(
        *args,
        "--model",
        model_file,
        *(["--html", tmp_path / "v.html"] if args[0] == "view" else ["--csv", out]),
    )
    assert message in result.assert_bad_input()
    assert not out.exists() and not (tmp_path / "v.html").exists()


def test_malformed_variants_file_leaves_nothing(cli_here, model_file, tmp_path):
    variants = tmp_path / "v.json"
    variants.write_text(
        '{"parameters": {"t": "coupling:hook_drive:hook_deg"}, "sweep": {"t": [1, "two"]}}'
    )
    out = tmp_path / "out.csv"
    result = cli_here(
        "clearance",
        "--model",
        model_file,
        "--pairs",
        "needle:hook",
        "--variants",
        variants,
        "--csv",
        out,
    )
    assert "finite number" in result.assert_bad_input()
    assert not out.exists()
