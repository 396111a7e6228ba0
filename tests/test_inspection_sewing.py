"""Probes and clearance checks on the shipped sewing machine."""

import mujoco
import numpy as np
import pytest

from mechanism.machine.models import DEFAULT_MODEL

pytestmark = pytest.mark.skipif(
    not DEFAULT_MODEL.exists(), reason="the shipped sewing machine MJCF is not in assets/mjcf"
)

RPM = 600.0


@pytest.fixture(scope="module")
def needle():
    from mechanism.inspection.needle import needle_motion

    return needle_motion(samples=360)


@pytest.fixture(scope="module")
def model():
    from mechanism.machine.models import load_model

    return load_model()


@pytest.mark.slow
def test_needle_tip_probe_reproduces_the_needle_inspection(needle):
    from mechanism.machine.machine import plate_top
    from mechanism.machine.models import load_spec
    from mechanism.inspection.probes import Probe, probe_cycle

    probes = [
        Probe("needle_tip", "position"),
        Probe("needle_tip", "velocity"),
        Probe("needle_tip", "acceleration"),
    ]
    columns = probe_cycle(
        load_spec(), probes, speed_rpm=RPM, resolution_deg=1.0, driver="arm_shaft"
    ).columns
    np.testing.assert_allclose(
        np.degrees(columns["arm_shaft_angle_rad"]), needle.arm_angle_deg, atol=1e-9
    )
    model = mujoco.MjModel.from_xml_path(str(DEFAULT_MODEL))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    plate_mm = plate_top(model, data, "needle_plate") * 1e3
    np.testing.assert_allclose(columns["needle_tip_z_mm"] - plate_mm, needle.needle_z_mm, atol=0.01)
    omega = RPM * 2 * np.pi / 60
    np.testing.assert_allclose(
        columns["needle_tip_vz_m_s"] * 1e3 / omega, needle.needle_velocity_mm_per_rad, atol=1e-6
    )
    # the inspection differentiates spectrally, the probe by central differences of exact velocities
    np.testing.assert_allclose(
        columns["needle_tip_az_m_s2"] * 1e3 / omega**2,
        needle.needle_acceleration_mm_per_rad2,
        atol=1e-3,
    )


def test_hook_point_clearance_at_the_passage_agrees_with_the_needle_inspection(model, needle):
    """Two independent measurements: the needle inspection's hook point (a site) to the
    needle mesh, and the clearance checker's exact part-to-part distance, at the passage."""
    from mechanism.inspection.clearance import ClearanceSweep, Pair
    from mechanism.kinematics.pose import sweep as pose_sweep

    sweep = ClearanceSweep(model, [Pair("needle", "hook")], driver="arm_shaft")
    result = sweep.run(full_curve=True)[0]
    angle = np.radians(needle.hook_passage_angle_deg)
    # walk there: same assembly branch
    start = pose_sweep(model, np.linspace(0.0, angle, 100), "arm_shaft")[-1]
    distance, _, _ = sweep.distance_at(Pair("needle", "hook"), angle, start)
    assert distance * 1e3 == pytest.approx(needle.hook_point_clearance_mm, abs=0.01)
    # household practice: 0-0.1 mm between hook point and needle (Janome 1600P service manual)
    assert 0.0 <= needle.hook_point_clearance_mm <= 0.1 + 1e-3
    assert result.grid_distance_mm.max() > 5.0  # the hook is far away for most of the cycle


def test_shipped_machine_passes_at_nominal_dimensions(model):
    from mechanism.inspection.clearance import check_clearance, parse_pairs

    report = check_clearance(
        model, parse_pairs("needle:hook,needle:needle_plate", model), driver="arm_shaft"
    )
    hook, plate = report.results
    assert report.passed
    assert 0.0 < hook.min_distance_mm <= 0.1 + 1e-3  # household range: 0-0.1 mm (Janome 1600P)
    # just after bottom dead centre, the needle rising (loop lift)
    assert 195.0 < hook.angle_deg < 215.0
    assert plate.min_distance_mm > 0.1


@pytest.mark.slow
def test_mistimed_hook_collides_with_the_needle(model):
    from mechanism.inspection.clearance import Pair
    from mechanism.inspection.variants import VariantSet, parameter, run_variants

    # the shipped description's mistimed variant
    variants = VariantSet(
        [parameter("hook_timing_deg", "coupling:hook_worm_gear:hook_deg")],
        ["nominal", "early hook"],
        np.array([[0.0], [40.0]]),
    )
    batch = run_variants(
        model, variants, [Pair("needle", "hook")], driver="arm_shaft", progress=False
    )
    early = batch.rows[1]
    assert early["pass"] == 0 and early["needle_vs_hook_min_mm"] < -0.01
    # 40 deg early on the hook = 20 deg early on the arm: the point reaches the needle near bottom dead centre
    assert 175.0 < early["needle_vs_hook_angle_deg"] < 195.0
