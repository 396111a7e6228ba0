"""The shipped bench press (the second machine): its generated second-generation CAD export, the
MJCF converted from it, and its kinematics and inertia against closed forms computed here from
the parameter file and the export's own numbers."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import defusedxml.ElementTree as ET
import mujoco
import numpy as np
import pytest

from mechanism.converters import convert
from mechanism.kinematics.linkage import compute_tables
from mechanism.machine.models import load_model
from tests.helpers import mjcf as same_model

REPO = Path(__file__).resolve().parent.parent
GENERATOR = REPO / "assets" / "cad" / "press" / "generate.py"
PARAMS = json.loads((REPO / "assets" / "cad" / "press" / "press.params.json").read_text())
ASSETS = REPO / "assets"
EXPORT = ASSETS / "cad" / "press" / "export"
MODEL = ASSETS / "mjcf" / "press.xml"
INCH, POUND = 0.0254, 0.45359237
NS = "{urn:mathworks:SimscapeMultibody:import}"

MOTOR, SHAFT, SLIDE = (
    "MOTOR_HOUSING-1--MOTOR_ROTOR-1",
    "BASE_FRAME-1--CRANKSHAFT-1",
    "BASE_FRAME-1--RAM-1",
)
TIP = "RAM-1"


def param(key: str) -> float:
    section, name = key.split(".")
    return PARAMS[section][name]["value"]


def inches(key: str) -> float:
    assert PARAMS[key.split(".")[0]][key.split(".")[1]]["unit"] == "in"
    return param(key) * INCH


# the slider-crank in metres, from the parameters: crank axis height, crank radius, rod length,
# wrist pin above the ram tip
R, L, PIN = inches("crank.radius"), inches("rod.length"), inches("ram.pin_height")
CRANK_Z = inches("ram.tip_clearance") + R + L + PIN
RATIO = param("worm_gear.wheel_teeth") / param("worm_gear.worm_starts")


def tip_height(theta):
    """Ram tip above the die plate, θ from top dead centre (crank pin straight up): the wrist pin
    is x(φ) = r cos φ + sqrt(l² - r² sin² φ) below the crank axis, φ = θ + π."""
    return CRANK_Z + R * np.cos(theta) - np.sqrt(L**2 - (R * np.sin(theta)) ** 2) - PIN


def tip_slope(theta):
    """dz/dθ of tip_height."""
    return -R * np.sin(theta) + R**2 * np.sin(theta) * np.cos(theta) / np.sqrt(
        L**2 - (R * np.sin(theta)) ** 2
    )


def export_parts() -> dict[str, dict]:
    """instance name -> mass [kg], centre of mass [m] and inertia tensor [kg m^2] (part axes)."""
    root = ET.parse(EXPORT / "press.xml").getroot()
    units = root.find(f"{NS}DataUnits").attrib
    assert units == {"length": "inch", "mass": "pound"}
    entities = {}
    for part in root.iter(f"{NS}Part"):
        props = part.find(f"{NS}MassProperties")
        ixx, iyy, izz, iyz, izx, ixy = (float(v) for v in props.find(f"{NS}Inertia").text.split())
        entities[part.get("uid")] = {
            "mass": float(props.find(f"{NS}Mass").text) * POUND,
            "com": np.array([float(v) for v in props.find(f"{NS}CenterOfMass").text.split()])
            * INCH,
            "inertia": np.array([[ixx, ixy, izx], [ixy, iyy, iyz], [izx, iyz, izz]])
            * POUND
            * INCH**2,
        }
    return {
        inst.get("name"): entities[inst.get("entityUid")] for inst in root.iter(f"{NS}Instance")
    }


@pytest.fixture(scope="module")
def model():
    return load_model(MODEL)


@pytest.fixture(scope="module")
def tables(model):
    return compute_tables(model, SHAFT, TIP, n=360)


# --------------------------------------------------------------------------- the export


@pytest.mark.slow
def test_regenerating_the_export_and_the_mjcf_gives_the_committed_model(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(GENERATOR), "-q", "-o", str(tmp_path / "cad")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "cad").iterdir()) == sorted(
        p.name for p in EXPORT.iterdir()
    )
    for path in EXPORT.iterdir():
        assert (tmp_path / "cad" / path.name).read_bytes() == path.read_bytes(), path.name
    convert(
        tmp_path / "cad" / "press.xml",
        tmp_path / "mjcf",
        name="press",
        mesh_dir=tmp_path / "meshes" / "press",
    )
    assert same_model.difference(tmp_path / "mjcf" / "press.xml", MODEL) is None
    meshes = ASSETS / "meshes" / "press"
    assert sorted(p.name for p in (tmp_path / "meshes" / "press").iterdir()) == sorted(
        p.name for p in meshes.iterdir()
    )
    for path in meshes.iterdir():
        assert (tmp_path / "meshes" / "press" / path.name).read_bytes() == path.read_bytes(), (
            path.name
        )


@pytest.mark.slow
def test_generator_rejects_a_bad_parameter_file_with_one_line(tmp_path):
    bad = json.loads(json.dumps(PARAMS))
    bad["rod"]["length"]["value"] = 0.5  # shorter than the crank radius
    path = tmp_path / "bad.params.json"
    path.write_text(json.dumps(bad))
    out = tmp_path / "export"
    proc = subprocess.run(
        [sys.executable, str(GENERATOR), "--params", str(path), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert (
        proc.stderr.startswith("error:")
        and len(proc.stderr.strip().splitlines()) == 1
        and "rod.length" in proc.stderr
    )
    assert not out.exists()


def test_export_is_second_generation_in_inches_with_mates_and_a_worm_gear():
    text = (EXPORT / "press.xml").read_text()
    root = ET.fromstring(text)
    assert root.tag == f"{NS}SimscapeMultibodyImportXML" and root.get("version") == "2.0"
    assert root.find(f"{NS}RootAssembly/{NS}Joints") is None  # SolidWorks writes mates, not joints
    tags = [c.tag.removeprefix(NS) for c in root.find(f"{NS}RootAssembly/{NS}Constraints")]
    assert {"Concentric", "Coincident", "WormAndGearConstraint"} == set(tags)
    names = [i.get("name") for i in root.iter(f"{NS}Instance")]
    assert all(n.endswith("-1") and n[:-2].isupper() for n in names)


def test_export_masses_are_the_solids_times_the_parameter_densities():
    import trimesh

    materials = {
        "BASE_FRAME": "cast_iron",
        "DIE_PLATE": "steel",
        "MOTOR_HOUSING": "aluminium",
        "MOTOR_ROTOR": "steel",
        "CRANKSHAFT": "steel",
        "WORM_WHEEL": "bronze",
        "CONNECTING_ROD": "steel",
        "RAM": "steel",
    }
    parts = export_parts()
    assert sorted(parts) == sorted(f"{n}-1" for n in materials)
    for name, material in materials.items():
        mesh = trimesh.load(EXPORT / f"{name}.STL")
        assert mesh.is_watertight
        volume_m3 = mesh.volume * INCH**3  # the STL is in the export's unit, inches
        assert parts[f"{name}-1"]["mass"] == pytest.approx(
            volume_m3 * param(f"materials.{material}"), rel=1e-6
        ), name
        assert parts[f"{name}-1"]["com"] == pytest.approx(mesh.center_mass * INCH, abs=1e-8), name


# --------------------------------------------------------------------------- the MJCF


def test_mates_become_three_hinges_a_slide_one_loop_and_the_worm_coupling(model):
    kinds = {model.joint(j).name: int(model.jnt_type[j]) for j in range(model.njnt)}
    hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
    assert kinds == {
        MOTOR: hinge,
        SHAFT: hinge,
        "CRANKSHAFT-1--CONNECTING_ROD-1": hinge,
        SLIDE: slide,
    }
    equalities = {model.equality(e).name: int(model.eq_type[e]) for e in range(model.neq)}
    connect, joint = int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_JOINT)
    assert equalities == {
        "loop:CONNECTING_ROD-1--RAM-1": connect,
        "loop:CONNECTING_ROD-1--RAM-1:2": connect,
        "coupling:WormGear1": joint,
    }
    coupling = model.equality("coupling:WormGear1")
    assert (
        model.joint(coupling.obj1id[0]).name == MOTOR
        and model.joint(coupling.obj2id[0]).name == SHAFT
    )
    assert coupling.data[:5] == pytest.approx([0.0, RATIO, 0, 0, 0])
    # the ram's part frame is its tip: the part site sits there at the assembly pose (TDC)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    assert data.site(TIP).xpos == pytest.approx([0, 0, tip_height(0.0)], abs=1e-9)


def test_total_mass_is_the_exports(model):
    exported = sum(part["mass"] for part in export_parts().values())
    assert float(model.body_mass.sum()) == pytest.approx(exported, rel=1e-9)


def test_ram_stroke_and_position_follow_the_slider_crank_equation(tables):
    theta = tables.angle_rad
    stroke = 2 * R
    assert float(np.ptp(tables.tool_z_m)) == pytest.approx(stroke, abs=1e-6 * stroke)
    assert np.max(np.abs(tables.tool_z_m - tip_height(theta))) < 1e-6 * stroke
    assert np.max(np.abs(tables.tool_dz_drad - tip_slope(theta))) < 1e-6 * stroke
    # bottom dead centre half a turn from the top, the tip just above the die plate
    assert theta[np.argmin(tables.tool_z_m)] == pytest.approx(math.pi)
    assert tables.tool_z_m.min() == pytest.approx(inches("ram.tip_clearance"), abs=1e-9)


def test_worm_gear_turns_the_motor_twenty_times_per_crank_turn(tables):
    assert RATIO == 20
    assert np.all(np.abs(tables.ratios[MOTOR] - RATIO) < 1e-9)
    assert np.all(np.abs(tables.ratios[SLIDE] - tip_slope(tables.angle_rad)) < 1e-6 * R)


def axial_inertia(part: dict) -> float:
    """Inertia about the part's own z axis through its frame origin (parallel-axis theorem):
    the rotor's, the crankshaft's and the wheel's part frames sit on their axes of rotation."""
    cx, cy, _ = part["com"]
    return part["inertia"][2, 2] + part["mass"] * (cx**2 + cy**2)


