"""Real CAD exports found in public repositories, which state no licence and so are not in this
repository: docs/real_exports.md says where each comes from and how to fetch them into a folder
named by $MECHANISM_REAL_EXPORTS. Without it these tests skip; tests/test_export_quirks.py checks
the same features on hand-built exports. Expected numbers come from the export files themselves
(part masses, pin positions) or from Simscape's own import of the same file."""

import math
import os
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from mechanism.converters import convert, read

FILES = {  # folder/file below $MECHANISM_REAL_EXPORTS, as docs/real_exports.md lays them out
    "fourbar": "proe-fourbar-firstgen/ASM0001.xml",
    "ballbeam": "solidworks-ballbeam-mates/Ballbeam_v2.xml",
    "furuta": "solidworks-furuta-mates/full assembly.xml",
    "hexapod": "solidworks-hexapod-leg-simmechanics-link4/Link1.xml",
    "shin": "solidworks-robot-shin-simmechanics-link4/robot_shin.xml",
    "drone": "onshape-octocopter/Drone.xml",
    "creo": "creo-arm-mates-modelunits/ASM0002.xml",
    "scara": "solidworks-scara-printer-mates/finalassem.xml",
    "creo_ballbeam": "creo-ballbeam-rigid/BALL_BEAM_V4.xml",
    "dumbbell": "solidworks-dumbbell-stacker-mates/Assem1.xml",
    "quadruped": "solidworks-quadruped-mates/Assem4.xml",
    "ballbeam_v7": "solidworks-ballbeam-v7-mates/full_ass_V7_Ball_and_Beam.xml",
    "wrist": "creo9-icub-wrist-mates/IC_021_G_207_MECH.xml",
    "backhoe": "onshape-backhoe-joints/backhoe_arm_OS.xml",
    "arm_robot": "onshape-arm-robot-joints/finalAssembly.xml",
    "massless_arm": "onshape-massless-arm-joints/Assembly1.xml",
}
ROOT = os.environ.get("MECHANISM_REAL_EXPORTS", "")
pytestmark = pytest.mark.skipif(
    not ROOT,
    reason="set MECHANISM_REAL_EXPORTS to a folder with the real CAD exports "
    "listed in docs/real_exports.md (not redistributable: no licence)",
)


def real(key: str) -> Path:
    path = Path(ROOT, FILES[key])
    if not path.is_file():
        pytest.skip(f"{path} is missing (docs/real_exports.md says where to download it)")
    return path


LB = 0.45359237


def stated_mass_kg(path: Path) -> float:
    """The export's own total, read with regular expressions (independent of the readers)."""
    text = path.read_text(encoding="utf-8")
    if "<PhysicalModelingXMLFile>" in text:
        factor = {"kg": 1.0, "lbm": LB, "g": 1e-3}
        return sum(
            float(m) * factor[u]
            for m, u in re.findall(r'<mass>([^<]+)</mass>\s*<massUnits>"(\w+)"', text)
        )
    masses = dict(
        re.findall(r'<Part name="[^"]*" uid="([^"]+)"[^>]*>.*?<Mass>([^<]+)</Mass>', text, re.S)
    )
    tree = text[text.index("<InstanceTree>") : text.index("</InstanceTree>")]
    # DataUnits: kg here
    return sum(float(masses[e]) for e in re.findall(r'entityUid="([^"]+)"', tree) if e in masses)


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    """key -> ConversionReport, each real export converted once."""
    cache = {}

    def get(key):
        if key not in cache:
            cache[key] = convert(real(key), tmp_path_factory.mktemp(key))
        return cache[key]

    return get


@pytest.mark.parametrize("key", FILES)
def test_real_export_converts_with_its_mass_and_nothing_floating(converted, key):
    report, path = converted(key), real(key)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    # abs: an export of 0 kg
    assert model.body_mass.sum() == pytest.approx(stated_mass_kg(path), rel=1e-6, abs=1e-8)
    assert mujoco.mjtJoint.mjJNT_FREE not in set(model.jnt_type)
    assert report.n_meshes or any("geometry file(s) are missing" in w for w in report.warnings)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    equality = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert np.all(np.abs(data.efc_pos[equality]) < 1e-9), "loops are closed at the assembly pose"


