"""The converter on real exports (LEGS, youBot) and on small hand-written ones."""

import json
import math
import time

import mujoco
import numpy as np
import pytest

from mechanism.converters import convert, read
from mechanism.converters.errors import ExportError
from tests.helpers.exports import (
    FourBar,
    Gen1Export,
    bar_inertia,
    box_stl,
    gen2_export,
    gen2_joint,
    gen2_part,
    gen2_transform,
    rotation,
)

LEGS = "cad-exports/legs-creo-firstgen/LEGS_MECHANISM.xml"
YOUBOT = "cad-exports/youbot-onshape/youBot.xml"


def _xml_masses(path, tag="mass"):
    import re

    return [float(v) for v in re.findall(rf"<{tag}>([^<]+)</{tag}>", path.read_text())]


# -- LEGS: a real first-generation export without its meshes ---------------------------------


@pytest.fixture(scope="module")
def legs(tmp_path_factory):
    from tests.conftest import shared_dir

    shared = shared_dir()
    if shared is None:
        pytest.skip("shared folder with the CAD export fixtures is not present")
    out = tmp_path_factory.mktemp("legs")
    return shared / LEGS, convert(shared / LEGS, out)


def test_legs_converts_with_missing_meshes_and_keeps_the_mass(legs):
    source, report = legs
    assert any(
        "geometry file(s) are missing" in w and "equivalent-inertia boxes" in w
        for w in report.warnings
    )
    stated = sum(_xml_masses(source))  # every Body's <mass> is in kg in this file
    assert report.total_mass_kg == pytest.approx(stated, rel=0.005)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.body_mass.sum() == pytest.approx(stated, rel=0.005)
    assert mujoco.mjtJoint.mjJNT_FREE not in set(model.jnt_type)


def test_legs_every_revolute_joint_is_a_hinge_or_a_loop_closure(legs):
    source, report = legs
    assembly = read(source)
    revolute = [j.name for j in assembly.joints if j.kind == "revolute"]
    assert len(revolute) == 15
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    hinges = {
        model.joint(i).name
        for i in range(model.njnt)
        if model.jnt_type[i] == mujoco.mjtJoint.mjJNT_HINGE
    }
    loops = {
        model.equality(i).name.split(":")[1]
        for i in range(model.neq)
        if model.equality(i).name.startswith("loop:")
    }
    assert set(revolute) == hinges | loops and not hinges & loops
    assert report.n_loop_closures == 1  # the left leg's RootPart is welded to both hip and ankle


def test_legs_repairs_the_mirrored_legs_inertias_and_names_each_part(legs):
    _, report = legs
    repaired = {
        w.split(":")[0].removeprefix("part ") for w in report.warnings if "inertia tensor" in w
    }
    assert repaired == {
        f"SIM_SEA_L_{n}"
        for n in ("HIP_1", "HIP_2", "UPPER_THIGH", "THIGH", "SHANK", "ANKLE", "FOOT", "SOLE")
    }
    assert any("cannot move" in w and "SIM_SEA_L_" in w for w in report.warnings), (
        "the over-constrained leg is reported"
    )


def test_legs_inertia_is_read_in_the_cg_frame_axes(legs):
    """The 1 kg weights are discs stacked in pairs; each disc's axis (largest moment) must point
    along its stacking direction, which holds only if CG orientations are read column by column."""
    source, _ = legs
    parts = {p.name: p for p in read(source).parts.values()}
    for first, second in (
        ("WEIGHT-1KG", "WEIGHT-1KG-1"),
        ("WEIGHT-1KG-2", "WEIGHT-1KG-3"),
        ("WEIGHT-1KG-4", "WEIGHT-1KG-5"),
    ):
        stack = parts[second].com - parts[first].com
        moments, axes = np.linalg.eigh(parts[first].inertia)
        assert abs(axes[:, 2] @ stack) / np.linalg.norm(stack) > 0.999


