"""What real CAD exporters write (docs/real_exports.md), on hand-built exports that carry the same
features and quirks (tests/helpers/quirk_exports.py): masses, joints found from mates, freedoms, loops
that close and move. Expected numbers come from each design's own geometry."""

import math

import mujoco
import numpy as np
import pytest

from mechanism.converters import convert, read
from mechanism.converters.names import sanitize
from tests.helpers.exports import rotation
from tests.helpers.quirk_exports import (
    INCH,
    X,
    Y,
    Z,
    ball_and_beam,
    ball_in_groove,
    circles_meet,
    conveyor_with_origin_mates,
    creo_arm,
    creo_ball_beam_rigid,
    furuta,
    hexapod_link,
    massless_link_tiny_parts,
    massless_skeleton_moving,
    onshape_copter,
    planar_puck,
    proe_fourbar,
    robot_shin,
    scara_printer,
    simscape_link_gen1,
)

BUILDERS = [
    proe_fourbar,
    ball_and_beam,
    furuta,
    hexapod_link,
    robot_shin,
    creo_arm,
    scara_printer,
    onshape_copter,
]
# one stand-in per failure class of issue 14, in its order
ISSUE_14 = [
    simscape_link_gen1,
    massless_link_tiny_parts,
    massless_skeleton_moving,
    planar_puck,
    creo_ball_beam_rigid,
    ball_in_groove,
    conveyor_with_origin_mates,
]
# furuta's world is Y-up; the puck's table stands in the xy plane: gravity along it
UP = {
    furuta: "y",
    planar_puck: "y",
}


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """builder -> (Built, ConversionReport), each export written and converted once."""
    cache = {}

    def get(builder):
        if builder not in cache:
            folder = tmp_path_factory.mktemp(builder.__name__)
            export = builder(folder)
            cache[builder] = export, convert(export.path, folder / "out", up=UP.get(builder, "z"))
        return cache[builder]

    return get


def _pairs(path, top_level=False):
    """(base, follower) -> joint for the joints the export's joints or mates define."""
    assembly = read(path)
    name = (lambda key: key.split("/")[0]) if top_level else (lambda key: assembly.parts[key].name)
    return {(name(j.base), name(j.follower)): j for j in assembly.joints if not j.synthetic}


def _driven(mjcf_path, *joints):
    """The model with a joint equality per joint pinning it to ``eq_data[id, 0]``, and no gravity."""
    spec = mujoco.MjSpec.from_file(str(mjcf_path))
    for joint in joints:
        spec.add_equality(
            name=f"drive {joint}",
            type=mujoco.mjtEq.mjEQ_JOINT,
            name1=joint,
            objtype=mujoco.mjtObj.mjOBJ_JOINT,
            data=[0.0] * 12,
        )
    model = spec.compile()
    model.opt.gravity[:] = 0
    return model, mujoco.MjData(model), [model.equality(f"drive {j}").id for j in joints]


def _turned_by(start, end) -> float:
    """The angle (rad) between two orientations."""
    return math.acos(np.clip((np.trace(start.T @ end) - 1) / 2, -1, 1))


