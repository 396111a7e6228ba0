"""Closed kinematic chains: loop closures keep the closing joint's real degrees of freedom.

Checked against analytic kinematics (Freudenstein's four-bar equation, a frictionless slide)
on exports written by hand in tests/helpers/exports.py.
"""

import math

import mujoco
import numpy as np
import pytest

from mechanism.converters import convert
from tests.helpers.exports import FourBar, Gen1Export, bar_inertia, rotation
from tests.helpers.quirk_exports import INCH, proe_fourbar


def _drive(model_path, joint: str):
    """Compile the model with a joint equality that pins ``joint`` to ``model.eq_data[drive, 0]``."""
    spec = mujoco.MjSpec.from_file(str(model_path))
    spec.add_equality(
        name="drive",
        type=mujoco.mjtEq.mjEQ_JOINT,
        name1=joint,
        objtype=mujoco.mjtObj.mjOBJ_JOINT,
        data=[0.0] * 12,
    )
    model = spec.compile()
    return model, mujoco.MjData(model), model.equality("drive").id


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _tilted_fourbar(folder):
    fourbar = FourBar()
    return fourbar, fourbar.export(folder), 1e-3  # its length unit in metres


def _proe_fourbar(folder):
    built = proe_fourbar(folder)
    return built.facts["fourbar"], built.path, INCH


@pytest.mark.parametrize(
    "export",
    [_tilted_fourbar, _proe_fourbar],
    ids=["tilted plane, mm and g", "Pro/E: inches, lbm, RootPart, axes along -z"],
)
def test_fourbar_follows_freudenstein_over_a_full_crank_turn(tmp_path, export):
    fourbar, path, unit = export(tmp_path)
    report = convert(path, tmp_path / "out")
    assert report.joints_by_type["hinge"] == 3 and report.n_loop_closures == 1
    assert report.degrees_of_freedom == 1
    model, data, drive = _drive(report.mjcf_path, "ground--crank")
    assert model.opt.gravity[2] < 0

    def at(site):  # in the export's length unit
        return data.site(site).xpos / unit

    steps = int(1.0 / model.opt.timestep)  # one crank turn per second, 5% more to finish the turn
    errors, gaps, crank_angles = [], [], []
    for step in range(int(1.05 * steps)):
        model.eq_data[drive, 0] = 2 * math.pi * step / steps
        mujoco.mj_step(model, data)
        crank = fourbar.plane_angle(at("crank_end") - at("crank_start"))
        rocker = fourbar.plane_angle(at("rocker_end") - at("rocker_start"))
        errors.append(abs(_wrap(rocker - fourbar.rocker_angle(crank))))
        gap = at("coupler_end") - at("rocker_end")
        gaps.append(np.linalg.norm(gap - (gap @ fourbar.plane[:, 2]) * fourbar.plane[:, 2]))
        crank_angles.append(crank)
    assert np.unwrap(crank_angles)[-1] - crank_angles[0] > 2 * math.pi, (
        "a full turn about the export's joint axis"
    )
    print(
        f"four-bar: worst rocker error {math.degrees(max(errors)):.5f} deg, loop gap {max(gaps):.2e} (export length unit)"
    )
    assert math.degrees(max(errors)) < 0.5
    assert max(gaps) < 0.001 * fourbar.coupler, (
        "the closing pin stays closed to 0.1% of the coupler length"
    )


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
    link = doc.body(
        "link",
        100,
        (50, 0, -50),
        bar_inertia(100, 141, 8, 8),
        cg_rotation=rotation((0, 1, 0), math.pi / 4),
        named_frames=[("link_axis_origin", (100, 0, 0)), ("link_axis_tip", (100, 0, 20))],
    )
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
    # x tilted down by 30 degrees
    rail = rotation((0, 1, 0), math.radians(30)) @ np.array([1.0, 0, 0])
    base = doc.body("base", 1000, (0, 0, 0), np.diag([1e6] * 3))
    doc.weld_to_ground(base)
    slider = doc.body(
        "slider",
        300,
        (0, 0, 0),
        bar_inertia(300, 40, 20, 20),
        named_frames=[("slider_mark", (0, 0, 0))],
    )
    doc.joint("rail_left", base, slider, (0, -20, 0), [("prismatic", rail)])
    doc.joint("rail_right", base, slider, (0, 20, 0), [("prismatic", rail)])
    report = convert(doc.write(tmp_path / "rails.xml"), tmp_path / "out")
    assert (
        report.joints_by_type["slide"] == 2
        and report.n_loop_closures == 1
        and report.degrees_of_freedom == 1
    )
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    # the carrier holds a share of the slider's own mass distribution: together they are the slider
    carrier, slider_body = model.body("rail_right_carrier"), model.body("slider")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pair_mass = carrier.mass[0] + slider_body.mass[0]
    assert pair_mass == pytest.approx(0.3, rel=1e-9) and carrier.mass[0] > 0.01 * pair_mass
    centre = (
        carrier.mass[0] * data.xipos[carrier.id] + slider_body.mass[0] * data.xipos[slider_body.id]
    ) / pair_mass
    assert np.linalg.norm(centre - data.xipos[slider_body.id]) < 1e-9
    assert abs(model.body_mass.sum() - report.export_mass_kg) < 1e-9 * report.export_mass_kg
    data = mujoco.MjData(model)
    steps = 400
    for _ in range(steps):
        mujoco.mj_step(model, data)
    travelled = data.site("slider_mark").xpos.copy()
    t = steps * model.opt.timestep
    expected = 0.5 * 9.81 * math.sin(math.radians(30)) * t**2
    assert travelled @ rail == pytest.approx(expected, rel=0.01)
    assert np.linalg.norm(travelled - (travelled @ rail) * rail) < 1e-5, (
        "no motion across the rails"
    )