def test_legs_named_frames_become_sites_with_unique_names(legs):
    _, report = legs
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    sites = [model.site(i).name for i in range(model.nsite)]
    assert len(sites) == len(set(sites))
    assert {"SCSYS_R_SOLE", "SCSYS_L_SOLE", "SCSYS_MTX_ACCEL", "SIM_SEA_R_THIGH"} <= set(sites)
    assert "SCSYS_EMS_ACCEL_2" in sites  # the same display name on several parts


# -- youBot: a real second-generation export with STEP geometry ------------------------------


@pytest.mark.slow
def test_youbot_cli_conversion_meets_the_acceptance(shared, tmp_path, cli):
    source = shared / YOUBOT
    started = time.perf_counter()
    result = cli("convert", source, "-o", tmp_path / "youbot", timeout=600)
    print(f"youBot conversion took {time.perf_counter() - started:.1f} s")  # measured, not asserted
    assert result.returncode == 0, result.stderr
    assert "joints: 7 (5 hinge, 2 slide)" in result.stdout
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "youbot" / "youBot.xml"))
    types = list(model.jnt_type)
    assert (
        types.count(mujoco.mjtJoint.mjJNT_HINGE) == 5
        and types.count(mujoco.mjtJoint.mjJNT_SLIDE) == 2
    )
    assert mujoco.mjtJoint.mjJNT_FREE not in types and len(types) == 7
    stated = sum(_xml_masses(source, "Mass"))
    assert len(_xml_masses(source, "Mass")) == 25
    assert model.body_mass.sum() == pytest.approx(stated, rel=0.005)
    visual_meshes = [
        i
        for i in range(model.ngeom)
        if model.geom_type[i] == mujoco.mjtGeom.mjGEOM_MESH
        and model.geom(i).name.endswith("_visual")
    ]
    assert len(visual_meshes) == 25
    assert all(model.mesh_vertnum[model.geom_dataid[i]] > 0 for i in visual_meshes)
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data)  # it simulates


def test_reading_step_geometry_shows_its_progress_and_judges_convexity_in_the_workers(
    shared, monkeypatch
):
    """An export of many STEP parts reads for seconds (the youBot's 25: 8-11 s on 2 cores): a
    bar (tqdm, shown on a terminal) counts every file to the end, and the convexity of each mesh
    is judged in the worker that read it, the same verdict as in the main process."""
    import tqdm

    from mechanism.converters import geometry

    seen = []

    class Recorder(tqdm.tqdm):
        def __init__(self, *args, **kwargs):
            kwargs.update(disable=False)
            super().__init__(*args, **kwargs)
            seen.append(self)

    monkeypatch.setattr(tqdm, "tqdm", Recorder)
    folder = (shared / YOUBOT).parent
    paths = [folder / name for name in ("Pin Housing C2.step", "Forearm Black Inlay.step")]
    found = geometry._read_in_workers(paths)
    assert len(seen) == 1 and seen[0].total == len(paths) and seen[0].n == len(paths)
    for path in paths:
        vertices, faces, carries_units, convex = found[path]
        assert carries_units and convex == geometry.is_convex(vertices, faces)


def test_youbot_joint_frames_meet_at_the_assembly_pose(shared):
    """Base and follower frames of every joint coincide (to the export's 0.2 mm gaps) with aligned z axes."""
    assembly = read(shared / YOUBOT)
    moving = [j for j in assembly.joints if not j.is_weld]
    assert sorted(j.kind for j in moving) == ["prismatic"] * 2 + ["revolute"] * 5
    for joint in moving:
        assert np.linalg.norm(joint.base_frame.position - joint.follower_frame.position) < 3e-4
        assert joint.base_frame.rotation[:, 2] @ joint.follower_frame.rotation[:, 2] > 0.9999


# -- hand-written exports ----------------------------------------------------------------------


