"""Zigzag timing against the arm shaft (analytic slider-crank needle)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mechanism.steppers import zigzag
from mechanism.errors import UserError

CRANK, ROD, TDC = 16.5, 50.0, 21.0
SPM = 1000.0


@pytest.fixture(scope="module")
def needle():
    return zigzag.NeedleProfile.slider_crank(CRANK, ROD, TDC)


def closed_form_window_s(spm, clearance=0.0):
    """Needle above the plate while r cos a + sqrt(l^2 - r^2 sin^2 a) > r + l - (TDC - c)."""
    reach = CRANK + ROD - (TDC - clearance)
    half_angle = math.acos((reach**2 - ROD**2 + CRANK**2) / (2 * reach * CRANK))
    return 2 * half_angle / (2 * math.pi) * 60.0 / spm


def test_window_matches_the_closed_form(needle):
    exit_angle, entry_angle = needle.window()
    assert exit_angle == pytest.approx(-entry_angle)
    assert (entry_angle - exit_angle) / (2 * math.pi) * 60 / SPM == pytest.approx(
        closed_form_window_s(SPM), rel=1e-9
    )
    exit_2, entry_2 = needle.window(clearance_mm=3.0)
    assert (entry_2 - exit_2) / (2 * math.pi) * 60 / SPM == pytest.approx(
        closed_form_window_s(SPM, 3.0), rel=1e-9
    )


def test_table_profile_reproduces_the_function(needle):
    angle = np.linspace(0, 2 * np.pi, 721)[:-1]
    table = zigzag.NeedleProfile.from_table(angle, needle(angle))
    probe = np.linspace(-7, 7, 101)
    np.testing.assert_allclose(table(probe), needle(probe), atol=0.01)
    assert table.window()[1] == pytest.approx(needle.window()[1], abs=1e-3)


def test_full_width_at_the_thesis_rate_is_flagged(needle):
    check = zigzag.check_move(SPM, needle, rate=1000)
    linkage = zigzag.ZigzagLinkage()
    assert check.steps == linkage.steps_full_width and check.width_mm == pytest.approx(
        linkage.width_mm
    )
    assert check.window_s == pytest.approx(closed_form_window_s(SPM), rel=1e-9)
    # the driver's last step comes half a step period before the end of the move
    assert check.move_time_s >= (check.steps - 0.5) / 1000
    assert check.move_time_s > check.window_s and check.flagged
    assert check.needle_z_at_finish_mm < 0  # the needle is already in the fabric
    assert check.lost_steps == 0


def test_faster_stepping_fits_in_the_window(needle):
    check = zigzag.check_move(SPM, needle, rate=1500)
    assert check.move_time_s >= (check.steps - 0.5) / 1500
    assert check.move_time_s < check.window_s and not check.flagged
    assert check.needle_z_at_finish_mm > 0


def test_stitch_run_agrees_with_the_single_move_check(needle):
    flagged = zigzag.sew(SPM, needle, stitches=3, rate=1000)
    assert flagged.summary["stitches_moving_in_fabric"] == [1, 2, 3]
    assert flagged.summary["worst_error_in_fabric_mm"] > flagged.summary["tolerance_mm"]
    clean = zigzag.sew(SPM, needle, stitches=3, rate=1500)
    assert clean.summary["stitches_moving_in_fabric"] == []
    columns = clean.columns
    inside = columns["needle_in_fabric"] > 0
    assert np.all(columns["needle_z_mm"][inside] <= 1e-9)  # in the fabric means below the plate top


def test_bad_needle_input(tmp_path):
    with pytest.raises(UserError):
        zigzag.NeedleProfile.slider_crank(60, 50)
    path = tmp_path / "needle.csv"
    path.write_text("arm_angle_deg,needle_z_mm\n0,1\n10,2\n")
    with pytest.raises(UserError, match="at least 8"):
        zigzag.NeedleProfile.from_csv(path)
    with pytest.raises(UserError, match="positive"):
        zigzag.check_move(-5, zigzag.NeedleProfile.slider_crank())
    with pytest.raises(UserError, match="no such file"):
        zigzag.machine_needle_profile(model_path=tmp_path / "missing.xml")


@pytest.mark.slow
def test_shipped_machine_needle_table_feeds_the_zigzag_check():
    # The shipped machine's needle rises 23.1 mm above the plate and goes 9.9 mm below it
    # (33 mm stroke): its table must say so, and at 1000 stitches/min a full-width move at
    # 1000 steps/s does not fit the time the needle spends above the plate.
    needle = zigzag.machine_needle_profile()
    heights = needle(np.linspace(0, 2 * np.pi, 721))
    assert heights.max() == pytest.approx(23.1, abs=0.01) and heights.min() == pytest.approx(
        -9.9, abs=0.01
    )
    check = zigzag.check_move(1000, needle, rate=1000)
    assert check.flagged
