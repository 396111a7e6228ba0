"""The shipped sewing machine: its generated CAD export, the MJCF converted from it, and its
motion checked against the analytic slider-crank, the belts and the thesis."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import defusedxml.ElementTree as ET
import mujoco
import numpy as np
import pytest
import trimesh

from mechanism.kinematics.pose import solve_pose
from mechanism.machine.models import DEFAULT_MODEL, load_model
from mechanism.inspection.needle import needle_motion
from mechanism.kinematics.linkage import compute_tables
from mechanism.data.reference import thesis

REPO = Path(__file__).resolve().parent.parent
CAD = REPO / "assets" / "cad" / "sapphire870"
EXPORT = CAD / "export"
PARAMS = json.loads((CAD / "sewing_machine.params.json").read_text())
MESHES = REPO / "assets" / "meshes" / "sapphire870"


def param(section, name):
    return PARAMS[section][name]["value"]


# --------------------------------------------------------------------------- the export


@pytest.mark.slow
def test_generator_reproduces_the_committed_export(tmp_path):
    out = tmp_path / "export"
    proc = subprocess.run(
        [sys.executable, str(CAD / "generate.py"), "-q", "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    fresh = sorted(p.name for p in out.iterdir())
    committed = sorted(p.name for p in EXPORT.iterdir())
    assert fresh == committed
    for name in committed:
        assert (out / name).read_bytes() == (EXPORT / name).read_bytes(), name


@pytest.mark.slow
def test_generator_rejects_a_bad_parameter_file_with_one_line(tmp_path):
    bad = json.loads(json.dumps(PARAMS))
    bad["crank"]["radius"]["unit"] = "inch"
    path = tmp_path / "bad.params.json"
    path.write_text(json.dumps(bad))
    out = tmp_path / "export"
    proc = subprocess.run(
        [sys.executable, str(CAD / "generate.py"), "--params", str(path), "-o", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error:") and len(proc.stderr.strip().splitlines()) == 1
    assert "crank.radius" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()


def _text(element, tag):
    return element.find(tag).text.strip().strip('"')


def _numbers(element, tag):
    return np.array([float(v) for v in _text(element, tag).split(",")])


def _export_parts():
    """name -> (mass g, CG world mm, inertia g mm^2 in CG axes, rotation part->world, CS1 origin, STL file)."""
    root = ET.parse(EXPORT / "sewing_machine.xml").getroot()
    parts = {}
    for body in root.iter("Body"):
        stl = _text(body, "geometryFileName")
        if not stl:
            continue
        frames = {_text(f, "name"): f for f in body.find("frames").findall("Frame")}
        cg, cs1 = frames["CG"], frames["CS1"]
        assert _text(body, "massUnits") == "g" and _text(body, "inertiaUnits") == "g*mm^2"
        rotation = _numbers(cs1, "orientation").reshape(3, 3).T  # written column by column
        np.testing.assert_allclose(_numbers(cg, "orientation"), _numbers(cs1, "orientation"))
        parts[_text(body, "name")] = (
            float(_text(body, "mass")),
            _numbers(cg, "position"),
            _numbers(body, "inertia").reshape(3, 3),
            rotation,
            _numbers(cs1, "position"),
            stl,
        )
    return parts


def test_export_mass_properties_are_those_of_the_meshes_and_the_parameter_densities():
    # g/mm^3
    densities = {name: entry["value"] * 1e-6 for name, entry in PARAMS["materials"].items()}
    parts = _export_parts()
    assert len(parts) == 24
    for name, (mass, cg, inertia, rotation, origin, stl) in parts.items():
        mesh = trimesh.load(EXPORT / stl, force="mesh")
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0, name
        density = mass / mesh.volume
        material = min(densities, key=lambda k: abs(densities[k] - density))
        assert density == pytest.approx(densities[material], rel=1e-5), (name, density)
        props = mesh.mass_properties
        np.testing.assert_allclose(
            rotation @ props["center_mass"] + origin, cg, atol=2e-3, err_msg=name
        )
        expected = props["inertia"] * densities[material]
        np.testing.assert_allclose(
            inertia, expected, rtol=2e-5, atol=2e-5 * np.abs(expected).max(), err_msg=name
        )


def test_export_names_the_frames_the_tools_rely_on():
    text = (EXPORT / "sewing_machine.xml").read_text()
    for frame in (
        "needle_tip",
        "needle_eye",
        "hook_point",
        "crank_pin_center",
        "take_up_eye",
        "needle_plate_top",
    ):
        assert f'<displayName>"{frame}"</displayName>' in text
    couplings = json.loads((EXPORT / "sewing_machine.couplings.json").read_text())["couplings"]
    ratios = {c["name"]: (c["input"], c["output"], c["ratio"]) for c in couplings}
    mech = thesis()["mechanism"]
    assert ratios["motor_belt"] == ("motor", "arm_shaft", mech["motor_to_arm_ratio"])
    assert ratios["lower_belt"] == ("arm_shaft", "lower_shaft", mech["arm_to_lower_shaft_ratio"])
    assert ratios["hook_worm_gear"] == (
        "lower_shaft",
        "hook",
        1 / mech["lower_shaft_to_hook_ratio"],
    )


# --------------------------------------------------------------------------- the MJCF


def test_committed_mjcf_is_what_the_converter_makes_of_the_committed_export(tmp_path):
    from mechanism.converters import convert

    mjcf, meshes = tmp_path / "mjcf", tmp_path / "meshes" / "sapphire870"  # the assets/ layout
    convert(EXPORT / "sewing_machine.xml", mjcf, mesh_dir=meshes)
    assert (mjcf / DEFAULT_MODEL.name).read_text() == DEFAULT_MODEL.read_text()
    fresh = sorted(p.name for p in meshes.iterdir())
    assert fresh == sorted(p.name for p in MESHES.iterdir())
    for name in fresh:
        assert (meshes / name).read_bytes() == (MESHES / name).read_bytes(), name


@pytest.fixture(scope="module")
def model():
    return load_model()


def test_each_mjcf_body_carries_the_mass_and_inertia_of_its_export_parts(model):
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # qpos0 = the export's assembly pose
    groups = {}
    for name, values in _export_parts().items():
        body = model.geom(name).bodyid[0]
        groups.setdefault(int(body), []).append(values)
    assert len(groups) == model.nbody - 1
    for body, members in groups.items():
        masses = np.array([m[0] for m in members]) * 1e-3
        cgs = np.array([m[1] for m in members]) * 1e-3
        total = masses.sum()
        com = (masses[:, None] * cgs).sum(axis=0) / total
        inertia = np.zeros((3, 3))
        for (_, cg, part_inertia, rotation, _, _), mass in zip(members, masses):
            d = cg * 1e-3 - com
            inertia += rotation @ (part_inertia * 1e-9) @ rotation.T + mass * (
                d @ d * np.eye(3) - np.outer(d, d)
            )
        assert model.body_mass[body] == pytest.approx(total, rel=1e-6), model.body(body).name
        np.testing.assert_allclose(data.xipos[body], com, atol=1e-8)
        R = data.ximat[body].reshape(3, 3)
        mjcf_inertia = R @ np.diag(model.body_inertia[body]) @ R.T
        np.testing.assert_allclose(
            mjcf_inertia,
            inertia,
            rtol=1e-5,
            atol=1e-6 * np.abs(inertia).max(),
            err_msg=model.body(body).name,
        )


def test_motor_rotor_inertia_is_the_thesis_value(model):
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    joint = model.joint("motor")
    body = joint.bodyid[0]
    axis = data.xaxis[joint.id]
    R = data.ximat[body].reshape(3, 3)
    d = data.xipos[body] - data.xanchor[joint.id]
    d_perp = d - (d @ axis) * axis
    about_axis = (
        axis @ (R @ np.diag(model.body_inertia[body]) @ R.T) @ axis
        + model.body_mass[body] * d_perp @ d_perp
    )
    assert about_axis == pytest.approx(
        thesis()["main_motor"]["inertia_from_geometry_kgm2"], rel=0.02
    )


def test_positive_arm_angle_is_forward_sewing(model):
    # the top of the crank (and of the handwheel) moves toward the operator (-y), the needle goes down
    data = mujoco.MjData(model)
    solve_pose(model, data, {"arm_shaft": 0.0})
    pin, tip = data.site("crank_pin_center").xpos.copy(), data.site("needle_tip").xpos.copy()
    solve_pose(model, data, {"arm_shaft": 0.05})
    assert data.site("crank_pin_center").xpos[1] < pin[1] - 1e-4
    assert data.site("needle_tip").xpos[2] < tip[2]


# --------------------------------------------------------------------------- motion


def analytic_needle(theta):
    """Needle point height [mm] and its first two derivatives per rad of arm angle from the
    parameter file: slider-crank with the needle-bar axis at y = 0, the arm shaft at
    y = -offset, TDC at arm angle 0, the needle point placed by the hook-timing rule."""
    r, L = param("crank", "radius"), param("link", "length")
    y_s = -param("needle_bar", "offset_y")

    def connector(phi):
        y = y_s - r * np.sin(phi)
        s = np.sqrt(L**2 - y**2)
        z = r * np.cos(phi) - s
        dy = -r * np.cos(phi)
        dz = -r * np.sin(phi) + y * dy / s
        ddy = r * np.sin(phi)
        dds = -(dy**2 + y * ddy) / s - (y * dy) ** 2 / s**3
        ddz = -r * np.cos(phi) - dds
        return z, dz, ddz

    grid = np.linspace(-np.pi, np.pi, 200001)
    phi_tdc = grid[np.argmax(connector(grid)[0])]
    stroke = connector(phi_tdc)[0] - connector(grid)[0].min()
    eye_top = param("needle", "eye_bottom_above_tip") + param("needle", "eye_length")
    hook_point_z = -(param("hook", "rim_below_plate") + param("hook", "point_below_rim"))
    tip_bdc = (
        hook_point_z
        - eye_top
        - param("hook", "point_above_eye")
        - param("hook", "needle_rise_at_passage")
    )
    z, dz, ddz = connector(theta + phi_tdc)
    return z - connector(phi_tdc)[0] + tip_bdc + stroke, dz, ddz


@pytest.fixture(scope="module")
def motion():
    return needle_motion(samples=360, speed_rpm=600)


def test_needle_position_velocity_and_acceleration_follow_the_analytic_slider_crank(motion):
    theta = np.radians(motion.arm_angle_deg)
    z, dz, ddz = analytic_needle(theta)
    assert np.abs(motion.needle_z_mm - z).max() < 0.05
    assert np.abs(motion.needle_velocity_mm_per_rad - dz).max() < 0.01 * np.abs(dz).max()
    assert np.abs(motion.needle_acceleration_mm_per_rad2 - ddz).max() < 0.01 * np.abs(ddz).max()
    # in-line slider-crank
    assert motion.stroke_mm == pytest.approx(2 * param("crank", "radius"), abs=0.01)
    assert motion.tdc_angle_deg == pytest.approx(0.0, abs=0.1)
    assert motion.bdc_angle_deg == pytest.approx(180.0, abs=0.1)


def test_hook_point_meets_the_needle_scarf_as_the_timing_rule_says(motion):
    assert motion.needle_rise_at_passage_mm == pytest.approx(
        param("hook", "needle_rise_at_passage"), abs=0.01
    )
    # the point runs `point_clearance` from the scarf bottom: measured on the needle's mesh
    assert motion.hook_point_clearance_mm == pytest.approx(
        param("hook", "point_clearance"), abs=0.005
    )
    eye_half = param("needle", "eye_length") / 2
    assert motion.hook_point_above_eye_mm - eye_half == pytest.approx(
        param("hook", "point_above_eye"), abs=0.01
    )
    # the hook turns twice per arm turn
    assert motion.hook_angle_deg[-1] + 2 * (
        motion.arm_angle_deg[1] - motion.arm_angle_deg[0]
    ) == pytest.approx(720.0)


def test_ten_arm_turns_turn_the_motor_80_the_lower_shaft_10_and_the_hook_20_times(model):
    spec = mujoco.MjSpec.from_file(str(DEFAULT_MODEL))
    drive = spec.add_actuator()
    drive.name, drive.target = "arm_drive", "arm_shaft"
    drive.trntype = mujoco.mjtTrn.mjTRN_JOINT
    drive.set_to_velocity(kv=0.5)  # N m s/rad at the arm: reaches speed in a few ms
    m = spec.compile()
    d = mujoco.MjData(m)
    solve_pose(m, d, {"arm_shaft": 0.0})
    q = {name: m.joint(name).qposadr[0] for name in ("arm_shaft", "motor", "lower_shaft", "hook")}
    start = {name: d.qpos[adr] for name, adr in q.items()}
    d.ctrl[0] = 2 * np.pi * 10  # 600 rpm at the arm
    while d.qpos[q["arm_shaft"]] - start["arm_shaft"] < 10 * 2 * np.pi:
        mujoco.mj_step(m, d)
        assert d.time < 5.0
    turns = {name: (d.qpos[adr] - start[name]) / (2 * np.pi) for name, adr in q.items()}
    arm = turns["arm_shaft"]
    assert turns["motor"] == pytest.approx(8 * arm, rel=1e-3)
    assert turns["lower_shaft"] == pytest.approx(arm, rel=1e-3)
    assert turns["hook"] == pytest.approx(2 * arm, rel=1e-3)
    # the loops held while running: the needle is where the kinematics puts it at this arm angle
    z_running = d.site("needle_tip").xpos[2]
    solve_pose(m, d, {"arm_shaft": d.qpos[q["arm_shaft"]]})
    assert z_running == pytest.approx(d.site("needle_tip").xpos[2], abs=5e-5)


def test_gravity_holding_torque_is_largest_after_bdc_and_smallest_on_the_way_down(model, motion):
    tables = compute_tables(model, "arm_shaft", "needle_tip", n=360)
    torque = tables.gravity_torque_Nm  # what the arm must supply to hold the machine still
    angle = np.degrees(tables.angle_rad)
    bdc = motion.bdc_angle_deg
    upstroke = (angle > bdc) & (angle < 360.0)
    hardest, easiest = angle[np.argmax(torque)], angle[np.argmin(torque)]
    assert torque.max() > 0 and bdc < hardest < bdc + 90.0  # lifting the needle bar out of BDC
    assert torque.min() < 0 and 0.0 < easiest < bdc  # gravity helps while the needle goes down
    assert (torque[upstroke] > -1e-3).all()
    # gravity explains at most the measured variation of the breakaway torque (thesis 5.2.2)
    static = thesis()["static_friction"]
    assert (
        torque.max() - torque.min()
        < static["highest_breakaway_arm_Nm"] - static["lowest_breakaway_arm_Nm"]
    )


# --------------------------------------------------------------------------- CLI


@pytest.mark.slow
def test_needle_cli_writes_the_table_and_the_plot(tmp_path, cli):
    csv, png = tmp_path / "needle.csv", tmp_path / "needle.png"
    result = cli("needle", "--csv", csv, "--plot", png, "--samples", "72", "--speed", "600")
    assert result.returncode == 0, result.stderr
    assert (
        "stroke: 33.000 mm" in result.stdout
        and "hook point passes the needle at shaft angle" in result.stdout
    )
    lines = [line for line in csv.read_text().splitlines() if not line.startswith("#")]
    assert lines[0].split(",") == [
        "arm_angle_deg",
        "needle_z_mm",
        "needle_velocity_mm_per_rad",
        "needle_acceleration_mm_per_rad2",
        "needle_velocity_mm_s",
        "needle_acceleration_mm_s2",
        "hook_angle_deg",
        "hook_point_to_needle_mm",
    ]
    assert len(lines) == 73
    assert png.stat().st_size > 10_000


@pytest.mark.parametrize(
    "args",
    [
        ("--samples", "5"),
        ("--speed", "-100"),
        ("--speed", "nan"),
        ("--model", "no/such/model.xml"),
    ],
)
def test_needle_cli_bad_input(tmp_path, cli_here, args):
    csv = tmp_path / "needle.csv"
    cli_here("needle", "--csv", csv, *args).assert_bad_input()
    assert not csv.exists()


def test_needle_cli_model_without_a_needle(tmp_path, cli_here):
    model = tmp_path / "pendulum.xml"
    model.write_text(
        '<mujoco><worldbody><body><joint name="arm_shaft"/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    line = cli_here("needle", "--model", model, "--csv", tmp_path / "n.csv").assert_bad_input()
    # the shipped roles do not fit it
    assert "motor_joint" in line and "close matches: arm_shaft" in line


@pytest.mark.slow
def test_no_two_parts_interpenetrate_over_a_revolution(model):
    """Exact mesh triangles (not MuJoCo's convex hulls) of every pair of bodies, at every
    2 degrees of arm angle: pins run in their bores with clearance, the hook point passes
    the needle's scarf, the take-up lever leaves the head through its slot."""
    from mechanism.kinematics.pose import sweep

    manager = trimesh.collision.CollisionManager()
    data = mujoco.MjData(model)
    geoms = [
        g
        for g in range(model.ngeom)
        if model.geom_group[g] == 3 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
    ]
    for g in geoms:
        mesh = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
        manager.add_object(
            str(g),
            trimesh.Trimesh(
                model.mesh_vert[v0 : v0 + nv], model.mesh_face[f0 : f0 + nf], process=False
            ),
        )
    clashes = set()
    for qpos in sweep(model, np.radians(np.arange(0, 360, 2.0)), "arm_shaft"):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        for g in geoms:
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g]
            manager.set_transform(str(g), T)
        _, pairs = manager.in_collision_internal(return_names=True)
        for a, b in pairs:
            if model.geom_bodyid[int(a)] != model.geom_bodyid[int(b)]:
                clashes.add(tuple(sorted((model.geom(int(a)).name, model.geom(int(b)).name))))
    assert not clashes
