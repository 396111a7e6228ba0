"""Second-generation exports that carry CAD mates instead of joints (SolidWorks, Creo, Inventor):
the joints are found from the freedoms the mates leave, as Simscape's smimport does.

Hand-written exports in tests/helpers/exports.py style; each mate is written in its part's own frame,
so a wrong frame convention shows up as a wrong joint.
"""

import math

import mujoco
import numpy as np
import pytest

from mechanism.converters import convert, read
from tests.helpers.exports import (
    gen2_export,
    gen2_instance,
    gen2_mate,
    gen2_part,
    gen2_transform,
    gen2_unknown,
    mate_side,
    pin_mates,
    rotation,
)

TILT = rotation((1, 1, 0), 0.6)  # the mechanisms' plane, turned away from the world axes


def _export(
    folder,
    poses,
    masses,
    mates,
    grounded=("ground",),
    extra_parts="",
    name="mates.xml",
    constraints_extra="",
):
    parts = (
        "".join(
            gen2_part(n, f"P-{n}", masses[n], (0, 0, 0), (1e-4, 1e-4, 1e-4, 0, 0, 0)) for n in poses
        )
        + extra_parts
    )
    instances = "".join(
        gen2_instance(n, f"P-{n}", *poses[n], grounded=n in grounded) for n in poses
    )
    (folder / name).write_text(
        gen2_export(instances, "", parts, constraints="".join(mates) + constraints_extra)
    )
    return folder / name


def _joints(path):
    return {j.name: j for j in read(path).joints if not j.synthetic}


@pytest.mark.parametrize(
    "case, kind, dof",
    [
        ("pin", "revolute", 1),
        ("bore only", "cylindrical", 2),
        ("face only", "planar", 3),
        ("two faces", "prismatic", 1),
        ("ball", "spherical", 3),
        ("two pins", "weld", 0),
    ],
)
def test_mate_sets_give_the_joint_with_the_freedoms_they_leave(tmp_path, case, kind, dof):
    normal, point = TILT[:, 2], np.array([0.02, -0.01, 0.05])
    poses = {
        "ground": (np.eye(3), np.zeros(3)),
        "part": (TILT @ rotation((0, 0, 1), 0.3), np.array([0.05, 0.02, 0.01])),
    }
    g = lambda shape, name, at=point, axis=normal: mate_side(shape, name, poses[name], at, axis)
    mates = {
        "pin": pin_mates("pin", "ground", "part", poses, point, normal),
        "bore only": [
            gen2_mate("Concentric", "bore", g("cylinder", "ground"), g("circle", "part"))
        ],
        "face only": [
            gen2_mate("Coincident", "face", g("plane", "ground"), g("plane", "part", axis=-normal))
        ],
        "two faces": [
            gen2_mate("Coincident", "bottom", g("plane", "ground"), g("plane", "part")),
            gen2_mate(
                "Coincident",
                "side",
                g("plane", "ground", axis=TILT[:, 1]),
                g("plane", "part", axis=TILT[:, 1]),
            ),
        ],
        "ball": [
            gen2_mate(
                "Concentric",
                "ball",
                g("sphere", "ground", axis=None),
                g("sphere", "part", axis=None),
            )
        ],
        "two pins": pin_mates("pin", "ground", "part", poses, point, normal)
        + [
            gen2_mate(
                "Concentric",
                "dowel",
                g("cylinder", "ground", point + 0.03 * TILT[:, 0]),
                g("cylinder", "part", point + 0.03 * TILT[:, 0]),
            )
        ],
    }[case]
    path = _export(tmp_path, poses, {"ground": 1.0, "part": 0.2}, mates)
    joints = [
        j for j in read(path).joints if j.follower.endswith("part") or j.base.endswith("part")
    ]
    real = [j for j in joints if not j.synthetic]
    if kind == "weld":
        assert not real and any(j.is_weld for j in joints)
        return
    (joint,) = real
    assert joint.kind == kind and joint.dof == dof
    if kind in ("revolute", "cylindrical", "planar"):
        hinge = [p for p in joint.primitives if p.kind == "hinge"][0]
        assert abs(hinge.axis @ normal) == pytest.approx(1, abs=1e-9)
        offset = joint.base_frame.position - point
        assert np.linalg.norm(np.cross(offset, normal)) < 1e-7, "the joint sits on the mated axis"
    if kind == "prismatic":
        assert abs(joint.primitives[0].axis @ TILT[:, 0]) == pytest.approx(1, abs=1e-9)
    if kind == "spherical":
        assert joint.base_frame.position == pytest.approx(point, abs=1e-9)