def hand_inertia(theta: np.ndarray) -> np.ndarray:
    """J(θ) at the crank: rotor × ratio², crankshaft and wheel, the rod (translation of its centre
    of mass and rotation about the pin axis) and the ram, from the slider-crank's closed form."""
    parts = export_parts()
    rotating = (
        RATIO**2 * axial_inertia(parts["MOTOR_ROTOR-1"])
        + axial_inertia(parts["CRANKSHAFT-1"])
        + axial_inertia(parts["WORM_WHEEL-1"])
    )
    rod, ram = parts["CONNECTING_ROD-1"], parts["RAM-1"]

    def rod_pose(t):
        """(centre of mass (y, z), rod angle) with the crank turned t about +x."""
        pin = np.array([-R * np.sin(t), CRANK_Z + R * np.cos(t)])
        wrist = np.array([np.zeros_like(t), tip_height(t) + PIN])
        along = (wrist - pin) / L  # rod part y; part x = y × (world x) in the (y, z) plane
        across = np.array([along[1], -along[0]])
        cx, cy, _ = rod["com"]  # part z is world x: no (y, z) motion
        return pin + cx * across + cy * along, np.arctan2(along[1], along[0])

    h = 1e-6
    (g1, a1), (g0, a0) = rod_pose(theta + h), rod_pose(theta - h)
    v_rod = (g1 - g0) / (2 * h)
    w_rod = (a1 - a0) / (2 * h)
    rod_part = rod["mass"] * (v_rod**2).sum(axis=0) + rod["inertia"][2, 2] * w_rod**2
    return rotating + rod_part + ram["mass"] * tip_slope(theta) ** 2