def test_proe_fourbar_in_inches_follows_freudenstein(converted):
    """Pro/E Wildfire, lbm and inches: the crank turns fully and the rocker follows the four-bar
    equation built from the pin positions written in the export."""
    pins = {
        ref: np.array([float(v) for v in pos.split(",")]) * 0.0254
        for ref, pos in re.findall(
            r'<Frame ref="(\d+)">\s*<name>[^<]*</name>\s*<nodeID>[^<]*</nodeID>\s*<position>([^<]+)',
            real("fourbar").read_text(),
        )
    }
    o2, o4, a, b = pins["3"][:2], pins["5"][:2], pins["7"][:2], pins["9"][:2]
    crank, coupler, rocker, ground = (
        np.linalg.norm(u - v) for u, v in ((a, o2), (b, a), (b, o4), (o4, o2))
    )
    # 50, 80, 200, 180 in
    assert (crank, coupler, rocker, ground) == pytest.approx((1.27, 2.032, 5.08, 4.572), abs=1e-3)

    def rocker_angle(theta, guess):
        """Rocker angle (from the ground line O2->O4) for crank angle theta, nearest ``guess``."""
        axis = (o4 - o2) / ground
        normal = np.array([-axis[1], axis[0]])
        pin_a = o2 + crank * (math.cos(theta) * axis + math.sin(theta) * normal)
        to_a = pin_a - o4
        d = np.linalg.norm(to_a)
        base = math.atan2(to_a @ normal, to_a @ axis)
        spread = math.acos(np.clip((rocker**2 + d**2 - coupler**2) / (2 * rocker * d), -1, 1))
        candidates = [base + spread, base - spread]
        return min(candidates, key=lambda c: abs(math.remainder(c - guess, 2 * math.pi)))

    report = converted("fourbar")
    spec = mujoco.MjSpec.from_file(str(report.mjcf_path))
    spec.add_equality(
        name="drive",
        type=mujoco.mjtEq.mjEQ_JOINT,
        name1="PRT0004--PRT0001",
        objtype=mujoco.mjtObj.mjOBJ_JOINT,
        data=[0.0] * 12,
    )
    model = spec.compile()
    data, drive = mujoco.MjData(model), model.equality("drive").id
    mujoco.mj_forward(model, data)
    axis = (o4 - o2) / ground
    normal = np.array([-axis[1], axis[0]])
    angle = lambda v: math.atan2(v @ normal, v @ axis)

    def tracker(body, point_xy):
        """The world xy of a pin, followed through its body's motion from the assembly pose."""
        b = model.body(body).id
        local = data.xmat[b].reshape(3, 3).T @ (np.append(point_xy, 0.254) - data.xpos[b])
        return lambda: (data.xpos[b] + data.xmat[b].reshape(3, 3) @ local)[:2]

    pin_a, pin_b = tracker("PRT0001", a), tracker("PRT0003", b)
    steps, worst, thetas = 2000, 0.0, []
    phi = angle(b - o4)
    for step in range(steps):
        model.eq_data[drive, 0] = -2 * math.pi * step / steps  # the export's axis is -z
        mujoco.mj_step(model, data)
        mujoco.mj_kinematics(model, data)
        theta = angle(pin_a() - o2)
        phi = rocker_angle(theta, phi)
        worst = max(worst, abs(math.remainder(angle(pin_b() - o4) - phi, 2 * math.pi)))
        thetas.append(theta)
    assert np.ptp(np.unwrap(thetas)) > 1.95 * math.pi, "the crank turned fully"
    print(f"Pro/E four-bar: worst rocker error {math.degrees(worst):.4f} deg")
    assert math.degrees(worst) < 0.5


BALLBEAM_SMIMPORT = {  # Simscape's own import of this file (Ballbeam_v2_DataFile.m next to it upstream)
    ("Fork S.iges-1", "Balance.iges-1"): "revolute",
    ("Varilla C.iges-1", "Fork S.iges-1"): "revolute",
    ("Cuerpo 06.iges-1", "Varilla C.iges-1"): "revolute",
    ("Roda.iges-1", "Cuerpo 06.iges-1"): "revolute",
    ("Varilla LL.iges-1", "Fork B.iges-1"): "revolute",
    ("Base.iges-1", "Varilla LL.iges-1"): "revolute",
    ("MG996R.step.iges-1", "arm_4pad.iges-1"): "revolute",
    ("Fork B.iges-1", "Balance.iges-1"): "cylindrical",
}


