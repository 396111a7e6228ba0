"""Closed kinematic chains: loop closures keep the closing joint's real degrees of freedom.

Checked against analytic kinematics (Freudenstein's four-bar equation, a frictionless slide)
on exports written by hand in tests/exports.py.
"""

import math

import mujoco
import numpy as np
import pytest

from converters import convert
from exports import FourBar, Gen1Export, bar_inertia, rotation


def _drive(model_path, joint: str):
    """Compile the model with a joint equality that pins ``joint`` to ``model.eq_data[drive, 0]``."""
    spec = mujoco.MjSpec.from_file(str(model_path))
    spec.add_equality(name="drive", type=mujoco.mjtEq.mjEQ_JOINT, name1=joint, objtype=mujoco.mjtObj.mjOBJ_JOINT,
                      data=[0.0] * 12)
    model = spec.compile()
    return model, mujoco.MjData(model), model.equality("drive").id


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def test_fourbar_in_a_tilted_plane_follows_freudenstein_over_a_full_crank_turn(tmp_path):
    fourbar = FourBar()
    report = convert(fourbar.export(tmp_path), tmp_path / "out")
    assert report.joints_by_type["hinge"] == 3 and report.n_loop_closures == 1
    assert report.degrees_of_freedom == 1
    model, data, drive = _drive(report.mjcf_path, "ground--crank")
    assert model.opt.gravity[2] < 0  # gravity acts in the tilted plane: the drive works against it

    def mm(site):
        return data.site(site).xpos * 1000.0

    steps = int(1.0 / model.opt.timestep)  # one crank turn per second, 5% more to finish the turn
    errors, gaps, crank_angles = [], [], []
    for step in range(int(1.05 * steps)):
        model.eq_data[drive, 0] = 2 * math.pi * step / steps
        mujoco.mj_step(model, data)
        crank = fourbar.plane_angle(mm("crank_end") - mm("crank_start"))
        rocker = fourbar.plane_angle(mm("rocker_end") - mm("rocker_start"))
        errors.append(abs(_wrap(rocker - fourbar.rocker_angle(crank))))
        gap = mm("coupler_end") - mm("rocker_end")
        gaps.append(np.linalg.norm(gap - (gap @ fourbar.plane[:, 2]) * fourbar.plane[:, 2]))
        crank_angles.append(crank)
    assert np.ptp(np.unwrap(crank_angles)) > 2 * math.pi, "the crank made a full turn"
    assert math.degrees(max(errors)) < 0.5
    assert max(gaps) < 0.001 * fourbar.coupler, "the closing pin stays closed to 0.1% of the coupler length"


def _spatial_loop(folder):
    """Ground -hinge(z)- A -revolute(z)- B, and B -spherical- ground below A's axis: one DOF.

    The spherical joint goes into the tree, so the A-B revolute closes the loop. Were it
    closed by a single point, B could spin about the line from the ball to the pin.
    """
    doc = Gen1Export()
    z = (0, 0, 1)
    base = doc.body("base", 1000, (0, 0, -150), np.diag([1e6] * 3) * 1.0)
    doc.weld_to_ground(base, (0, 0, -150))
    arm = doc.body("arm", 200, (50, 0, 0), bar_inertia(200, 100, 10, 10))
    link = doc.body("link", 100, (50, 0, -50), bar_inertia(100, 141, 8, 8), cg_rotation=rotation((0, 1, 0), math.pi / 4),
                    named_frames=[("link_axis_origin", (100, 0, 0)), ("link_axis_tip", (100, 0, 20))])
    doc.joint("arm_hinge", base, arm, (0, 0, 0), [("revolute", z)])
    doc.joint("ball", base, link, (0, 0, -100), [("spherical", (0, 0, 1))])
    doc.joint("pin", arm, link, (100, 0, 0), [("revolute", z)])
    return doc.write(folder / "spatial.xml")


def test_revolute_loop_closure_keeps_the_joint_axis_under_a_torque_about_another_axis(tmp_path):
    report = convert(_spatial_loop(tmp_path), tmp_path / "out")
    assert report.joints_by_type == {"hinge": 1, "slide": 0, "ball": 1, "free": 0}
    assert report.degrees_of_freedom == 1
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    closures = [model.equality(i).name for i in range(model.neq)]
    assert closures == ["loop:pin", "loop:pin:2"]
    data = mujoco.MjData(model)
    model.opt.gravity[:] = 0
    link = model.body("link").id
    spin_axis = np.array([100.0, 0.0, 100.0]) / math.hypot(100, 100)  # ball centre -> pin
    for _ in range(1000):  # 0.5 s of a 0.2 N*m torque that only a point closure would let through
        data.xfrc_applied[link, 3:] = 0.2 * spin_axis
        mujoco.mj_step(model, data)
    axis = data.site("link_axis_tip").xpos - data.site("link_axis_origin").xpos
    tilt = math.degrees(math.acos(np.clip(axis[2] / np.linalg.norm(axis), -1, 1)))
    assert tilt < 0.5, f"the pin's axis tilted by {tilt:.3f} degrees"


def test_prismatic_loop_closure_uses_a_carrier_and_slides_freely(tmp_path):
    """A slider on two parallel rails: one rail is a tree slide, the other closes the loop
    through a carrier body. Down a 30 degree incline it must accelerate at g sin(30)."""
    doc = Gen1Export()
    rail = rotation((0, 1, 0), math.radians(30)) @ np.array([1.0, 0, 0])  # x tilted down by 30 degrees
    base = doc.body("base", 1000, (0, 0, 0), np.diag([1e6] * 3))
    doc.weld_to_ground(base)
    slider = doc.body("slider", 300, (0, 0, 0), bar_inertia(300, 40, 20, 20), named_frames=[("slider_mark", (0, 0, 0))])
    doc.joint("rail_left", base, slider, (0, -20, 0), [("prismatic", rail)])
    doc.joint("rail_right", base, slider, (0, 20, 0), [("prismatic", rail)])
    report = convert(doc.write(tmp_path / "rails.xml"), tmp_path / "out")
    assert report.joints_by_type["slide"] == 2 and report.n_loop_closures == 1 and report.degrees_of_freedom == 1
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.body("rail_right_carrier").mass[0] < 0.01 * model.body("slider").mass[0]
    assert abs(model.body_mass.sum() - report.export_mass_kg) < 0.005 * report.export_mass_kg
    data = mujoco.MjData(model)
    steps = 400
    for _ in range(steps):
        mujoco.mj_step(model, data)
    travelled = data.site("slider_mark").xpos.copy()
    t = steps * model.opt.timestep
    expected = 0.5 * 9.81 * math.sin(math.radians(30)) * t**2
    assert travelled @ rail == pytest.approx(expected, rel=0.01)
    assert np.linalg.norm(travelled - (travelled @ rail) * rail) < 1e-5, "no motion across the rails"
