"""Step sequences: rate profiles integrate exactly, target files, bad files."""

from __future__ import annotations

import numpy as np
import pytest

from mechanism.steppers import step_profiles
from mechanism.errors import UserError


def test_rate_profile_position_is_the_exact_integral(tmp_path):
    path = tmp_path / "ramp.csv"
    path.write_text(
        "# a ramp up, cruise, ramp down\ntime_s,rate_steps_s\n0,0\n0.1,500\n0.3,500\n0.4,0\n"
    )
    profile = step_profiles.resolve(str(path))
    # triangle + rectangle + triangle: 25 + 100 + 25 steps
    assert float(profile.position_steps(0.4)) == pytest.approx(150.0)
    # during the first ramp x = a t^2 / 2 with a = 5000 steps/s^2
    t = np.linspace(0, 0.1, 11)
    np.testing.assert_allclose(profile.position_steps(t), 0.5 * 5000 * t**2, atol=1e-12)
    assert profile.duration_s == pytest.approx(0.4)


def test_negative_rates_run_backwards_and_a_late_first_row_waits(tmp_path):
    path = tmp_path / "back.csv"
    path.write_text("time_s,rate_steps_s\n0.05,-200\n0.15,-200\n")
    profile = step_profiles.resolve(str(path))
    assert float(profile.position_steps(0.05)) == 0.0
    assert float(profile.position_steps(0.15)) == pytest.approx(-20.0)


def test_target_file_heads_for_each_target_at_the_slew_rate(tmp_path):
    path = tmp_path / "targets.csv"
    path.write_text("time_s,target_steps\n0,10\n0.1,-5\n0.12,3\n")
    profile = step_profiles.resolve(str(path), rate=500)
    assert float(profile.position_steps(0.02)) == pytest.approx(10.0)  # 10 steps at 500 steps/s
    assert float(profile.position_steps(0.1)) == pytest.approx(10.0)  # waits for the next row
    assert float(profile.position_steps(0.12)) == pytest.approx(0.0)  # interrupted on its way to -5
    assert float(profile.position_steps(profile.duration_s)) == pytest.approx(3.0)
    assert profile.duration_s == pytest.approx(0.126)
    assert len(profile.reversal_times_s()) == 2


@pytest.mark.parametrize(
    "text, message",
    [
        ("time_s,rate_steps_s\n0,1\n0.1,x\n", "not a number"),
        ("time_s,speed\n0,1\n0.1,2\n", "rate_steps_s"),
        ("time_s,rate_steps_s,target_steps\n0,1,2\n0.1,2,3\n", "exactly one"),
        ("time_s,target_steps\n0.2,1\n0.1,2\n", "not strictly increasing"),
        ("time_s,rate_steps_s\n0,1\n", "two rows"),
        ("", "empty"),
    ],
)
def test_malformed_sequence_files(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(UserError, match=message):
        step_profiles.resolve(str(path))


def test_unknown_names_and_bad_rates():
    with pytest.raises(UserError, match="thread-cut"):
        step_profiles.resolve("thread-cutt")
    with pytest.raises(UserError, match="positive"):
        step_profiles.resolve("thread-cut", rate=-1000)
    with pytest.raises(UserError, match="positive"):
        step_profiles.move(10, 0)