def test_reflected_inertia_at_the_crank_is_the_hand_calculation(tables):
    expected = hand_inertia(tables.angle_rad)
    assert np.max(np.abs(tables.inertia_kgm2 / expected - 1)) < 1e-6
    rotor = RATIO**2 * axial_inertia(export_parts()["MOTOR_ROTOR-1"])
    # the motor rotor through the worm is most of it; the slider-crank varies it by about 2 %
    assert 0.9 < rotor / tables.mean_inertia_kgm2 < 0.95
    assert 0.01 < np.ptp(tables.inertia_kgm2) / tables.mean_inertia_kgm2 < 0.04


def test_gravity_torque_is_the_ram_and_rod_weight_through_the_linkage(tables):
    """G(θ) = g (m_ram dz/dθ + m_rod dz_rod/dθ) + crank unbalance; its mean over a turn is zero."""
    assert abs(float(tables.gravity_torque_Nm.mean())) < 1e-9
    ram = export_parts()["RAM-1"]["mass"]
    # the rod and the crank pin add to the ram
    assert np.max(np.abs(tables.gravity_torque_Nm)) > 9.81 * ram * R


def exact_meshes(model) -> dict[str, object]:
    """Collision geom name -> its exact triangles (geom frame), not MuJoCo's convex hull."""
    import trimesh

    meshes = {}
    for g in range(model.ngeom):
        if model.geom_group[g] == 3 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            mesh = model.geom_dataid[g]
            vertices = model.mesh_vert[model.mesh_vertadr[mesh] :][: model.mesh_vertnum[mesh]]
            faces = model.mesh_face[model.mesh_faceadr[mesh] :][: model.mesh_facenum[mesh]]
            meshes[model.geom(g).name] = trimesh.Trimesh(vertices, faces, process=False)
    return meshes


@pytest.mark.slow
def test_no_two_parts_interpenetrate_over_a_revolution(model):
    """Every pair of bodies at every 3 degrees of crank angle: pins run in their bores, the rod in
    the ram's slot, the ram in its keyed guide, the worm over the wheel (running clearance 0.005 in)."""
    import trimesh

    from mechanism.kinematics.pose import sweep

    meshes = exact_meshes(model)
    assert len(meshes) == 8
    body = {name: int(model.geom(name).bodyid[0]) for name in meshes}
    data = mujoco.MjData(model)
    clashes = set()
    for qpos in sweep(model, np.radians(np.arange(0, 360, 3.0)), SHAFT):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        scene = trimesh.collision.CollisionManager()
        for name, mesh in meshes.items():
            placed = np.eye(4)
            placed[:3, :3], placed[:3, 3] = data.geom(name).xmat.reshape(3, 3), data.geom(name).xpos
            scene.add_object(name, mesh, transform=placed)
        clashes |= {
            tuple(sorted(pair))
            for pair in scene.in_collision_internal(return_names=True)[1]
            if body[pair[0]] != body[pair[1]]
        }
    assert not clashes