def _loop_error(data, skip=()) -> float:
    rows = (data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & ~np.isin(
        data.efc_id, list(skip)
    )
    return float(np.abs(data.efc_pos[rows]).max(initial=0.0))


@pytest.mark.parametrize("builder", BUILDERS, ids=lambda b: b.__name__)
def test_export_converts_with_its_mass_and_nothing_floating(built, builder):
    export, report = built(builder)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert report.export_mass_kg == pytest.approx(export.mass_kg, rel=1e-12)
    assert model.body_mass.sum() == pytest.approx(export.mass_kg, rel=1e-9)
    assert mujoco.mjtJoint.mjJNT_FREE not in set(model.jnt_type)
    assert any("geometry file(s) are missing" in w for w in report.warnings)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert _loop_error(data) < 1e-9, "loops are closed at the assembly pose"


def test_proe_fourbar_in_inches_and_pounds_through_a_root_part(built):
    """Pro/E writes lbm, lbm*in^2 and inches, grounds the frame through a massless RootPart and
    writes the pin axes along -z (Freudenstein over a full turn: test_closed_chain.py)."""
    export, report = built(proe_fourbar)
    fourbar = export.facts["fourbar"]
    assert report.n_bodies == 4 and report.degrees_of_freedom == 1 and report.n_loop_closures == 1
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    o2, o4, a, b = fourbar.points()
    for site, pin, layer in (
        ("crank_start", o2, 1),
        ("crank_end", a, 1),
        ("coupler_end", b, 2),
        ("rocker_start", o4, 1),
    ):
        assert data.site(site).xpos == pytest.approx(
            fourbar.world(*pin, 4.0 * layer) * INCH, abs=1e-9
        )
    assert data.joint("ground--crank").xaxis == pytest.approx([0, 0, -1], abs=1e-9)
    crank = model.body("crank")
    expected = fourbar.masses()["crank"] * 0.45359237
    assert crank.mass[0] == pytest.approx(expected, rel=1e-9)
    # a bar's inertia about its long axis: m (w^2 + t^2) / 12 in lbm*in^2
    assert min(crank.inertia) == pytest.approx(
        expected * (6.0**2 + 3.0**2) / 12 * INCH**2, rel=1e-6
    )


def test_solidworks_ball_and_beam_mates_give_a_spatial_loop_that_moves_as_designed(built):
    """Seven revolutes and a cylindrical from coincident, concentric, parallel, distance and angle
    mates; driving the servo 20 degrees turns the beam as the four-bar S-A-B-P says."""
    export, report = built(ball_and_beam)
    facts = export.facts
    assert {pair: j.kind for pair, j in _pairs(export.path).items()} == facts["joints"]
    assert any(facts["loose"] in w and "fixed to the world" in w for w in report.warnings)
    assert report.n_loop_closures == 1
    model, data, (drive,) = _driven(report.mjcf_path, "servo-1--horn-1")
    s, p = facts["S"], facts["P"]
    plane = lambda v: np.array([v @ X, v @ Z])  # the plane of motion
    angle = lambda v: math.atan2(v[1], v[0])
    mujoco.mj_forward(model, data)
    beam_start = data.site("beam-1").xmat.reshape(3, 3).copy()
    for step in range(600):
        model.eq_data[drive, 0] = math.radians(20) * min(1.0, step / 400)
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    assert _loop_error(data, skip=[drive]) < 1e-5, "the linkage stays closed (10 micrometres)"
    a, b = data.site("horn-1").xpos, data.site("fork_s-1").xpos
    alpha = angle(plane(a - s))
    assert abs(math.degrees(alpha - angle(plane(facts["A"] - s)))) == pytest.approx(20, abs=0.05)
    expected_b = circles_meet(
        plane(p), facts["beam"], plane(a), facts["rod"], near=plane(facts["B"])
    )
    assert plane(b) == pytest.approx(expected_b, abs=1e-6)
    assert abs(b @ Y - facts["B"] @ Y) < 1e-6, "nothing leaves the plane of motion"
    tilt = _turned_by(beam_start, data.site("beam-1").xmat.reshape(3, 3))
    expected_tilt = abs(
        math.remainder(angle(expected_b - plane(p)) - angle(plane(facts["B"] - p)), 2 * math.pi)
    )
    assert expected_tilt > math.radians(1)
    assert math.degrees(tilt) == pytest.approx(math.degrees(expected_tilt), abs=1e-3)


def _settle(mjcf_path, joint, seconds=0.25) -> float:
    """How far ``joint`` moves from the assembly pose, left alone under gravity for ``seconds``."""
    model = mujoco.MjModel.from_xml_path(str(mjcf_path))
    data = mujoco.MjData(model)
    for _ in range(int(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return abs(float(data.joint(joint).qpos[0]))


def test_furuta_pendulum_in_a_y_up_world(built, tmp_path):
    """Mates only, with a lock mate exported as an UnknownConstraint (reported), a hidden part (kept)
    and circle geometry: the pendulum turns about the arm, perpendicular to the vertical motor axis,
    and hangs still when gravity acts against the export's y axis (``up="y"``), not against z."""
    export, report = built(furuta)
    facts = export.facts
    assert any("Lock3" in w and "UnknownConstraint" in w for w in report.warnings)
    joints = _pairs(export.path)
    assert {pair: j.kind for pair, j in joints.items()} == facts["joints"]
    pendulum = joints[("encoder mount-1", "pendulum-1")]
    motor = joints[("arm-1", "shaft coupling-1")]
    (swing,), (spin,) = pendulum.primitives, motor.primitives
    assert abs(swing.axis @ X) == pytest.approx(1, abs=1e-9) and abs(
        spin.axis @ facts["up"]
    ) == pytest.approx(1, abs=1e-9)
    assert (
        np.linalg.norm(np.cross(pendulum.base_frame.position - facts["pivot"], swing.axis)) < 1e-9
    )
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.opt.gravity == pytest.approx([0, -9.81, 0])
    assert model.site(sanitize(facts["hidden"])).id >= 0
    joint = sanitize(facts["pendulum"])
    assert _settle(report.mjcf_path, joint) < 1e-6, "hanging straight down: at rest"
    z_up = convert(export.path, tmp_path / "z-up")
    assert _settle(z_up.mjcf_path, joint) > 0.05, (
        "with gravity along -z the pendulum falls sideways"
    )


def test_legacy_root_with_one_rigid_subassembly_used_twice_and_cyrillic_names(built):
    """SimMechanics Link 4's SimMechanicsImportXML: the servo sub-assembly's inner uids repeat in
    its two instances; Cyrillic part and mate names; the mates bolt everything into one body."""
    export, report = built(hexapod_link)
    facts = export.facts
    assert "SimMechanicsImportXML" in report.export_format
    assert (
        report.n_parts == facts["n_parts"]
        and report.n_bodies == 1
        and report.degrees_of_freedom == 0
    )
    assembly = read(export.path)
    assert facts["unicode_parts"] <= {p.name for p in assembly.parts.values()}
    assert sum("by mates" in j.name for j in assembly.joints) == 4, (
        "bracket, plate, bracket: four bolted pairs"
    )
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    sites = {model.site(i).name for i in range(model.nsite)}
    assert len(sites) == model.nsite == facts["n_parts"], (
        "every part has its own site, also where names collide"
    )
    assert {"case-1", "case-1_2", "top-1", "top-1_2"} <= sites
    assert data.site("case-1_2").xpos == pytest.approx(facts["case_b"], abs=1e-9)


def test_flexible_subassembly_keeps_its_own_mates_in_its_own_frame(built):
    """robot_shin: the damper sub-assembly (flexible, turned about z) mates its cap and rod in its
    own frame: the rod slides along the damper. Turning the shin about the knee, the rod eye follows
    the shin and the damper turns about its housing eye to keep pointing at it."""
    export, report = built(robot_shin)
    facts = export.facts
    axis, knee, h, d = facts["damper_axis"], facts["knee"], facts["housing_eye"], facts["rod_eye"]
    joints = _pairs(export.path)
    stroke, cap = joints[("cap-1", "stroke-1")], joints[("housing-1", "cap-1")]
    assert stroke.kind == "cylindrical" and cap.kind == "revolute"
    for joint in (stroke, cap):
        assert abs(joint.primitives[-1].axis @ axis) == pytest.approx(1, abs=1e-5)
    assert report.n_loop_closures == 3, "12 joints between 10 rigid units"
    assert report.degrees_of_freedom == 7, (
        "the shin, the foot, four pins' and the damper cap's spins"
    )
    # the shin's face mate to the knee is a planar joint: its hinge turns the shin
    model, data, (drive,) = _driven(report.mjcf_path, "lower_knee-1--upper_shin-1_hinge")
    mujoco.mj_forward(model, data)
    assert (
        len(
            {
                model.site_bodyid[model.site(s).id]
                for s in ("ankle-1", "sole-1", "spring_a-1", "spring_b-1")
            }
        )
        == 1
    )
    shin = model.body("upper_shin-1").id
    start = data.xmat[shin].reshape(3, 3).copy()
    # the damper axis in the housing's frame
    housing_axis = data.site("housing-1").xmat.reshape(3, 3).T @ axis
    for step in range(500):
        model.eq_data[drive, 0] = 0.3 * min(1.0, step / 400)
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    assert _loop_error(data, skip=[drive]) < 1e-5
    turned = math.atan2(*(start.T @ data.xmat[shin].reshape(3, 3))[[1, 0], 0])
    assert abs(turned) == pytest.approx(0.3, abs=1e-4)
    assert data.site("upper_shin-1").xpos == pytest.approx(knee, abs=1e-6), (
        "the shin turns about the knee pin"
    )
    rod_eye = knee + rotation(Z, turned) @ (d - knee)
    assert data.site("stroke-1").xpos == pytest.approx(rod_eye, abs=1e-6)
    pointing = data.site("housing-1").xmat.reshape(3, 3) @ housing_axis
    assert pointing == pytest.approx((rod_eye - h) / np.linalg.norm(rod_eye - h), abs=1e-6)


def test_creo_export_without_data_units_is_read_in_its_model_units(built):
    """Creo 6 writes no <DataUnits>: numbers are in the ModelUnits (mm); its line axes are long
    vectors. Each line + plane coincidence gives the designed prismatic or revolute joint."""
    export, report = built(creo_arm)
    joints = _pairs(export.path, top_level=True)
    assert set(joints) == set(export.facts["joints"])
    for pair, (kind, axis, point_m) in export.facts["joints"].items():
        joint = joints[pair]
        assert joint.kind == kind
        assert abs(joint.primitives[0].axis @ axis) == pytest.approx(1, abs=1e-9)
        if kind == "revolute":
            assert np.linalg.norm(np.cross(joint.base_frame.position - point_m, axis)) < 1e-9, (
                "on the designed axis, in metres"
            )
    assert read(export.path).parts["5"].com == pytest.approx([0, 0, 0.0064], abs=1e-12)
    assert report.degrees_of_freedom == 6 and report.n_loop_closures == 0
    assert any(
        export.facts["skeleton"] in w and "connected to nothing" in w for w in report.warnings
    )


def test_parallel_arm_printer_moves_its_head_as_the_five_bar_says(built):
    """Rigid sub-assemblies for every link (two used several times), pins from circle-circle
    mates: 9 revolutes, 2 cylindricals and the bed's prismatic; 3 loops; 3 freedoms. Turning
    the two cranks moves the head to the five-bar's point and the parallelograms keep it square."""
    export, report = built(scara_printer)
    facts = export.facts
    joints = _pairs(export.path, top_level=True)
    assert {pair: j.kind for pair, j in joints.items()} == facts["joints"]
    assert report.degrees_of_freedom == 3 and report.n_loop_closures == 3
    cranks = [sanitize(joints[("base-1", k)].name) for k in ("crank-2", "crank-3")]
    model, data, drives = _driven(report.mjcf_path, *cranks)
    mujoco.mj_forward(model, data)
    head_start = data.site("carriage-1").xmat.reshape(3, 3).copy()
    targets = np.radians([8.0, -6.0])
    for step in range(500):
        model.eq_data[drives, 0] = targets * min(1.0, step / 300)
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    assert _loop_error(data, skip=drives) < 1e-5
    turned = [float(data.joint(c).qpos[0] * (data.joint(c).xaxis @ Z)) for c in cranks]  # about +z
    assert np.abs(turned) == pytest.approx(np.abs(targets), abs=1e-4)
    tip = lambda pivot, theta: pivot + facts["crank"] * np.array([math.cos(theta), math.sin(theta)])
    head = circles_meet(
        tip(facts["o1"], facts["theta_b"] + turned[0]),
        facts["forearm"],
        tip(facts["o2"], facts["theta_c"] + turned[1]),
        facts["forearm"],
        near=facts["head"],
    )
    assert np.linalg.norm(head - facts["head"]) > 0.005, "the head moved"
    assert data.site("carriage-1").xpos[:2] == pytest.approx(head, abs=1e-6)
    assert math.degrees(_turned_by(head_start, data.site("carriage-1").xmat.reshape(3, 3))) < 1e-3


def test_onshape_subassembly_joints_repeat_per_instance(built):
    """Onshape: one arm-motor sub-assembly used six times, each with a cylindrical and a planar
    joint between the same arm and motor (together: a spinning motor) and a revolute blade;
    centimetre documents, metre data."""
    export, report = built(onshape_copter)
    arms = export.facts["arms"]
    assert report.degrees_of_freedom == 2 * arms
    assert report.joints_by_type["hinge"] == 3 * arms and report.joints_by_type["slide"] == 3 * arms
    assert report.n_loop_closures == arms
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    for k, blade in enumerate(export.facts["blades"]):
        assert data.site("Blade" if k == 0 else f"Blade_{k + 1}").xpos == pytest.approx(
            blade, abs=1e-8
        )


# -- issue 14: the classes of real exports the converter got wrong --------------------------------


def _loop_error_under_gravity(mjcf_path, seconds=0.1, damping=0.05) -> float:
    """The largest loop-closure error (m) while the model moves under gravity for ``seconds`` from
    the assembly pose, every joint damped (``damping`` N*m*s/rad or N*s/m)."""
    model = mujoco.MjModel.from_xml_path(str(mjcf_path))
    model.dof_damping[:] = damping
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    worst = _loop_error(data)
    for _ in range(int(round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
        worst = max(worst, _loop_error(data))
    return worst


@pytest.mark.parametrize("builder", ISSUE_14, ids=lambda b: b.__name__)
def test_issue_14_exports_convert_with_the_exports_mass_and_closed_loops(built, builder):
    """What the held-out real exports are checked for: MuJoCo loads the model, its total mass is the
    export's (exactly: only float rounding), nothing floats, loops are closed at the assembly pose
    and stay closed to 0.1 mm for 0.1 s under gravity with damped joints."""
    export, report = built(builder)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert report.export_mass_kg == pytest.approx(export.mass_kg, rel=1e-12)
    assert model.body_mass.sum() == pytest.approx(export.mass_kg, rel=1e-9)
    assert mujoco.mjtJoint.mjJNT_FREE not in set(model.jnt_type)
    assert _loop_error_under_gravity(report.mjcf_path) < 1e-4


def test_simscape_multibody_link_first_generation_root(built, tmp_path):
    """Class 1: Simscape Multibody Link 4.8+ names the first-generation model element
    <SimscapeMultibody>: the same four-bar as under <SimMechanics>."""
    export, report = built(simscape_link_gen1)
    assert report.export_format.startswith("first-generation")
    assert report.n_bodies == 4 and report.degrees_of_freedom == 1 and report.n_loop_closures == 1
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    fourbar = export.facts["fourbar"]
    _, _, a, _ = fourbar.points()
    assert data.site("crank_end").xpos == pytest.approx(fourbar.world(*a, 4.0) * 1e-3, abs=1e-9)
    # the same model element written as the document's root
    text = export.path.read_text(encoding="utf-8")
    start, end = (
        text.index("<SimscapeMultibody>"),
        text.index("</SimscapeMultibody>") + len("</SimscapeMultibody>"),
    )
    bare = tmp_path / "bare.xml"
    bare.write_text(text[start:end], encoding="utf-8")
    again = convert(bare, tmp_path / "bare")
    assert (again.n_bodies, again.degrees_of_freedom, again.total_mass_kg) == (
        4,
        1,
        report.total_mass_kg,
    )


def test_massless_moving_part_gets_an_inertia_mujoco_accepts(built):
    """Class 2: a massless moving part in an assembly of tiny parts: its stand-in inertia is floored
    as every moving body's is (MuJoCo refuses moving bodies under 1e-15 kg*m^2)."""
    export, report = built(massless_link_tiny_parts)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    body = model.body(model.site_bodyid[model.site("SKEL").id])
    assert body.mass[0] > 0 and body.inertia.min() >= 1e-12
    assert any("SKEL" in w and "no mass" in w for w in report.warnings)
    assert model.body_mass.sum() == pytest.approx(export.mass_kg, rel=1e-12)


def test_massless_moving_skeleton_borrows_mass_so_the_total_stays_exact(built):
    """Class 5: the mass a massless moving skeleton needs is lent by the body it moves on, so the
    model's total mass is the export's exactly (a stand-in added on top was 8e-6 of it)."""
    export, report = built(massless_skeleton_moving)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.body_mass.sum() == pytest.approx(export.mass_kg, rel=1e-12)
    assert report.total_mass_kg == pytest.approx(report.export_mass_kg, rel=1e-12)
    lever = model.body(model.site_bodyid[model.site("LEVER").id]).mass[0]
    skeleton = model.body(model.site_bodyid[model.site("SKEL").id]).mass[0]
    assert skeleton > 0 and lever + skeleton == pytest.approx(0.2 + 0.01, rel=1e-12), (
        "lever and its spring pin lend it"
    )
    assert any("SKEL" in w and "taken from body LEVER" in w for w in report.warnings)


def test_planar_joint_pivot_stays_at_its_mates(built):
    """Class 3: a face mate leaves the planar joint's pivot undetermined: it is put at the mates
    (on the mated faces), not wherever rounding noise or the world origin puts it."""
    export, report = built(planar_puck)
    facts = export.facts
    (planar,) = [j for j in read(export.path).joints if j.kind == "planar"]
    assert np.linalg.norm(planar.base_frame.position - facts["contact"]) < 1e-5
    hinge = [p for p in planar.primitives if p.kind == "hinge"][0]
    assert abs(hinge.axis @ facts["normal"]) == pytest.approx(1, abs=1e-6)
    assert report.degrees_of_freedom == 2 and report.n_loop_closures == 1


def test_creo_rigid_constraints_without_geometry_weld_their_parts(built):
    """Class 4: Creo's <Rigid> constraints carry no geometry; they weld their two parts, so the
    servo sits on the base and the holder on the beam: a four-bar, one freedom, one loop."""
    export, report = built(creo_ball_beam_rigid)
    assert report.degrees_of_freedom == 1 and report.n_loop_closures == 1
    assert not any("fixed to the world" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    body = lambda site: model.site_bodyid[model.site(site).id]  # noqa: E731
    for a, b in export.facts["welded"]:
        assert body(a) == body(b)
    assert body("BASE") == 0 or model.body(body("BASE")).jntnum[0] == 0
    model, data, (drive,) = _driven(report.mjcf_path, "SERVO--HORN")
    for step in range(400):
        model.eq_data[drive, 0] = math.radians(10) * min(1.0, step / 300)
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    s, p, rod = (
        export.facts["S"],
        export.facts["P"],
        np.linalg.norm(export.facts["B"] - export.facts["A"]),
    )
    a, b = data.site("ROD").xpos, data.site("HOLDER").xpos
    assert np.linalg.norm(a - s) == pytest.approx(np.linalg.norm(export.facts["A"] - s), abs=1e-6)
    assert np.linalg.norm(b - p) == pytest.approx(np.linalg.norm(export.facts["B"] - p), abs=1e-5)
    assert np.linalg.norm(b - a) == pytest.approx(rod, abs=1e-5), (
        "the rod joins the horn to the beam"
    )
    assert np.linalg.norm(b - export.facts["B"]) > 1e-3, "the beam moved"


def test_sphere_tangent_mates_make_no_joint(built):
    """Class 6: a ball held by sphere-plane Tangent mates in a groove: Simscape makes no joint from
    them, and neither does the converter (a warning names the ball and the beam)."""
    export, report = built(ball_in_groove)
    ball, beam = export.facts["ball"], export.facts["beam"]
    assert not [
        j for j in read(export.path).joints if ball in (j.base, j.follower) and not j.synthetic
    ]
    assert (
        sum(ball in w and beam in w and "Tangent" in w and "no joint" in w for w in report.warnings)
        == 2
    )
    assert report.joints_by_type == {"hinge": 1, "slide": 0, "ball": 0, "free": 0}


@pytest.mark.slow
def test_loose_mates_to_the_assembly_origin_make_no_joints_to_the_world(built):
    """Class 7: in a 270-instance assembly every roller's axis is also mated to the assembly's Top
    Plane, which leaves it four freedoms against the world: no joint from those (one warning), so
    the swing arm and the rollers turn on their pins, no loop locks them."""
    export, report = built(conveyor_with_origin_mates)
    rollers = export.facts["rollers"]
    assert export.facts["instances"] >= 270
    assembly = read(export.path)
    assert not [
        j for j in assembly.joints if "<ground>" in (j.base, j.follower) and not j.synthetic
    ]
    assert report.joints_by_type == {"hinge": rollers + 1, "slide": 0, "ball": 0, "free": 0}
    assert report.degrees_of_freedom == rollers + 1 and report.n_loop_closures == 0
    (warning,) = [w for w in report.warnings if "assembly origin" in w]
    assert warning.startswith(f"{rollers} part(s)") and "OnTop1" in warning
    assert _settle(report.mjcf_path, export.facts["arm"], seconds=0.05) > 1e-3, (
        "the arm swings under gravity"
    )