def test_solidworks_mates_give_the_joints_simscape_finds(converted):
    assembly = read(real("ballbeam"))
    names = {k: p.name for k, p in assembly.parts.items()}
    found = {(names[j.base], names[j.follower]): j.kind for j in assembly.joints if not j.synthetic}
    assert found == BALLBEAM_SMIMPORT
    report = converted("ballbeam")
    assert any("Ball.iges-1" in w and "fixed to the world" in w for w in report.warnings), (
        "the loose ball is reported"
    )


CREO_SMIMPORT = {  # Simscape's import of this file (ASM0002_DataFile.m next to it upstream), by instance uid
    ("5", "9"): "revolute",
    ("9", "11"): "prismatic",
    ("11", "12"): "prismatic",
    ("12", "14"): "revolute",
    ("14", "15"): "prismatic",
    ("15", "16"): "revolute",
}


def test_creo_export_without_data_units_is_read_in_its_model_units(converted):
    """Creo 6 (Simscape Multibody Link 6.0) writes no <DataUnits>: its numbers are in ModelUnits (mm),
    and its line axes are not unit vectors. The mates give Simscape's six joints."""
    assembly = read(real("creo"))
    found = {(j.base, j.follower): j.kind for j in assembly.joints if not j.synthetic}
    assert found == CREO_SMIMPORT
    slide = next(j for j in assembly.joints if (j.base, j.follower) == ("11", "12"))
    assert slide.primitives[0].axis == pytest.approx([0, 0, 1], abs=1e-9)
    # 600 mm - 80 mm: millimetres, not metres
    assert slide.base_frame.position[0] == pytest.approx(0.52, abs=1e-9)
    assert converted("creo").degrees_of_freedom == 6


SCARA_SMIMPORT = {  # Simscape's import (finalassem_DataFile.m upstream): 9 revolute, 2 cylindrical, 1 prismatic
    ("base.STEP-1", "bedplate.STEP-1"): "prismatic",
    ("base.STEP-1", "1.STEP-1"): "revolute",
    ("base.STEP-1", "1.STEP-2"): "revolute",
    ("base.STEP-1", "1.STEP-3"): "revolute",
    ("1.STEP-1", "3.STEP-1"): "revolute",
    ("1.STEP-3", "3.STEP-1"): "revolute",
    ("1.STEP-2", "2.STEP-1"): "revolute",
    ("1.STEP-3", "2.STEP-2"): "revolute",
    ("2.STEP-2", "nozzle.STEP-1"): "revolute",
    ("nozzle.STEP-1", "4.STEP-1"): "revolute",
    ("2.STEP-1", "nozzle.STEP-1"): "cylindrical",
    ("3.STEP-1", "4.STEP-1"): "cylindrical",
}


def test_solidworks_parallel_arm_printer_matches_simscape_and_has_three_freedoms(converted):
    """A five-bar parallel arm carrying the nozzle and a bed on two rails, all in rigid
    sub-assemblies, mated by coincident circles: 2 arm motors + the bed = 3 freedoms."""
    found = {
        (j.base.split("/")[0], j.follower.split("/")[0]): j.kind
        for j in read(real("scara")).joints
        if not j.synthetic
    }
    assert found == SCARA_SMIMPORT
    report = converted("scara")
    assert report.degrees_of_freedom == 3 and report.n_loop_closures == 3