def test_four_bar_conversion_is_byte_for_byte_deterministic(tmp_path):
    source = FourBar().export(tmp_path)
    first = convert(source, tmp_path / "a")
    second = convert(source, tmp_path / "b")
    assert first.mjcf_path.read_bytes() == second.mjcf_path.read_bytes()
    names = sorted(p.name for p in first.mesh_dir.iterdir())
    assert (
        names
        == sorted(p.name for p in second.mesh_dir.iterdir())
        == ["coupler.stl", "crank.stl", "frame.stl", "rocker.stl"]
    )
    for name in names:
        assert (first.mesh_dir / name).read_bytes() == (second.mesh_dir / name).read_bytes()


def test_stl_in_millimetres_is_scaled_to_metres_and_placed_at_the_part_frame(tmp_path):
    fourbar = FourBar()
    report = convert(fourbar.export(tmp_path), tmp_path / "out")
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom = model.geom("crank")
    mesh = geom.dataid[0]
    vertices = model.mesh_vert[
        model.mesh_vertadr[mesh] : model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]
    ]
    world = data.geom("crank").xpos + vertices @ data.geom("crank").xmat.reshape(3, 3).T
    start, end = data.site("crank_start").xpos, data.site("crank_end").xpos
    along = (world - start) @ (end - start) / np.linalg.norm(end - start)
    assert along.min() == pytest.approx(0, abs=1e-6) and along.max() == pytest.approx(
        fourbar.crank / 1000, abs=1e-6
    )
    assert model.geom("crank").contype[0] == 1, "a box is convex: it collides"
    assert model.geom("crank_visual").contype[0] == 0 and model.geom("crank_visual").group[0] == 1


def test_meshes_can_live_in_another_folder(tmp_path):
    report = convert(
        FourBar().export(tmp_path),
        tmp_path / "assets" / "mjcf",
        name="bars",
        mesh_dir=tmp_path / "assets" / "meshes",
    )
    assert report.mjcf_path == tmp_path / "assets" / "mjcf" / "bars.xml"
    assert 'meshdir="../meshes"' in report.mjcf_path.read_text()
    assert (tmp_path / "assets" / "meshes" / "crank.stl").exists()
    assert not (tmp_path / "assets" / "mjcf" / "meshes").exists()
    mujoco.MjModel.from_xml_path(str(report.mjcf_path))


def _two_shafts(folder, sidecar=None, motor_inertia=2e3, arm_inertia=5e4):
    """Two shafts on parallel hinges, a belt side-car couples them."""
    doc = Gen1Export()
    base = doc.body("base", 1000, (0, 0, -50), np.diag([1e6] * 3))
    doc.weld_to_ground(base)
    motor = doc.body("motor_rotor", 100, (0, 0, 0), np.diag([motor_inertia] * 3))
    arm = doc.body("arm_shaft", 300, (80, 0, 0), np.diag([arm_inertia] * 3))
    doc.joint("motor", base, motor, (0, 0, 0), [("revolute", (0, 0, 1))])
    doc.joint("arm shaft", base, arm, (80, 0, 0), [("revolute", (0, 0, 1))])
    path = doc.write(folder / "shafts.xml")
    if sidecar is not None:
        (folder / "shafts.couplings.json").write_text(json.dumps(sidecar))
    return path


def _belt(**changes):
    entry = {
        "name": "motor belt",
        "kind": "belt",
        "input": "motor",
        "output": "arm shaft",
        "ratio": 8.0,
    }
    entry.update(changes)
    return {"format": "mechanism-couplings/1", "couplings": [entry]}


