"""The bench-recording contract: reading, validation errors, the velocity definition."""

import json

import numpy as np
import pytest

from mechanism.errors import UserError
from mechanism.sysid.recording import (
    ENCODER_STEP_RAD,
    check_excitation,
    make_recording,
    read_recording,
    smoothed_velocity,
)

FS = 1000.0


def write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def ramp_csv(seconds=3.0, header="time,voltage,arm_angle", extra="", speed=10.0, voltage=None):
    t = np.arange(int(seconds * FS)) / FS
    u = voltage(t) if voltage else np.where(t < seconds / 2, 5.0, 12.0)
    a = np.floor(speed * t / ENCODER_STEP_RAD) * ENCODER_STEP_RAD
    rows = "\n".join(f"{ti:.3f},{ui:.3f},{ai:.7f}{extra}" for ti, ui, ai in zip(t, u, a))
    return f"# layers: 0\n{header}\n{rows}\n"


def test_reads_contract_with_metadata_aliases_and_unknown_columns(tmp_path):
    rec = read_recording(
        write(
            tmp_path / "r.csv", ramp_csv(header="time_s,voltage_V,arm_angle_rad,junk", extra=",x")
        )
    )
    assert rec.metadata == {"layers": "0"}
    assert rec.dt == pytest.approx(1e-3)
    assert rec.duration_s == pytest.approx(2.999)
    assert rec.current_A is None
    # the velocity of a quantised 10 rad/s ramp is 10 rad/s to within the quantisation floor
    assert np.abs(rec.velocity_rad_s[50:-50] - 10.0).max() < 0.05


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("time,voltage\n0,1\n1,2\n2,3\n", "missing required column(s) arm_angle"),
        ("time,voltage,arm_angle\n0,1,0\n0.001,1,nan\n", "NaN/inf"),
        ("time,voltage,arm_angle\n0,1,0\n0.001,inf,0\n", "NaN/inf"),
        ("time,voltage,arm_angle\n0,1,0\n0.001,1,0\n0.001,1,0\n", "duplicated"),
        ("time,voltage,arm_angle\n0,1,0\n0.002,1,0\n0.001,1,0\n", "decreasing"),
        ("time,voltage,arm_angle\n0,1,0\n0.001,1,0\n", "at least 2 s"),
    ],
)
def test_bad_recordings_are_one_line_user_errors(tmp_path, text, fragment):
    with pytest.raises(UserError) as info:
        read_recording(write(tmp_path / "bad.csv", text))
    assert fragment in str(info.value)
    assert "\n" not in str(info.value)


def test_gaps_are_errors_but_jitter_is_resampled():
    t = np.arange(3000) / FS
    with pytest.raises(UserError, match="gap"):
        make_recording(np.r_[t[:1000], t[1500:]], np.ones(2500), np.zeros(2500))
    jitter = t + np.random.default_rng(0).uniform(-2e-5, 2e-5, len(t))
    rec = make_recording(jitter, np.ones(len(t)), 7.0 * jitter)
    assert np.allclose(np.diff(rec.time_s), rec.dt)
    assert np.abs(rec.velocity_rad_s[30:-30] - 7.0).max() < 1e-6


def test_velocity_definition_tracks_a_ripple_and_has_a_low_quantisation_floor():
    t = np.arange(20000) / FS
    true_angle = 30 * t + 0.01 * np.sin(2 * np.pi * 12 * t)  # 30 rad/s with a 12 Hz ripple
    true_velocity = 30 + 0.01 * 2 * np.pi * 12 * np.cos(2 * np.pi * 12 * t)
    measured = np.floor(true_angle / ENCODER_STEP_RAD) * ENCODER_STEP_RAD
    v = smoothed_velocity(measured, 1 / FS)
    raw = np.diff(measured) * FS
    assert np.std(raw - 30) > 0.1  # raw differencing: 0.31 rad/s steps
    err = (v - true_velocity)[100:-100]
    # the ripple (0.75 rad/s) passes, quantisation is filtered
    assert np.sqrt(np.mean(err**2)) < 0.015


def test_constant_voltage_is_not_identifiable_and_steps_are():
    t = np.arange(5000) / FS
    flat = make_recording(t, np.full(len(t), 12.0), 50 * t)
    assert not check_excitation(flat).identifiable
    assert "constant" in check_excitation(flat).reason
    steps = make_recording(t, np.where(t < 2.5, 6.0, 14.0), 50 * t)
    assert check_excitation(steps).identifiable


def test_cli_bad_recordings_exit_2_with_one_error_line(tmp_path, cli_here):
    bad = write(tmp_path / "bad.csv", "time,voltage,arm_angle\n0,1,0\n0.001,1,0\n0.001,1,0\n")
    out = tmp_path / "d.json"
    for verb in ("identify", "diagnose"):
        line = cli_here(verb, bad, "--json", out).assert_bad_input()
        assert "duplicated" in line
    assert not out.exists()
    short = write(tmp_path / "short.csv", ramp_csv(seconds=1.0))
    assert "at least 2 s" in cli_here("diagnose", short, "--json", out).assert_bad_input()
    missing = write(tmp_path / "missing.csv", "time,voltage\n0,1\n")
    assert "arm_angle" in cli_here("diagnose", missing, "--json", out).assert_bad_input()
    assert not out.exists()


@pytest.mark.slow
def test_cli_constant_voltage_is_a_not_identifiable_finding(tmp_path, cli):
    flat = write(
        tmp_path / "flat.csv", ramp_csv(seconds=3.0, voltage=lambda t: np.full(len(t), 12.0))
    )
    out = tmp_path / "d.json"
    line = cli("diagnose", flat, "--json", out).assert_bad_input()
    assert "not identifiable" in line
    data = json.loads(out.read_text())
    assert data["identifiable"] is False and data["effects"] == [] and "constant" in data["reason"]


def test_encoder_counts_from_metadata_or_the_angles_steps():
    """Counts per turn come from a `# counts_per_rev:` line, else from the angle's quantisation
    (every step a whole number of counts); an unquantised angle has none; a bad line is one error."""
    from mechanism.errors import UserError
    from mechanism.sysid.residual import encoder_counts

    t = np.arange(5000) * 1e-3
    step = 2 * np.pi / 2500
    angle = np.floor((30 * t + 3 * np.sin(7 * t)) / step) * step
    assert encoder_counts(make_recording(t, np.ones(len(t)), angle)) == 2500
    assert (
        encoder_counts(make_recording(t, np.ones(len(t)), 30 * t + 0.01 * np.sin(50 * t))) is None
    )
    assert (
        encoder_counts(
            make_recording(t, np.ones(len(t)), angle, metadata={"counts_per_rev": "4096"})
        )
        == 4096
    )
    with pytest.raises(UserError, match="counts_per_rev"):
        encoder_counts(
            make_recording(t, np.ones(len(t)), angle, metadata={"counts_per_rev": "many"})
        )
