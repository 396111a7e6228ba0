"""Clearance between real part shapes against analytic cases (0.01 mm)."""

import mujoco
import numpy as np
import pytest

from tests.helpers import mechanisms as M
from mechanism.inspection.clearance import Pair, all_pairs, check_clearance, parse_pairs
from mechanism.errors import UserError
from mechanism.kinematics.pose import sweep

TOL_MM = 0.01


@pytest.fixture(scope="module")
def needle_model():
    return M.needle_and_plate().compile()


def test_two_cylinders_minimum_distance_and_angle():
    expected_mm = (0.03 - 0.012 - 0.005 - 0.004) * 1e3
    mesh = check_clearance(
        M.crank_and_post().compile(), [Pair("post", "pin")], driver="arm_shaft"
    ).results[0]
    assert mesh.min_distance_mm == pytest.approx(expected_mm, abs=TOL_MM)
    assert not mesh.interferences
    # the tessellated cylinders' distance ripples by ~1e-7 m, which flattens the minimum's angle
    assert mesh.angle_deg == pytest.approx(37.3, abs=0.05)
    exact = check_clearance(
        M.crank_and_post(mesh=False).compile(), [Pair("post", "pin")], driver="arm_shaft"
    ).results[0]
    assert exact.min_distance_mm == pytest.approx(expected_mm, abs=1e-6)
    assert exact.angle_deg == pytest.approx(37.3, abs=1e-3)
    # the closest points lie on the line of centres, on each surface
    assert np.linalg.norm(exact.point_a_mm - exact.point_b_mm) == pytest.approx(
        expected_mm, abs=1e-6
    )
    assert exact.point_a_mm[0] == pytest.approx(30 - 5, abs=1e-4)


def test_sampled_curve_is_the_analytic_distance():
    sweep_result = check_clearance(
        M.crank_and_post().compile(), [Pair("post", "pin")], resolution_deg=5, driver="arm_shaft"
    ).results[0]
    from mechanism.inspection.clearance import ClearanceSweep

    sweep = ClearanceSweep(
        M.crank_and_post().compile(), [Pair("post", "pin")], driver="arm_shaft", resolution_deg=5
    )
    curve = sweep.run(full_curve=True)[0]
    theta = np.radians(curve.grid_angle_deg)
    np.testing.assert_allclose(
        curve.grid_distance_mm, M.crank_post_distance(theta) * 1e3, atol=TOL_MM
    )
    # skipping far samples on the hull bound changes nothing at the minimum
    assert curve.min_distance_mm == pytest.approx(sweep_result.min_distance_mm, abs=1e-9)


@pytest.mark.slow
def test_interfering_cylinders_depth_and_angle_range():
    P, rho, reach = 0.019, 0.012, 0.009
    result = check_clearance(
        M.crank_and_post(P=P).compile(), [Pair("post", "pin")], driver="arm_shaft"
    ).results[0]
    assert len(result.interferences) == 1
    hit = result.interferences[0]
    depth_mm = (reach - (P - rho)) * 1e3
    half_width = np.degrees(np.arccos((P**2 + rho**2 - reach**2) / (2 * P * rho)))
    assert hit.depth_mm == pytest.approx(depth_mm, abs=TOL_MM)
    assert result.min_distance_mm == pytest.approx(-depth_mm, abs=TOL_MM)
    assert hit.start_deg == pytest.approx(37.3 - half_width, abs=0.01)
    assert hit.end_deg == pytest.approx(37.3 + half_width, abs=0.01)
    assert hit.angle_deg == pytest.approx(37.3, abs=0.5)
    assert not result.passes()