def _slider_crank(folder, r=0.03, l=0.1, q0=math.radians(40)):
    """A slider-crank built only from mates, in the tilted plane, millimetre-free SI export."""
    n, ex, ey = TILT[:, 2], TILT[:, 0], TILT[:, 1]
    origin = np.array([0.1, -0.05, 0.2])
    a = origin + r * (math.cos(q0) * ex + math.sin(q0) * ey)
    b = origin + (r * math.cos(q0) + math.sqrt(l * l - (r * math.sin(q0)) ** 2)) * ex
    rod_angle = math.atan2(*((b - a) @ np.column_stack([ey, ex])))
    poses = {
        "ground": (np.eye(3), np.zeros(3)),
        "crank": (TILT @ rotation((0, 0, 1), q0), origin),
        "rod": (TILT @ rotation((0, 0, 1), rod_angle), a),
        "slider": (TILT, b),
    }
    mates = (
        pin_mates("main", "ground", "crank", poses, origin, n)
        + pin_mates("crank_pin", "crank", "rod", poses, a, n)
        + pin_mates("wrist", "rod", "slider", poses, b, n)
        + [
            gen2_mate(
                "Coincident",
                "guide_bottom",
                mate_side("plane", "ground", poses["ground"], b - 0.01 * n, n),
                mate_side("plane", "slider", poses["slider"], b - 0.01 * n, -n),
            ),
            gen2_mate(
                "Coincident",
                "guide_side",
                mate_side("plane", "ground", poses["ground"], b + 0.01 * ey, ey),
                mate_side("plane", "slider", poses["slider"], b + 0.01 * ey, -ey),
            ),
        ]
    )
    masses = {"ground": 2.0, "crank": 0.05, "rod": 0.08, "slider": 0.1}
    return _export(folder, poses, masses, mates), origin, (r, l, q0)


def test_slider_crank_from_mates_follows_its_analytic_stroke(tmp_path):
    path, origin, (r, l, q0) = _slider_crank(tmp_path)
    joints = _joints(path)
    assert sorted(j.kind for j in joints.values()) == [
        "prismatic",
        "revolute",
        "revolute",
        "revolute",
    ]
    report = convert(path, tmp_path / "out")
    assert report.degrees_of_freedom == 1 and report.n_loop_closures == 1
    spec = mujoco.MjSpec.from_file(str(report.mjcf_path))
    spec.add_equality(
        name="drive",
        type=mujoco.mjtEq.mjEQ_JOINT,
        name1="ground--crank",
        objtype=mujoco.mjtObj.mjOBJ_JOINT,
        data=[0.0] * 12,
    )
    model = spec.compile()
    data, drive = mujoco.MjData(model), model.equality("drive").id
    ex, ey = TILT[:, 0], TILT[:, 1]
    worst, turned = 0.0, []
    steps = 1000
    for step in range(steps):
        model.eq_data[drive, 0] = 2 * math.pi * step / steps
        mujoco.mj_step(model, data)
        mujoco.mj_kinematics(model, data)
        crank_x = data.site("crank").xmat.reshape(3, 3)[:, 0]
        q = math.atan2(crank_x @ ey, crank_x @ ex)
        expected = r * math.cos(q) + math.sqrt(l * l - (r * math.sin(q)) ** 2)
        worst = max(worst, abs((data.site("slider").xpos - origin) @ ex - expected))
        turned.append(q)
    assert np.ptp(np.unwrap(turned)) > 1.9 * math.pi
    assert worst < 1e-3 * r, f"slider off its analytic stroke by {worst * 1e3:.4f} mm"