def test_belt_coupling_holds_the_ratio_and_reflects_the_motor_inertia(tmp_path):
    report = convert(_two_shafts(tmp_path, _belt()), tmp_path / "out")
    assert report.n_couplings == 1 and report.degrees_of_freedom == 1
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.equality("coupling:motor_belt").type == mujoco.mjtEq.mjEQ_JOINT
    data = mujoco.MjData(model)
    torque = 0.01  # N*m on the motor shaft
    motor = model.joint("motor").dofadr[0]
    for _ in range(1000):
        data.qfrc_applied[motor] = torque
        mujoco.mj_step(model, data)
    q_motor, q_arm = (
        data.qpos[model.joint("motor").qposadr[0]],
        data.qpos[model.joint("arm_shaft").qposadr[0]],
    )
    assert q_motor == pytest.approx(8.0 * q_arm, rel=1e-3)
    # ideal belt: the arm sees 8x the torque and 64x the motor inertia
    i_motor, i_arm = 2e3 * 1e-9, 5e4 * 1e-9  # g*mm^2 -> kg*m^2
    t = 1000 * model.opt.timestep
    expected = 0.5 * 8 * torque / (i_arm + 64 * i_motor) * t**2
    assert q_arm == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize(
    "sidecar, message",
    [
        (
            _belt(input="motr"),
            "input joint 'motr' does not exist in the export (did you mean motor",
        ),
        (_belt(ratio="eight"), "'ratio' must be a number, got \"eight\""),
        (_belt(ratio=0), "'ratio' must not be zero"),
        ({"couplings": []}, 'expected a JSON object with "format"'),
    ],
)
def test_bad_couplings_sidecar_is_an_error_naming_the_problem(tmp_path, sidecar, message):
    with pytest.raises(ExportError, match=None) as info:
        read(_two_shafts(tmp_path, sidecar))
    assert message in str(info.value)


def test_sanitised_joint_names_are_accepted_in_the_sidecar(tmp_path):
    assembly = read(_two_shafts(tmp_path, _belt(output="arm_shaft", offset_deg=90)))
    coupling = assembly.couplings[0]
    assert coupling.output == "arm shaft" and coupling.offset == pytest.approx(math.pi / 2)