def test_solidworks_ball_and_beam_loop_moves_with_the_servo(converted):
    """Driving the servo horn tilts the beam through the spatial linkage; the loop stays closed."""
    spec = mujoco.MjSpec.from_file(str(converted("ballbeam").mjcf_path))
    spec.add_equality(
        name="drive",
        type=mujoco.mjtEq.mjEQ_JOINT,
        name1="MG996R.step.iges-1--arm_4pad.iges-1",
        objtype=mujoco.mjtObj.mjOBJ_JOINT,
        data=[0.0] * 12,
    )
    model = spec.compile()
    data, drive = mujoco.MjData(model), model.equality("drive").id
    mujoco.mj_forward(model, data)
    beam = model.site("Balance.iges-1").id
    start = data.site_xmat[beam].reshape(3, 3).copy()
    for step in range(600):
        model.eq_data[drive, 0] = math.radians(20) * min(1.0, step / 400)
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    loops = (data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (data.efc_id != drive)
    assert np.abs(data.efc_pos[loops]).max() < 1e-5, "the linkage stays closed (10 micrometres)"
    tilt = math.degrees(
        math.acos(np.clip((np.trace(start.T @ data.site_xmat[beam].reshape(3, 3)) - 1) / 2, -1, 1))
    )
    assert tilt > 1.0, f"the beam tilted only {tilt:.3f} degrees"


def test_solidworks_rigid_link_made_of_two_rigid_servo_subassemblies_is_one_body(converted):
    """SimMechanics Link 4.6 (SimMechanicsImportXML): the same rigid sub-assembly twice (its instance
    uids repeat), brackets bolted by two pins or pin-and-parallel mates: a rigid leg link."""
    report = converted("hexapod")
    assert report.n_parts == 19 and report.n_bodies == 1 and report.degrees_of_freedom == 0
    sites = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    assert {"bottom_cover-1", "bottom_cover-1_2"} <= {
        sites.site(i).name for i in range(sites.nsite)
    }


def test_flexible_subassembly_keeps_its_own_mates_in_its_own_frame(converted):
    """robot_shin: the damper sub-assembly (flexible, turned 11.7 degrees) has its own mates; the rod
    slides along the damper's axis, which is the sub-assembly's y axis in the world."""
    assembly = read(real("shin"))
    names = {k: p.name for k, p in assembly.parts.items()}
    stroke = next(j for j in assembly.joints if not j.synthetic and names[j.follower] == "stroke-1")
    assert stroke.kind == "cylindrical"
    damper_y = np.array([0.202482, 0.979286, 0.0])  # second column of the sub-assembly's rotation
    assert abs(stroke.primitives[0].axis @ damper_y) == pytest.approx(1, abs=1e-5)
    report = converted("shin")
    assert report.degrees_of_freedom >= 1 and report.n_loop_closures >= 1


def test_onshape_subassembly_joints_repeat_per_instance(converted):
    """Onshape octocopter: eight instances of one sub-assembly, each with a cylindrical and a planar
    joint (together a spinning motor) and a revolute blade: 16 freedoms, 8 x 3 joints."""
    report = converted("drone")
    assert report.degrees_of_freedom == 16
    assert report.joints_by_type["hinge"] == 24 and report.joints_by_type["slide"] == 24
    assert report.n_loop_closures == 8


FURUTA_SMIMPORT = {  # Simscape's import of this file (fullAssembly_DataFile3.m in the same upstream commit)
    **{
        pair: "cylindrical"
        for pair in (
            ("second link holder-1", "link 2-1"),
            ("cover of the bearing-1", "holder of Encoder-1"),
            ("cover of the bearing-1", "NTN_6000  (Bearing 10x26x8)-8"),
            ("cover of the bearing-1", "MH2530-6.35-10-1"),
        )
    },
    **{
        pair: "planar"
        for pair in (
            ("Base cover-1", "NTN_6000  (Bearing 10x26x8)-8"),
            ("cross holder of the motor-1", "MH2530-6.35-10-1"),
        )
    },
    **{
        pair: "revolute"
        for pair in (
            ("encoder fixation-1", "link 2-1"),
            ("Base-1", "cross holder of the motor-1"),
            ("holder of Encoder-1", "MH2530-6.35-10-1"),
        )
    },
}


def test_furuta_pendulum_mates(converted):
    """SolidWorks 2023, mates only, with an UnknownConstraint (a lock mate the exporter could not
    describe): it fixes its two parts, and every other pair of parts gets its own joint: Simscape's
    9 joints, kind and part pair; the pendulum arm turns about the horizontal encoder axis."""
    report = converted("furuta")
    assert any("Lock3" in w and "fixes" in w for w in report.warnings)
    assembly = read(real("furuta"))
    names = {k: p.name for k, p in assembly.parts.items()}
    found = {
        frozenset((names[j.base], names[j.follower])): j.kind
        for j in assembly.joints
        if not j.synthetic
    }
    assert found == {frozenset(pair): kind for pair, kind in FURUTA_SMIMPORT.items()}
    joints = {j.name: j for j in assembly.joints if not j.synthetic}
    arm = joints["encoder fixation-1--link 2-1"]
    assert arm.kind == "revolute"
    motor = joints["holder of Encoder-1--MH2530-6.35-10-1"]
    assert abs(arm.primitives[0].axis @ motor.primitives[0].axis) < 1e-6, (
        "pendulum axis is perpendicular to the motor's"
    )


CREO_BALLBEAM_SMIMPORT = {  # Simscape's import (BALL_BEAM_V4_DataFile.m upstream): joint IDs [base:-:follower]
    ("44", "45"): "revolute",
    ("60", "62"): "revolute",
    ("64", "88"): "revolute",
    ("85", "88"): "revolute",
    ("88", "96"): "prismatic",
}


def test_creo_rigid_constraints_weld_and_give_simscapes_joints(converted):
    """Creo 11 (Simscape Multibody Link 7.4) writes <Rigid> constraints as two bare InstancePaths,
    no geometry (issue 14 class 4): they weld their parts, and the mates give Simscape's joints:
    4 revolute + 1 prismatic, one loop, two freedoms (the servo and the ball on the beam)."""
    assembly = read(real("creo_ballbeam"))
    found = {(j.base, j.follower): j.kind for j in assembly.joints if not j.synthetic}
    assert found == CREO_BALLBEAM_SMIMPORT
    assert sum(bool(j.kind == "weld" and j.sources) for j in assembly.joints) == 9, (
        "nine <Rigid> constraints"
    )
    report = converted("creo_ballbeam")
    assert report.degrees_of_freedom == 2 and report.n_loop_closures == 1
    assert not any("fixed to the world" in w for w in report.warnings)
    model = mujoco.MjModel.from_xml_path(str(report.mjcf_path))
    model.dof_damping[:] = 0.05
    data = mujoco.MjData(model)
    worst = 0.0
    for _ in range(200):  # 0.1 s under gravity
        mujoco.mj_step(model, data)
        equality = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        worst = max(worst, float(np.abs(data.efc_pos[equality]).max(initial=0.0)))
    assert worst < 1e-4


DUMBBELL_SMIMPORT = {  # Simscape's import (Assem1_DataFile.m upstream): 4 cylindrical, 20 revolute, [base:-:follower]
    **{
        pair: "cylindrical"
        for pair in (
            ("Part1-1", "Part3-1"),
            ("Part1-1", "Part3-2"),
            ("Part1-1", "Part3-3"),
            ("Part3-1", "Part5-1"),
        )
    },
    **{
        pair: "revolute"
        for pair in (
            ("Part1-1", "Part3-14"),
            ("Part1-1", "Part3-15"),
            ("Part1-1", "Part3-16"),
            ("Part1-1", "Part3-4"),
            ("Part2-1", "Part3-1"),
            ("Part2-1", "Part3-2"),
            ("Part2-1", "Part3-3"),
            ("Part2-1", "Part3-4"),
            ("Part2-4", "Part3-13"),
            ("Part2-4", "Part3-14"),
            ("Part2-4", "Part3-15"),
            ("Part2-4", "Part3-16"),
            ("Part3-13", "Part1-1"),
            ("Part3-13", "Part5-7"),
            ("Part3-14", "Part5-8"),
            ("Part3-3", "Part5-2"),
            ("Part4-1", "Part5-1"),
            ("Part4-1", "Part5-2"),
            ("Part4-1", "Part5-7"),
            ("Part4-1", "Part5-8"),
        )
    },
}


def test_solidworks_dumbbell_stacker_mates_give_simscapes_24_joints(converted):
    """Simscape Multibody Link 5.1, SolidWorks 2016: 46 concentric and coincident mates between 16
    instances give Simscape's 24 joints, kind, part pair and direction."""
    assembly = read(real("dumbbell"))
    names = {k: p.name for k, p in assembly.parts.items()}
    assert {
        (names[j.base], names[j.follower]): j.kind for j in assembly.joints if not j.synthetic
    } == DUMBBELL_SMIMPORT
    assert converted("dumbbell").n_loop_closures == 10


QUADRUPED_SMIMPORT = {  # Simscape's import (Assem4_DataFile.m upstream): 8 revolute, [base:-:follower]
    pair: "revolute"
    for pair in (
        ("leg1-1", "thigh1-1"),
        ("thigh1-1", "base1-1"),
        ("thigh1-2", "leg1-2"),
        ("base1-1", "thigh1-2"),
        ("leg2-1", "thigh2-1"),
        ("thigh2-1", "base1-1"),
        ("thigh2-2", "leg2-2"),
        ("base1-1", "thigh2-2"),
    )
}


def test_solidworks_quadruped_gives_simscapes_eight_revolutes(converted):
    """Simscape Multibody Link 4.8, SolidWorks 2021: two grounded parts (one massless), four legs of
    thigh and shank, each pinned by a concentric and a coincident mate: Simscape's 8 revolute
    joints, part pair and direction, 8 freedoms and no loop."""
    assembly = read(real("quadruped"))
    names = {k: p.name for k, p in assembly.parts.items()}
    assert {
        (names[j.base], names[j.follower]): j.kind for j in assembly.joints if not j.synthetic
    } == QUADRUPED_SMIMPORT
    report = converted("quadruped")
    assert report.degrees_of_freedom == 8 and report.n_loop_closures == 0


def _kinds(key):
    from collections import Counter

    return Counter(j.kind for j in read(real(key)).joints if not j.synthetic and j.kind != "weld")


def test_solidworks_assembly_with_screws_and_stacked_weights_gets_simscapes_joints_pair_by_pair(
    converted,
):
    """SolidWorks 2023 (Link 7.4), 50 instances with screws, nuts and a stack of weights; three mates
    name the root assembly itself (its origin). Simscape's DataFile lists 20 cylindrical, 24 planar,
    7 prismatic and 12 revolute joints: each pair of parts its own joint (the weights, mated to the
    bracket and to each other, are held by prismatic and planar joints). Known difference: Simscape
    fixes two set screws mated by a concentric and a plane-to-cylinder distance (we let them spin:
    2 more revolute) and a cable mated by circles (one compound joint here)."""
    kinds = _kinds("ballbeam_v7")
    assert (kinds["cylindrical"], kinds["planar"], kinds["prismatic"]) == (20, 24, 7)
    assert kinds["revolute"] == 12 + 2 and kinds["compound"] == 1
    report = converted("ballbeam_v7")
    assert not any(
        "not connected to the ground" in w or "not an instance" in w for w in report.warnings
    )


def test_creo_9_wrist_and_onshape_backhoe_give_simscapes_joint_kinds(converted):
    """Creo 9 (Link 7.4) with numeric uids and revolutes to the assembly origin: Simscape's 9 revolute;
    Onshape's exporter with joints (fastened ones are welds): Simscape's 8 revolute and 7 cylindrical."""
    assert dict(_kinds("wrist")) == {"revolute": 9}
    assert dict(_kinds("backhoe")) == {"revolute": 8, "cylindrical": 7}
    # Onshape 2024, servos fastened to their links
    assert dict(_kinds("arm_robot")) == {"revolute": 13}
    assert (
        converted("wrist").degrees_of_freedom == 3 and converted("backhoe").degrees_of_freedom == 3
    )


def test_onshape_arm_without_any_mass_gets_only_what_mujoco_needs(converted):
    """Onshape without materials: every part weighs 0. Simscape's joints (10 revolute, 7 cylindrical);
    the moving bodies get the least mass MuJoCo accepts (1e-9 kg in all), not milligrams."""
    assert dict(_kinds("massless_arm")) == {"revolute": 10, "cylindrical": 7}
    model = mujoco.MjModel.from_xml_path(str(converted("massless_arm").mjcf_path))
    assert 0 < model.body_mass.sum() <= 1e-9 * (1 + 1e-9)