def test_gen2_slider_crank_follows_its_analytic_stroke(tmp_path):
    """Second-generation slider-crank in millimetres: crank r about world z, rod l, slider on a
    prismatic joint along world x (its joint frame's z axis turned onto x). The revolute
    rod--slider closes the loop; x_slider = r cos(q) + sqrt(l^2 - r^2 sin^2(q))."""
    from tests.helpers.exports import gen2_export, gen2_joint, gen2_part, gen2_transform

    r, l, q0 = 30.0, 100.0, math.radians(40)
    a = np.array([r * math.cos(q0), r * math.sin(q0), 0.0])
    b = np.array([r * math.cos(q0) + math.sqrt(l * l - (r * math.sin(q0)) ** 2), 0.0, 0.0])
    # an arbitrary part frame
    slider_pose = (
        rotation((0, 0, 1), math.radians(30)),
        b + np.array([0, 0, 5.0]),
    )

    def in_slider(point, frame_rotation=np.eye(3)):
        rot, origin = slider_pose
        return gen2_transform(rot.T @ frame_rotation, rot.T @ (np.asarray(point) - origin))

    along_x = rotation((0, 1, 0), math.pi / 2)  # maps z onto x
    parts = "".join(
        [
            gen2_part("ground", "P0", 1000, (0, 0, -10), (1e6, 1e6, 1e6, 0, 0, 0)),
            gen2_part("crank", "P1", 40, a / 2, (1e3, 4e3, 4e3, 0, 0, 0)),
            gen2_part("rod", "P2", 60, (a + b) / 2, (1e3, 5e4, 5e4, 0, 0, 0)),
            gen2_part("slider", "P3", 80, (0, 0, 0), (2e4, 2e4, 2e4, 0, 0, 0)),
        ]
    )
    instances = (
        '<Instance entityUid="P0" grounded="true" name="ground" uid="I0">'
        + gen2_transform()
        + "</Instance>"
        '<Instance entityUid="P1" name="crank" uid="I1">' + gen2_transform() + "</Instance>"
        '<Instance entityUid="P2" name="rod" uid="I2">' + gen2_transform() + "</Instance>"
        f'<Instance entityUid="P3" name="slider" uid="I3">{gen2_transform(*slider_pose)}</Instance>'
    )
    joints = (
        gen2_joint("Revolute", "crank", ["I0"], gen2_transform(), ["I1"], gen2_transform())
        + gen2_joint(
            "Revolute",
            "crank_pin",
            ["I1"],
            gen2_transform(None, a),
            ["I2"],
            gen2_transform(None, a),
        )
        + gen2_joint(
            "Prismatic", "guide", ["I0"], gen2_transform(along_x, b), ["I3"], in_slider(b, along_x)
        )
        + gen2_joint("Revolute", "wrist_pin", ["I2"], gen2_transform(None, b), ["I3"], in_slider(b))
    )
    (tmp_path / "slider_crank.xml").write_text(
        gen2_export(instances, joints, parts, length="millimeter", mass="gram")
    )
    report = convert(tmp_path / "slider_crank.xml", tmp_path / "out")
    assert report.joints_by_type == {"hinge": 2, "slide": 1, "ball": 0, "free": 0}
    assert report.n_loop_closures == 1 and report.degrees_of_freedom == 1
    model, data, drive = _drive(report.mjcf_path, "crank")
    steps = int(0.5 / model.opt.timestep)
    worst = 0.0
    for step in range(steps):
        model.eq_data[drive, 0] = 2 * math.pi * step / steps
        mujoco.mj_step(model, data)
        # positions of the new qpos (mj_step leaves those of the old one)
        mujoco.mj_kinematics(model, data)
        q = q0 + data.qpos[model.joint("crank").qposadr[0]]
        expected = r * math.cos(q) + math.sqrt(l * l - (r * math.sin(q)) ** 2)
        x = 1000 * data.site("slider").xpos[0]
        worst = max(worst, abs(x - expected))
    print(f"slider-crank: worst stroke error {worst:.5f} mm")
    assert worst < 0.001 * 2 * r, f"slider off its analytic stroke by {worst:.4f} mm"