def test_bearing_mated_to_two_bolted_parts_gets_a_joint_per_pair(tmp_path):
    """Face mate to one part, bore mate to a part bolted to it: as in Simscape's import, each pair
    its own joint (a planar on the face, a cylindrical in the bore) closing a loop, in which the
    bearing keeps exactly one freedom: it turns."""
    n, p = TILT[:, 2], np.array([0.0, 0.0, 0.1])
    poses = {
        "ground": (np.eye(3), np.zeros(3)),
        "cover": (TILT, p),
        "bearing": (TILT @ rotation((0, 0, 1), 1.0), p),
    }
    g = lambda shape, name, at, axis: mate_side(shape, name, poses[name], at, axis)
    mates = pin_mates("bolt", "ground", "cover", poses, p + 0.03 * TILT[:, 0], n) + [
        gen2_mate(
            "Concentric",
            "dowel",
            g("cylinder", "ground", p - 0.03 * TILT[:, 0], n),
            g("cylinder", "cover", p - 0.03 * TILT[:, 0], n),
        ),
        gen2_mate("Coincident", "seat", g("plane", "ground", p, n), g("plane", "bearing", p, -n)),
        gen2_mate(
            "Concentric", "bore", g("cylinder", "cover", p, n), g("cylinder", "bearing", p, n)
        ),
    ]
    export = _export(tmp_path, poses, {"ground": 1.0, "cover": 0.2, "bearing": 0.01}, mates)
    assert sorted(j.kind for j in _joints(export).values()) == ["cylindrical", "planar"]
    report = convert(export, tmp_path / "out")
    assert report.n_loop_closures == 1 and report.degrees_of_freedom == 1


def test_mates_to_the_assembly_origin_rigid_groups_and_rigid_subassemblies(tmp_path):
    """An empty InstancePath is the assembly origin (Onshape); instances sharing a rigidGroup are one
    body; a sub-assembly marked rigid="true" is one body even though its own mates are listed."""
    n = np.array([0.0, 0, 1])
    parts = "".join(
        gen2_part(x, f"P-{x}", m, (0, 0, 0), (1e-4, 1e-4, 1e-4, 0, 0, 0))
        for x, m in (("wheel", 0.3), ("hub", 0.1), ("a", 0.2), ("b", 0.2), ("c", 0.05))
    )
    unit = gen2_instance(
        "unit",
        "A-unit",
        None,
        (0.2, 0, 0),
        extra=' rigid="true"',
        children=gen2_instance("a", "P-a") + gen2_instance("b", "P-b", None, (0.05, 0, 0)),
    )
    instances = (
        gen2_instance("wheel", "P-wheel", None, (0, 0, 0.1), extra=' rigidGroup="root.g1"')
        + gen2_instance("hub", "P-hub", None, (0, 0, 0.12), extra=' rigidGroup="root.g1"')
        + unit
        + gen2_instance("c", "P-c", None, (0.2, 0, 0.05))
    )
    to_origin = lambda name, path, point, shape="cylinder", axis=n: gen2_mate(
        "Concentric" if shape == "cylinder" else "Coincident",
        name,
        (shape, [], point, axis),
        (shape, path, (0, 0, 0), axis),
    )
    mates = (
        to_origin("axle", ["wheel"], (0, 0, 0.1))
        + to_origin("axle_face", ["wheel"], (0, 0, 0.1), "plane")
        + to_origin("unit_pin", ["unit", "a"], (0.2, 0, 0))
        + to_origin("unit_face", ["unit", "a"], (0.2, 0, 0), "plane")
    )
    inner = gen2_mate(
        "Concentric",
        "inner",
        ("cylinder", ["a"], (0, 0, 0), n),
        ("cylinder", ["b"], (-0.05, 0, 0), n),
    )
    assemblies = (
        f'<Assembly name="unit" uid="A-unit"><Constraints>{inner}</Constraints><Joints/></Assembly>'
    )
    (tmp_path / "origin.xml").write_text(
        gen2_export(instances, "", parts, assemblies, constraints=mates)
    )
    report = convert(tmp_path / "origin.xml", tmp_path / "out")
    assert report.joints_by_type["hinge"] == 2 and report.joints_by_type["slide"] == 0
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    body = lambda site: model.site_bodyid[model.site(site).id]
    assert body("wheel") == body("hub") and body("a") == body("b") and body("wheel") != body("a")
    assert any("connected to nothing" in w and "c" in w for w in report.warnings)
    assert report.total_mass_kg == pytest.approx(0.85)