@pytest.mark.slow
def test_needle_through_plate_hole_is_a_clearance_not_a_hull_collision(needle_model):
    result = check_clearance(
        needle_model, [Pair("needle", "needle_plate")], driver="arm_shaft"
    ).results[0]
    expected_mm = (M.HOLE_RADIUS - M.NEEDLE_RADIUS - M.OFFSET) * 1e3
    assert result.min_distance_mm == pytest.approx(expected_mm, abs=TOL_MM)
    assert not result.interferences
    # at that angle the needle is inside the hole: MuJoCo's convex hull of the plate would collide
    data = mujoco.MjData(needle_model)
    data.qpos[:] = sweep(
        needle_model, np.linspace(0, np.radians(result.angle_deg), 60), "arm_shaft"
    )[-1]  # stay on the assembly branch
    mujoco.mj_kinematics(needle_model, data)
    tip = data.site("needle_tip").xpos[2]
    assert tip < M.PLATE_TOP
    hull = mujoco.mj_geomDistance(
        needle_model,
        data,
        needle_model.geom("needle").id,
        needle_model.geom("needle_plate").id,
        1.0,
        None,
    )
    assert hull < 0


def test_hook_point_passes_the_needle_scarf(needle_model):
    result = check_clearance(needle_model, [Pair("needle", "hook")], driver="arm_shaft").results[0]
    assert result.min_distance_mm == pytest.approx(M.HOOK_GAP * 1e3, abs=TOL_MM)
    assert result.angle_deg == pytest.approx(M.HOOK_PASS_DEG, abs=0.1)
    assert result.passes(required_mm=0.05) and not result.passes(required_mm=0.2)


@pytest.mark.slow
def test_mistimed_hook_hits_the_needle():
    model = M.needle_and_plate(
        hook_offset_deg=-30
    ).compile()  # passes at 210 deg: the scarf is above the hook
    result = check_clearance(model, [Pair("needle", "hook")], driver="arm_shaft").results[0]
    assert result.interferences
    assert result.min_distance_mm < 0
    # the hook point cuts into the full needle diameter: up to 0.2 mm (scarf depth minus gap)
    assert 0 < result.interferences[0].depth_mm <= (M.SCARF[2] - M.HOOK_GAP) * 1e3 + TOL_MM


def test_pairs_are_checked(needle_model):
    assert parse_pairs("needle:hook, needle:needle_plate", needle_model) == [
        Pair("needle", "hook"),
        Pair("needle", "needle_plate"),
    ]
    with pytest.raises(UserError, match="same part twice"):
        parse_pairs("needle:needle", needle_model)
    with pytest.raises(UserError, match="close matches: needle"):
        parse_pairs("neddle:hook", needle_model)
    with pytest.raises(UserError, match="A:B"):
        parse_pairs("needle", needle_model)


def test_all_pairs_skip_parts_joined_to_each_other(needle_model):
    pairs = {frozenset((p.a, p.b)) for p in all_pairs(needle_model)}
    assert frozenset(("needle", "hook")) in pairs and frozenset(("needle", "needle_plate")) in pairs
    assert frozenset(("rod", "needle_bar")) not in pairs  # closed by the loop connects
    assert frozenset(("crank", "rod")) not in pairs  # the crank pin joint
    assert frozenset(("needle", "needle_bar")) not in pairs  # same body
    # the frame holds more than the bushing
    assert frozenset(("needle_bar", "needle_plate")) in pairs


def test_a_long_clearance_check_shows_its_progress(monkeypatch):
    """`clearance --all-pairs` runs for a minute on a real machine: a bar (tqdm, shown on a
    terminal after 2 s) counts every sample of the cycle and every pair to the end."""
    import tqdm

    seen = []

    class Recorder(tqdm.tqdm):
        def __init__(self, *args, **kwargs):
            kwargs.update(disable=False, delay=0.0)
            super().__init__(*args, **kwargs)
            seen.append(self)

    monkeypatch.setattr(tqdm, "tqdm", Recorder)
    check_clearance(
        M.crank_and_post(mesh=False).compile(),
        [Pair("post", "pin")],
        driver="arm_shaft",
        resolution_deg=10.0,
        progress=True,
    )
    assert len(seen) == 1 and seen[0].total == 36 + 1 and seen[0].n == seen[0].total