def test_unconnected_part_is_fixed_to_the_world_with_a_warning(tmp_path):
    doc = Gen1Export()
    base = doc.body("base", 1000, (0, 0, 0), np.diag([1e6] * 3))
    doc.weld_to_ground(base)
    doc.body("loose bolt", 5, (10, 0, 0), np.diag([10.0] * 3))
    report = convert(doc.write(tmp_path / "loose.xml"), tmp_path / "out")
    assert any("loose bolt" in w and "fixed to the world" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.njnt == 0 and model.nbody == 3


def test_massless_moving_part_gets_a_small_mass_with_a_warning(tmp_path):
    doc = Gen1Export()
    base = doc.body("base", 1000, (0, 0, 0), np.diag([1e6] * 3))
    doc.weld_to_ground(base)
    lever = doc.body("lever", 0, (10, 0, 0), np.zeros((3, 3)))
    doc.joint("pivot", base, lever, (0, 0, 0), [("revolute", (0, 0, 1))])
    report = convert(doc.write(tmp_path / "lever.xml"), tmp_path / "out")
    assert any("lever" in w and "no mass" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert 0 < model.body("lever").mass[0] < 0.01


def test_missing_geometry_becomes_an_equivalent_inertia_box(tmp_path):
    doc = Gen1Export()
    base = doc.body("base", 1000, (0, 0, 0), np.diag([1e6] * 3))
    doc.weld_to_ground(base)
    mass, size = 240.0, np.array([40.0, 20.0, 10.0])  # g, mm
    tilt = rotation((1, 1, 0), 0.4)
    doc.body(
        "block", mass, (5, 5, 5), bar_inertia(mass, *size), cg_rotation=tilt, geometry="block.stl"
    )
    doc.joint("slide", base, doc.bodies[-1], (5, 5, 5), [("prismatic", (1, 0, 0))])
    report = convert(doc.write(tmp_path / "block.xml"), tmp_path / "out")
    assert any("block.stl" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    geom = model.geom("block_visual")
    assert geom.type[0] == mujoco.mjtGeom.mjGEOM_BOX
    assert sorted(2 * geom.size) == pytest.approx(sorted(size / 1000), rel=1e-6)


def test_non_convex_part_is_marked_for_exact_distance(tmp_path):
    import trimesh

    doc = Gen1Export()
    base = doc.body("base", 1000, (0, 0, 0), np.diag([1e6] * 3), geometry="base.stl")
    doc.weld_to_ground(base)
    box_stl(tmp_path / "base.stl", (-10, -10, -10), (10, 10, 10))
    ring = trimesh.creation.annulus(r_min=8, r_max=12, height=4)  # mm, not convex
    ring.export(tmp_path / "ring.stl")
    doc.body(
        "ring",
        50,
        (0, 0, 30),
        np.diag([3e3, 3e3, 5e3]),
        part_origin_mm=(0, 0, 30),
        geometry="ring.stl",
    )
    doc.joint("spin", base, doc.bodies[-1], (0, 0, 30), [("revolute", (0, 0, 1))])
    report = convert(doc.write(tmp_path / "ring.xml"), tmp_path / "out")
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    ring_geom, base_geom = model.geom("ring"), model.geom("base")
    assert ring_geom.contype[0] == 0 and ring_geom.conaffinity[0] == 0 and ring_geom.group[0] == 3
    assert base_geom.contype[0] == 1
    mesh = ring_geom.dataid[0]
    assert model.mesh_facenum[mesh] == len(ring.faces), "the exported triangles are kept"


def test_path_traversal_in_a_geometry_name_is_refused(tmp_path):
    doc = Gen1Export()
    base = doc.body("base", 1000, (0, 0, 0), np.diag([1e6] * 3), geometry="../../etc/passwd")
    doc.weld_to_ground(base)
    with pytest.raises(ExportError, match="points outside the export folder"):
        read(doc.write(tmp_path / "evil.xml"))


# -- second generation: nested sub-assemblies, units, inertia order ---------------------------


def _gen2_with_subassemblies(folder):
    """Root: a grounded base; a rigid two-part sub-assembly on a revolute; a flexible
    sub-assembly (its own slide joint, one part grounded inside it) on a second revolute.
    Data in millimetres and grams; instance rotations are not identities."""
    turn = rotation((0, 0, 1), math.pi / 2)
    tilt = rotation((1, 0, 0), math.pi / 2)
    parts = "".join(
        [
            gen2_part("Base", "P-base", 2000, (0, 0, -10), (4e6, 4e6, 4e6, 0, 0, 0)),
            gen2_part("Housing", "P-housing", 300, (0, 0, 0), (1e5, 2e5, 3e5, 0, 0, 0)),
            gen2_part("Cover", "P-cover", 100, (10, 0, 0), (2e4, 2e4, 2e4, 0, 0, 0)),
            gen2_part("Carriage", "P-carriage", 50, (0, 0, 0), (1e4, 1e4, 1e4, 0, 0, 0)),
            gen2_part("Slider", "P-slider", 20, (0, 5, 0), (4e3, 1e3, 4e3, 100, 200, 300)),
        ]
    )
    rigid = (
        f'<Instance entityUid="A-rigid" name="Motor &lt;1&gt;" uid="I-motor">{gen2_transform(turn, (100, 0, 0))}'
        f'<Instance entityUid="P-housing" name="Housing &lt;1&gt;" uid="I-housing">{gen2_transform(None, (0, 0, 0))}</Instance>'
        f'<Instance entityUid="P-cover" name="Cover &lt;1&gt;" uid="I-cover">{gen2_transform(None, (0, 0, 20))}</Instance>'
        "</Instance>"
    )
    flexible = (
        f'<Instance entityUid="A-flex" name="Slide unit &lt;1&gt;" uid="I-unit">{gen2_transform(tilt, (0, 100, 0))}'
        f'<Instance entityUid="P-carriage" grounded="true" name="Carriage &lt;1&gt;" uid="I-carriage">{gen2_transform()}</Instance>'
        f'<Instance entityUid="P-slider" name="Slider &lt;1&gt;" uid="I-slider">{gen2_transform(None, (0, 0, 5))}</Instance>'
        "</Instance>"
    )
    instances = (
        f'<Instance entityUid="P-base" grounded="true" name="Base &lt;1&gt;" uid="I-base">{gen2_transform()}</Instance>'
        + rigid
        + flexible
    )
    joints = gen2_joint(
        "Revolute",
        "motor_axis",
        ["I-base"],
        gen2_transform(None, (100, 0, 0)),
        ["I-motor", "I-housing"],
        gen2_transform(),
    ) + gen2_joint(
        "Revolute",
        "unit_axis",
        ["I-base"],
        gen2_transform(None, (0, 100, 0)),
        ["I-unit", "I-carriage"],
        gen2_transform(tilt.T),
    )
    assemblies = (
        '<Assembly name="Motor" uid="A-rigid"><Joints/><Constraints/></Assembly>'
        '<Assembly name="Slide unit" uid="A-flex"><Constraints/><Joints>'
        + gen2_joint(
            "Prismatic",
            "slide",
            ["I-carriage"],
            gen2_transform(),
            ["I-slider"],
            gen2_transform(None, (0, 0, -5)),
        )
        + "</Joints></Assembly>"
    )
    text = gen2_export(instances, joints, parts, assemblies, length="millimeter", mass="gram")
    (folder / "nested.xml").write_text(text)
    return folder / "nested.xml"


def test_gen2_nested_subassemblies_become_the_right_bodies_and_joints(tmp_path):
    report = convert(_gen2_with_subassemblies(tmp_path), tmp_path / "out")
    assert report.joints_by_type == {"hinge": 2, "slide": 1, "ball": 0, "free": 0}
    assert report.n_bodies == 4  # base; motor (housing + cover); slide unit (carriage); slider
    assert report.total_mass_kg == pytest.approx(2.47)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert model.site_bodyid[model.site("Housing").id] == model.site_bodyid[model.site("Cover").id]
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # the flexible unit is tilted 90 degrees about x: its slide runs along world -y... its z axis maps to -y
    slide_axis = data.xaxis[model.joint("slide").id]
    assert slide_axis == pytest.approx([0, -1, 0], abs=1e-9)
    # rigid sub-assembly at x = 100 mm: the cover's frame, 20 mm up inside it
    assert data.site("Cover").xpos == pytest.approx([0.1, 0.0, 0.02], abs=1e-12)


def test_gen2_inertia_order_and_units(tmp_path):
    assembly = read(_gen2_with_subassemblies(tmp_path))
    slider = next(p for p in assembly.parts.values() if p.name == "Slider")
    tilt = rotation((1, 0, 0), math.pi / 2)
    # g*mm^2 -> kg*m^2
    ixx, iyy, izz, iyz, izx, ixy = np.array([4e3, 1e3, 4e3, 100, 200, 300]) * 1e-9
    local = np.array([[ixx, ixy, izx], [ixy, iyy, iyz], [izx, iyz, izz]])
    assert slider.inertia == pytest.approx(tilt @ local @ tilt.T, abs=1e-18)
    assert slider.mass == pytest.approx(0.02)
    assert slider.com == pytest.approx(np.array([0, 0.1, 0]) + tilt @ np.array([0, 0.005, 0.005]))
    cover = next(p for p in assembly.parts.values() if p.name == "Cover")
    assert cover.com == pytest.approx([0.1, 0.01, 0.02])  # (10, 0, 0) mm turned 90 degrees about z


def test_gen2_compound_joints_get_suffixed_names_and_6dof_to_ground_is_free(tmp_path):
    parts = "".join(
        gen2_part(n, f"P-{n}", 1.0, (0, 0, 0), (0.01, 0.01, 0.01, 0, 0, 0))
        for n in ("base", "a", "b", "c", "d")
    )
    grounded = ' grounded="true"'
    instances = "".join(
        f'<Instance entityUid="P-{n}"{grounded if n == "base" else ""} name="{n} &lt;1&gt;" uid="I-{n}">'
        f"{gen2_transform(None, (i * 0.1, 0, 0))}</Instance>"
        for i, n in enumerate(("base", "a", "b", "c", "d"))
    )
    joints = (
        gen2_joint(
            "Planar",
            "table",
            ["I-base"],
            gen2_transform(None, (0.1, 0, 0)),
            ["I-a"],
            gen2_transform(),
        )
        + gen2_joint(
            "Universal",
            "cardan",
            ["I-a"],
            gen2_transform(None, (0.1, 0, 0)),
            ["I-b"],
            gen2_transform(),
        )
        + gen2_joint(
            "SixDOF",
            "floating",
            ["I-base"],
            gen2_transform(None, (0.3, 0, 0)),
            ["I-c"],
            gen2_transform(),
        )
        + gen2_joint(
            "Bushing",
            "mount",
            ["I-c"],
            gen2_transform(None, (0.1, 0, 0)),
            ["I-d"],
            gen2_transform(),
        )
    )
    (tmp_path / "compound.xml").write_text(gen2_export(instances, joints, parts))
    report = convert(tmp_path / "compound.xml", tmp_path / "out")
    assert any("mount" in w and "stiffness" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    names = [model.joint(i).name for i in range(model.njnt)]
    assert names[:5] == [
        "table_slide1",
        "table_slide2",
        "table_hinge",
        "cardan_hinge1",
        "cardan_hinge2",
    ]
    assert "floating" in names and model.joint("floating").type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert [n for n in names if n.startswith("mount")] == [
        "mount_slide1",
        "mount_slide2",
        "mount_slide3",
        "mount_hinge1",
        "mount_hinge2",
        "mount_hinge3",
    ]
    assert report.degrees_of_freedom == 3 + 2 + 6 + 6


def test_gen2_stl_written_in_millimetres_is_detected_by_its_mass_properties(tmp_path):
    # mm, well away from the part origin
    box_stl(tmp_path / "block.stl", (100, 0, 0), (140, 20, 10))
    parts = gen2_part("base", "P-base", 1.0, (0, 0, 0), (0.01, 0.01, 0.01, 0, 0, 0)) + gen2_part(
        "block",
        "P-block",
        0.063,
        (0.12, 0.01, 0.005),
        (1e-6, 1e-6, 1e-6, 0, 0, 0),
        geometry="block.stl",
    )
    instances = (
        '<Instance entityUid="P-base" grounded="true" name="base" uid="I-base">'
        + gen2_transform()
        + "</Instance>"
        '<Instance entityUid="P-block" name="block" uid="I-block">'
        + gen2_transform()
        + "</Instance>"
    )
    joints = gen2_joint(
        "Revolute", "hinge", ["I-base"], gen2_transform(), ["I-block"], gen2_transform()
    )
    (tmp_path / "units.xml").write_text(gen2_export(instances, joints, parts))
    report = convert(tmp_path / "units.xml", tmp_path / "out")
    assert any("block.stl" in w and "read in mm" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    mesh = model.geom("block").dataid[0]
    vertices = model.mesh_vert[
        model.mesh_vertadr[mesh] : model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]
    ]
    world = data.geom("block").xpos + vertices @ data.geom("block").xmat.reshape(3, 3).T
    assert world.min(axis=0) == pytest.approx([0.1, 0, 0], abs=1e-7)
    assert world.max(axis=0) == pytest.approx([0.14, 0.02, 0.01], abs=1e-7)


def test_units_of_first_generation_exports():
    from mechanism.converters.units import inertia_factor, length_factor, mass_factor, volume_factor

    assert length_factor('"in"', "t") == 0.0254 and length_factor("millimeter", "t") == 1e-3
    assert mass_factor("lbm", "t") == pytest.approx(0.45359237) and mass_factor(
        "pound", "t"
    ) == mass_factor("lbm", "t")
    assert inertia_factor("g*mm^2", "t") == pytest.approx(1e-9)
    assert inertia_factor("lbm*in^2", "t") == pytest.approx(0.45359237 * 0.0254**2)
    assert inertia_factor("slug*ft^2", "t") == pytest.approx(14.593902937 * 0.3048**2)
    assert inertia_factor("lbm*in*in", "t") == inertia_factor("lbm*in^2", "t")
    assert volume_factor("mm^3", "t") == pytest.approx(1e-9)
    with pytest.raises(ExportError, match="unknown inertia unit"):
        inertia_factor("kg*m", "t")