def test_unknown_and_unpositioned_constraints_are_reported(tmp_path):
    """A mate the exporter could not describe (<UnknownConstraint>, a SolidWorks lock) fixes its two
    parts, as Simscape's import does (the real Furuta export's DataFile has no joint where its Lock3
    is); a mate kind with no positional meaning for its geometry is reported and ignored."""
    poses = {
        "ground": (np.eye(3), np.zeros(3)),
        "part": (np.eye(3), np.array([0.1, 0, 0])),
        "free": (np.eye(3), np.array([0.3, 0, 0])),
    }
    unknown = gen2_unknown("Lock3", ["ground"], ["part"])
    width = gen2_mate(
        "Width",
        "Width1",
        ("plane", ["ground"], (0, 0, 0), (1, 0, 0)),
        ("plane", ["free"], (0, 0, 0), (1, 0, 0)),
    )
    report = convert(
        _export(tmp_path, poses, {"ground": 1, "part": 1, "free": 1}, [unknown, width]),
        tmp_path / "out",
    )
    assert any("Lock3" in w and "fixes" in w and "Simscape" in w for w in report.warnings)
    assert any("Width1" in w and "not supported" in w for w in report.warnings)
    assert any("connected to nothing" in w and "free" in w for w in report.warnings)
    assert not any("connected to nothing" in w and "part," in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.site_bodyid[model.site("part").id] == model.site_bodyid[model.site("ground").id]


def test_plane_or_axis_exported_without_its_direction_is_reported_not_a_crash(tmp_path):
    """A plane or a bore written without its <Axis> constrains nothing this reader can know: the mate
    is reported and ignored, the others still make their joint (the residuals crossed None with the
    other side's axis: numpy's 'At least one array has zero dimension' ended the conversion)."""
    z = np.array([0.0, 0, 1])
    poses = {"ground": (np.eye(3), np.zeros(3)), "part": (np.eye(3), np.array([0.1, 0, 0]))}
    pin = pin_mates("pin", "ground", "part", poses, poses["part"][1], z)
    blind_face = gen2_mate(
        "Coincident",
        "BlindFace",
        ("plane", ["ground"], (0.1, 0, 0), None),
        ("plane", ["part"], (0, 0, 0), (0, 0, 1)),
    )
    blind_bore = gen2_mate(
        "Concentric",
        "BlindBore",
        ("cylinder", ["ground"], (0.1, 0, 0), (0, 0, 1)),
        ("cylinder", ["part"], (0, 0, 0), None),
    )
    export = _export(tmp_path, poses, {"ground": 1.0, "part": 0.2}, pin + [blind_face, blind_bore])
    report = convert(export, tmp_path / "out")
    assert any("BlindFace" in w and "no positional meaning" in w for w in report.warnings)
    assert any("BlindBore" in w and "no positional meaning" in w for w in report.warnings)
    assert [j.kind for j in _joints(export).values()] == ["revolute"]


def _gear_train(folder, relation):
    """Two shafts on revolutes (mates to the ground) and a gear relation between them."""
    z = np.array([0.0, 0, 1])
    poses = {
        "ground": (np.eye(3), np.zeros(3)),
        "pinion": (np.eye(3), np.array([0.0, 0, 0.01])),
        "wheel": (rotation((0, 0, 1), 0.4), np.array([0.06, 0, 0.01])),
    }
    mates = pin_mates("p", "ground", "pinion", poses, poses["pinion"][1], z) + pin_mates(
        "w", "ground", "wheel", poses, poses["wheel"][1], z
    )
    parts = "".join(
        gen2_part(n, f"P-{n}", m, (0, 0, 0), (i, i, i, 0, 0, 0))
        for n, m, i in (("ground", 1.0, 1e-3), ("pinion", 0.05, 1e-5), ("wheel", 0.2, 1e-4))
    )
    instances = "".join(
        gen2_instance(n, f"P-{n}", *poses[n], grounded=n == "ground") for n in poses
    )
    (folder / "gears.xml").write_text(
        gen2_export(instances, "", parts, constraints="".join(mates) + relation)
    )
    return folder / "gears.xml"


def test_gear_constraint_becomes_a_coupling_with_the_stated_radii(tmp_path):
    frame = lambda uid, x: (
        f"<InstancePath><Uid>{uid}</Uid></InstancePath>{gen2_transform(None, (0, 0, 0))}"
    )
    relation = (
        f'<CommonGearConstraint name="mesh"><BaseFrame>{frame("pinion", 0)}</BaseFrame>'
        f"<FollowerFrame>{frame('wheel', 0)}</FollowerFrame><BaseRadius>0.02</BaseRadius>"
        f"<FollowerRadius>0.04</FollowerRadius></CommonGearConstraint>"
    )
    report = convert(_gear_train(tmp_path, relation), tmp_path / "out")
    assert report.n_couplings == 1 and report.degrees_of_freedom == 1
    assert any("mesh" in w and "external gear" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    data = mujoco.MjData(model)
    pinion, wheel = model.joint("ground--pinion"), model.joint("ground--wheel")
    for _ in range(400):
        data.qfrc_applied[pinion.dofadr[0]] = 0.01
        mujoco.mj_step(model, data)
    turned_pinion, turned_wheel = data.qpos[pinion.qposadr[0]], data.qpos[wheel.qposadr[0]]
    assert abs(turned_pinion) > 0.05
    # external gears: the wheel (twice the radius) turns half as far, the other way
    assert turned_wheel == pytest.approx(-0.5 * turned_pinion, rel=1e-3)


def test_gear_without_a_ratio_is_reported_not_guessed(tmp_path):
    relation = gen2_mate(
        "Gear",
        "GearMate1",
        ("cylinder", ["pinion"], (0, 0, 0), (0, 0, 1)),
        ("cylinder", ["wheel"], (0, 0, 0), (0, 0, 1)),
    )
    report = convert(_gear_train(tmp_path, relation), tmp_path / "out")
    assert report.n_couplings == 0 and report.degrees_of_freedom == 2
    assert any("GearMate1" in w and "no ratio" in w and "side-car" in w for w in report.warnings)


def test_joint_naming_a_missing_instance_is_skipped_with_a_warning(tmp_path):
    """Onshape writes joints of suppressed parts; one such joint must not sink the whole file."""
    from tests.helpers.exports import gen2_joint

    parts = "".join(
        gen2_part(n, f"P-{n}", 1.0, (0, 0, 0), (0.01, 0.01, 0.01, 0, 0, 0)) for n in ("base", "arm")
    )
    instances = gen2_instance("base", "P-base", grounded=True) + gen2_instance(
        "arm", "P-arm", None, (0.1, 0, 0)
    )
    joints = gen2_joint(
        "Revolute",
        "shoulder",
        ["base"],
        gen2_transform(None, (0.1, 0, 0)),
        ["arm"],
        gen2_transform(),
    ) + gen2_joint("Revolute", "ghost", ["arm"], gen2_transform(), ["deleted"], gen2_transform())
    (tmp_path / "ghost.xml").write_text(gen2_export(instances, joints, parts))
    report = convert(tmp_path / "ghost.xml", tmp_path / "out")
    assert report.joints_by_type["hinge"] == 1
    assert any("ghost" in w and "deleted" in w and "ignored" in w for w in report.warnings)


def test_second_generation_inches_and_slugs(tmp_path):
    """DataUnits in inches and slugs (an Inventor/SolidWorks US-customary export): positions,
    masses and inertias (slug*in^2) come out in SI."""
    inch, slug = 0.0254, 14.593902937206364
    parts = gen2_part("base", "P-base", 1.0, (0, 0, 0), (1, 1, 1, 0, 0, 0)) + gen2_part(
        "arm", "P-arm", 0.5, (2.0, 0, 0), (0.1, 0.4, 0.45, 0, 0, 0.02)
    )
    instances = gen2_instance("base", "P-base", grounded=True) + gen2_instance(
        "arm", "P-arm", None, (0, 0, 3.0)
    )
    mates = pin_mates(
        "pivot",
        "ground",
        "part",
        {"ground": (np.eye(3), np.zeros(3)), "part": (np.eye(3), np.array([0, 0, 3.0]))},
        np.array([0, 0, 3.0]),
        np.array([0, 0, 1.0]),
    )
    mates = [
        m.replace("<Uid>ground</Uid>", "<Uid>base</Uid>").replace(
            "<Uid>part</Uid>", "<Uid>arm</Uid>"
        )
        for m in mates
    ]
    (tmp_path / "us.xml").write_text(
        gen2_export(instances, "", parts, length="inch", mass="slug", constraints="".join(mates))
    )
    assembly = read(tmp_path / "us.xml")
    arm = next(p for p in assembly.parts.values() if p.name == "arm")
    assert arm.mass == pytest.approx(0.5 * slug)
    assert arm.com == pytest.approx([2.0 * inch, 0, 3.0 * inch])
    assert arm.inertia[0, 0] == pytest.approx(0.1 * slug * inch**2) and arm.inertia[
        0, 1
    ] == pytest.approx(0.02 * slug * inch**2)
    (pivot,) = [j for j in assembly.joints if not j.synthetic]
    assert pivot.kind == "revolute" and pivot.base_frame.position == pytest.approx(
        [0, 0, 3.0 * inch]
    )


def test_planar_pivot_is_the_mates_centre_whatever_the_rounding_noise():
    """Issue 14 class 3: a face mate leaves a planar joint's pivot free in the plane; with the axes
    carrying 1e-7 of rounding noise (exports print 6 to 9 digits) the pivot stays at the mated
    faces, within a micrometre, for any orientation (the least-squares centre put it up to 0.3 m off)."""
    from mechanism.converters.mates import MateGeometry, freedoms

    rng = np.random.default_rng(0)
    for _ in range(50):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        point = rng.normal(size=3) * 0.1
        noisy = lambda v: (v + rng.normal(size=3) * 1e-7) / np.linalg.norm(v)  # noqa: E731
        found = freedoms(
            [
                (
                    "coincident",
                    MateGeometry("a", "plane", point, noisy(normal)),
                    MateGeometry("b", "plane", point + rng.normal(size=3) * 1e-7, -noisy(normal)),
                )
            ]
        )
        assert found.kind == "planar"
        assert np.linalg.norm(found.anchor - point) < 1e-6


def test_mates_naming_the_root_assembly_tie_a_part_to_its_origin(tmp_path):
    """SolidWorks writes mates to the assembly origin with an InstancePath holding the root
    assembly's own uid: three plane coincidences with it fix the base to the world (before, they
    were ignored as naming no instance, and the base was fixed only by the fallback), and a
    revolute pair to the origin turns as Simscape's import makes it."""
    poses = {
        "base": (np.eye(3), np.array([0.1, 0.2, 0.0])),
        "arm": (rotation((0, 0, 1), 0.4), np.array([0.1, 0.2, 0.05])),
    }
    mates = [
        gen2_mate(
            "Coincident",
            f"origin_{i}",
            mate_side("plane", "base", poses["base"], poses["base"][1], axis),
            ("plane", ["root"], poses["base"][1], axis),
        )
        for i, axis in enumerate(np.eye(3))
    ]
    mates += pin_mates("pin", "base", "arm", poses, poses["arm"][1], (0, 0, 1))
    # ["root"]: the uid gen2_export gives the root assembly
    export = _export(tmp_path, poses, {"base": 1.0, "arm": 0.2}, mates, grounded=())
    report = convert(export, tmp_path / "out")
    assert not any(
        "not an instance" in w or "not connected to the ground" in w for w in report.warnings
    ), report.warnings
    assert report.degrees_of_freedom == 1 and report.joints_by_type["hinge"] == 1
    assembly = read(export)
    from mechanism.converters.assembly import GROUND

    assert any(j.kind == "weld" and GROUND in (j.base, j.follower) for j in assembly.joints)
