"""The shipped servo arm (the third machine, a third kind): a geared servo lifts a loaded arm through
a four-bar against gravity between hard stops, and a pendulum hangs from the arm on a free pin.

Checked against closed forms computed here from the parameter file and the export's own mass
properties: the four-bar's output angle (Freudenstein's equation), the static holding torque over
the travel (virtual work through the four-bar, the pendulum hanging), the pendulum's period (a
compound pendulum) and the servo's step response (its linearised loop equation)."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
import tomllib
from pathlib import Path

import defusedxml.ElementTree as ET
import mujoco
import numpy as np
import pytest

import mechanism
from tests.helpers import mjcf as same_model
from mechanism.kinematics.pose import approach, solve_pose, velocity_ratios
from mechanism.physics.friction import FrictionLaw

REPO = Path(__file__).resolve().parent.parent
ASSETS = REPO / "assets"
CAD = ASSETS / "cad" / "servo_arm"
EXPORT = CAD / "export"
MODEL = ASSETS / "mjcf" / "servo_arm.xml"
PARAMS = json.loads((CAD / "servo_arm.params.json").read_text())
DESCRIPTION = tomllib.loads((ASSETS / "machines" / "servo_arm.toml").read_text())
NS = "{urn:mathworks:SimscapeMultibody:import}"
MM, GRAM, G = 1e-3, 1e-3, 9.81  # the MJCF's gravity (the converter's 9.81 m/s^2 against --up y)

MOTOR, HORN = "SERVO_CASE-1--MOTOR_ROTOR-1", "SERVO_CASE-1--SERVO_HORN-1"
ARM, PENDULUM = "FRAME-1--ARM-1", "ARM-1--PENDULUM-1"


def param(key: str) -> float:
    section, name = key.split(".")
    return PARAMS[section][name]["value"]


# the four-bar from the parameters (metres): crank (horn) a, coupler b, rocker (lever) c, ground d
A, B, C, D = (param(f"four_bar.{k}") * MM for k in ("crank", "coupler", "rocker", "ground"))
THETA2_0 = math.radians(param("four_bar.horn_angle_deg"))
RATIO = param("servo.gear_ratio")
SHEET = {key: entry["value"] for key, entry in PARAMS["datasheet"].items()}


def freudenstein(theta2):
    """The rocker angle (from the ground line O2 -> O4) of the open branch, coupler pin above the line."""
    k1, k2, k3 = D / A, D / C, (A * A - B * B + C * C + D * D) / (2 * A * C)
    big_a = np.cos(theta2) - k1 - k2 * np.cos(theta2) + k3
    big_b = -2 * np.sin(theta2)
    big_c = k1 - (k2 + 1) * np.cos(theta2) + k3
    return np.remainder(
        2 * np.arctan2(-big_b - np.sqrt(big_b**2 - 4 * big_a * big_c), 2 * big_a), 2 * np.pi
    )


def freudenstein_residual(theta2, theta4):
    """K1 cos θ4 - K2 cos θ2 + K3 - cos(θ2 - θ4), zero on every pose of the linkage."""
    k1, k2, k3 = D / A, D / C, (A * A - B * B + C * C + D * D) / (2 * A * C)
    return k1 * np.cos(theta4) - k2 * np.cos(theta2) + k3 - np.cos(theta2 - theta4)


THETA4_0 = float(freudenstein(THETA2_0))


def export_parts() -> dict[str, dict]:
    """instance -> mass [kg], centre of mass [m, part frame], inertia about it [kg m^2, part axes],
    and the part frame's origin [m, world at the assembly pose]."""
    root = ET.parse(EXPORT / "servo_arm.xml").getroot()
    assert root.find(f"{NS}DataUnits").attrib == {"length": "millimeter", "mass": "gram"}
    entities = {}
    for part in root.iter(f"{NS}Part"):
        props = part.find(f"{NS}MassProperties")
        ixx, iyy, izz, iyz, izx, ixy = (float(v) for v in props.find(f"{NS}Inertia").text.split())
        entities[part.get("uid")] = {
            "mass": float(props.find(f"{NS}Mass").text) * GRAM,
            "com": np.array([float(v) for v in props.find(f"{NS}CenterOfMass").text.split()]) * MM,
            "inertia": np.array([[ixx, ixy, izx], [ixy, iyy, iyz], [izx, iyz, izz]]) * GRAM * MM**2,
        }
    out = {}
    for inst in root.iter(f"{NS}Instance"):
        origin = np.array(
            [float(v) for v in inst.find(f"{NS}Transform/{NS}Translation").text.split()]
        )
        rotation = np.array(
            [float(v) for v in inst.find(f"{NS}Transform/{NS}Rotation").text.split()]
        )
        out[inst.get("name")] = {
            **entities[inst.get("entityUid")],
            "origin": origin * MM,
            "rotation": rotation.reshape(3, 3),
        }
    return out


PARTS = export_parts()


def _turn(angle, vector):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1]])


def potential(theta2):
    """V(θ2) = g Σ m y of every moving part's centre of mass, the pendulum hanging (its centre of
    mass straight below its pin: V moves with the pin). Planar (x, y) closed form from the
    four-bar: the horn turns about O2 by θ2 - θ2_0, the arm (with the payload bolted on) about O4
    by θ4 - θ4_0, the coupler's frame sits at the horn pin A, its x along A -> B."""
    theta2 = np.asarray(theta2, float)
    theta4 = freudenstein(theta2)
    o2, o4 = np.zeros(2), np.array([D, 0.0])
    pin_a = A * np.array([np.cos(theta2), np.sin(theta2)])
    pin_b = np.array([D + C * np.cos(theta4), C * np.sin(theta4)])
    theta3 = np.arctan2(pin_b[1] - pin_a[1], pin_b[0] - pin_a[0])

    def world(name):
        part = PARTS[name]
        return part["origin"][:2] + (part["rotation"] @ part["com"])[:2]

    def y_about(name, pivot, turn):
        return pivot[1] + _turn(turn, world(name) - pivot)[1]

    horn = PARTS["SERVO_HORN-1"]
    coupler = PARTS["COUPLER-1"]
    y = horn["mass"] * y_about("SERVO_HORN-1", o2, theta2 - THETA2_0)
    y = y + coupler["mass"] * (pin_a[1] + _turn(theta3, coupler["com"][:2])[1])
    for name in ("ARM-1", "PAYLOAD-1"):
        y = y + PARTS[name]["mass"] * y_about(name, o4, theta4 - THETA4_0)
    pin_p = PARTS["PENDULUM-1"]["origin"][:2]
    y = y + PARTS["PENDULUM-1"]["mass"] * (o4[1] + _turn(theta4 - THETA4_0, pin_p - o4)[1])
    return G * y


def holding_torque(theta2, h=1e-6):
    """The torque at the horn that holds the arm still: dV/dθ2 (virtual work), for one θ2."""
    return float(np.squeeze(potential(theta2 + h) - potential(theta2 - h)) / (2 * h))


@pytest.fixture(scope="module")
def machine():
    return mechanism.load_machine("servo_arm")


def _no_coulomb(pendulum_viscous: float) -> dict:
    """The described viscous friction with the Coulomb parts left out (a dead band makes a holding
    torque or a small step indeterminate within it); the pendulum's damping as given."""
    friction = DESCRIPTION["friction"]
    laws = {j: FrictionLaw(viscous=t.get("viscous_Nm_s_per_rad", 0.0)) for j, t in friction.items()}
    laws[PENDULUM] = FrictionLaw(viscous=pendulum_viscous)
    return laws


@pytest.fixture(scope="module")
def free_machine():
    """The servo arm without Coulomb friction, the pendulum's pin as described."""
    return mechanism.load_machine(
        "servo_arm", friction=_no_coulomb(SHEET["pendulum_viscous_Nm_s_per_rad"])
    )


def pendulum_numbers(model) -> tuple[float, float, float]:
    """(m, d, I about the pin) of the pendulum from the model's own body: its mass, the distance
    of its centre of mass from the pin axis (in the plane) and its inertia about that axis."""
    body = model.body("PENDULUM-1").id
    m = float(model.body_mass[body])
    jnt = model.joint(PENDULUM).id
    com = model.body_ipos[body] - model.jnt_pos[jnt]
    axis = model.jnt_axis[jnt]
    d = float(np.linalg.norm(com - (com @ axis) * axis))
    quat = model.body_iquat[body]
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, quat)
    rot = rot.reshape(3, 3)
    inertia = rot @ np.diag(model.body_inertia[body]) @ rot.T
    return m, d, float(axis @ inertia @ axis) + m * d * d


# --------------------------------------------------------------------------- the export and MJCF


def test_export_is_a_y_up_second_generation_export_with_mates_and_a_gear_mate():
    root = ET.parse(EXPORT / "servo_arm.xml").getroot()
    assert root.tag == f"{NS}SimscapeMultibodyImportXML" and root.get("version") == "2.0"
    assert root.find(f"{NS}RootAssembly/{NS}Joints") is None  # SolidWorks writes mates, not joints
    tags = {c.tag.removeprefix(NS) for c in root.find(f"{NS}RootAssembly/{NS}Constraints")}
    assert tags == {"Concentric", "Coincident", "GearConstraint"}
    gravity = np.array([float(v) for v in root.find(f"{NS}Gravity").text.split()])
    assert gravity[1] < 0 and not gravity[[0, 2]].any()
    from mechanism.converters.convert import detect_up
    from mechanism.converters.load import read

    assert detect_up(read(EXPORT / "servo_arm.xml"))[0] == "y"


def test_mates_become_a_four_bar_a_pendulum_and_the_gear_coupling(machine):
    model = machine.model
    hinge = int(mujoco.mjtJoint.mjJNT_HINGE)
    assert {model.joint(j).name: int(model.jnt_type[j]) for j in range(model.njnt)} == {
        name: hinge for name in (MOTOR, HORN, "SERVO_HORN-1--COUPLER-1", ARM, PENDULUM)
    }
    coupling = model.equality("coupling:GearMate1")
    # a three-stage external spur train: the horn turns against the motor
    assert coupling.data[:2] == pytest.approx([0.0, -RATIO])
    assert machine.motor_ratio == pytest.approx(RATIO) and machine.frame.direction == -1.0
    assert np.allclose(model.opt.gravity, [0, -G, 0])
    assert machine.passive_joints == [PENDULUM]
    assert not machine.rotates
    assert np.degrees(machine.shaft_span_rad) == pytest.approx([-45.0, 45.0])
    exported = sum(p["mass"] for p in PARTS.values())
    assert float(model.body_mass.sum()) == pytest.approx(exported, rel=1e-9)


def test_description_carries_the_parameter_files_datasheet():
    motor = DESCRIPTION["motor"][MOTOR]
    assert motor["type"] == "servo"
    for key in (
        "resistance_ohm",
        "torque_constant_Nm_per_A",
        "back_emf_V_s_per_rad",
        "supply_V",
        "kp_V_per_rad",
        "kd_V_s_per_rad",
    ):
        assert motor[key] == SHEET[key], key
    friction = DESCRIPTION["friction"]
    assert friction[MOTOR] == {
        "coulomb_Nm": SHEET["motor_coulomb_Nm"],
        "viscous_Nm_s_per_rad": SHEET["motor_viscous_Nm_s_per_rad"],
    }
    assert friction[HORN] == {
        "coulomb_Nm": SHEET["output_coulomb_Nm"],
        "viscous_Nm_s_per_rad": SHEET["output_viscous_Nm_s_per_rad"],
    }
    assert friction[PENDULUM] == {"viscous_Nm_s_per_rad": SHEET["pendulum_viscous_Nm_s_per_rad"]}
    assert DESCRIPTION["limits"][HORN] == {
        "lower_deg": SHEET["lower_deg"],
        "upper_deg": SHEET["upper_deg"],
    }


@pytest.mark.slow
def test_regenerating_the_export_and_the_mjcf_gives_the_committed_model(tmp_path):
    spec = importlib.util.spec_from_file_location("servo_arm_generator", CAD / "generate.py")
    generator = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = generator
    spec.loader.exec_module(generator)
    files = generator.build_export(generator.Params.load(CAD / "servo_arm.params.json"))[0]
    assert sorted(files) == sorted(p.name for p in EXPORT.iterdir())
    for name, data in files.items():
        assert data == (EXPORT / name).read_bytes(), name
    meshes = tmp_path / "meshes" / "servo_arm"
    mechanism.convert(
        EXPORT / "servo_arm.xml", tmp_path / "mjcf", name="servo_arm", mesh_dir=meshes, up="y"
    )
    assert same_model.difference(tmp_path / "mjcf" / "servo_arm.xml", MODEL) is None
    shipped = ASSETS / "meshes" / "servo_arm"
    assert sorted(p.name for p in meshes.iterdir()) == sorted(p.name for p in shipped.iterdir())
    for path in shipped.iterdir():
        assert (meshes / path.name).read_bytes() == path.read_bytes(), path.name


# --------------------------------------------------------------------------- closed forms


def _horn_and_lever(model, data) -> tuple[float, float]:
    """θ2 and θ4 (from the ground line) of the posed model, read from the parts' world frames."""

    def turned(site):
        xmat = data.site(site).xmat.reshape(3, 3)
        return math.atan2(xmat[1, 0], xmat[0, 0])

    return THETA2_0 + turned("SERVO_HORN-1"), THETA4_0 + turned("ARM-1")


def test_the_arm_follows_freudensteins_equation_over_the_travel(machine):
    """The pose solver on the converted model, horn over its whole travel: the lever's angle is
    Freudenstein's, and the equation's residual vanishes."""
    model, data = machine.model, mujoco.MjData(machine.model)
    low, high = model.jnt_range[model.joint(HORN).id]
    approach(model, data, HORN, float(low))
    errors, residuals = [], []
    for q in np.linspace(low, high, 37):
        solve_pose(model, data, {HORN: float(q)})
        theta2, theta4 = _horn_and_lever(model, data)
        assert theta2 == pytest.approx(THETA2_0 + q, abs=1e-12)
        errors.append(math.remainder(theta4 - float(freudenstein(theta2)), 2 * math.pi))
        residuals.append(float(freudenstein_residual(theta2, theta4)))
    assert max(map(abs, errors)) < 1e-8
    assert max(map(abs, residuals)) < 1e-8
    # the lever swings a good 50 degrees over the horn's 90
    assert math.degrees(float(freudenstein(THETA2_0 + high) - freudenstein(THETA2_0 + low))) > 50


def _hanging_pose(model, data, q_horn: float) -> None:
    """The linkage with the horn at ``q_horn`` and the pendulum hanging (not turned in the world)."""
    solve_pose(model, data, {HORN: q_horn})
    data.qpos[model.joint(PENDULUM).qposadr[0]] = -data.qpos[model.joint(ARM).qposadr[0]]
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)


def test_the_static_holding_torque_is_the_virtual_work_of_gravity_through_the_four_bar(machine):
    """MuJoCo's generalised gravity along the linkage's motion (pose solver, constraint-consistent
    joint velocities), the pendulum hanging, against dV/dθ2 from the closed form."""
    model, data = machine.model, mujoco.MjData(machine.model)
    low, high = model.jnt_range[model.joint(HORN).id]
    approach(model, data, HORN, float(low))
    errors, torques = [], []
    for q in np.linspace(low, high, 19):
        _hanging_pose(model, data, float(q))
        pin = data.site("PENDULUM-1").xpos
        com = data.xipos[model.body("PENDULUM-1").id]
        assert abs(com[0] - pin[0]) < 1e-12  # hangs straight down: no torque about its pin
        model_torque = float(velocity_ratios(model, data, HORN) @ data.qfrc_bias)
        expected = float(holding_torque(THETA2_0 + q))
        torques.append(expected)
        errors.append(abs(model_torque / expected - 1))
    assert max(errors) < 1e-7
    # the horn holds the arm up over the whole travel (positive θ2 lifts it)
    assert min(torques) > 0


@pytest.fixture(scope="module")
def held_machine():
    """The servo arm without Coulomb friction and with the pendulum's pin damped about critically,
    so that a held arm comes to rest with the pendulum hanging."""
    model = mechanism.load_machine("servo_arm").model
    m, d, inertia = pendulum_numbers(model)
    critical = 2 * math.sqrt(inertia * m * G * d)
    return mechanism.load_machine("servo_arm", friction=_no_coulomb(critical))


@pytest.mark.parametrize("shaft_deg", [-30.0, 0.0, 30.0])
def test_the_servo_holds_the_arm_with_the_closed_form_torque(held_machine, shaft_deg):
    """simulate: the servo holds where the run starts; at rest its motor current times Kt, through
    the gear, is the holding torque at the horn's angle (after the loop's sag)."""
    run = mechanism.simulate(
        held_machine, voltage_V={}, duration_s=0.8, start_angle_rad=math.radians(shaft_deg)
    )
    joints = run.joints
    q_horn = float(joints[f"{HORN}_pos_rad"][-1])
    assert abs(joints[f"{HORN}_vel_rad_s"][-1]) < 1e-4
    motor_torque = SHEET["torque_constant_Nm_per_A"] * float(run.current_A[-1])
    at_horn = motor_torque * -RATIO  # q_motor = -ratio q_horn: power balance
    assert at_horn == pytest.approx(float(holding_torque(THETA2_0 + q_horn)), rel=1e-3)
    # the loop sags by the torque over its stiffness at the horn, ratio² Kt kp / R
    stiffness = RATIO**2 * SHEET["torque_constant_Nm_per_A"] * SHEET["kp_V_per_rad"]
    sag = at_horn / (stiffness / SHEET["resistance_ohm"])
    start = held_machine.joint_position(math.radians(shaft_deg))
    assert q_horn - start == pytest.approx(-sag, rel=0.05)


def test_the_pendulum_swings_with_the_compound_pendulum_period(free_machine):
    """Arm held by the servo, the pendulum released a few degrees off vertical (it starts hanging
    as assembled, the arm turned): T = 2π sqrt(I_pin / (m g d)), the model's own m, d, I."""
    run = mechanism.simulate(
        free_machine, voltage_V={}, duration_s=1.2, start_angle_rad=math.radians(6.0)
    )
    t = run.time_s
    swing = run.joints[f"{ARM}_pos_rad"] + run.joints[f"{PENDULUM}_pos_rad"]  # in the world
    amplitude = float(np.max(np.abs(swing)))
    assert 0.02 < amplitude < 0.1
    up = np.flatnonzero((swing[:-1] < 0) & (swing[1:] >= 0))
    crossings = t[up] - swing[up] * (t[up + 1] - t[up]) / (swing[up + 1] - swing[up])
    assert len(crossings) >= 2
    measured = float(np.mean(np.diff(crossings)))
    m, d, inertia = pendulum_numbers(free_machine.model)
    expected = 2 * math.pi * math.sqrt(inertia / (m * G * d)) * (1 + amplitude**2 / 16)
    assert measured == pytest.approx(expected, rel=5e-4)


def _reflected(model, data) -> tuple[float, float]:
    """(J, G') at the motor at the posed state: the inertia along the linkage's motion per motor
    radian with the pendulum not turning (it hangs: a small step moves its pin straight up or
    down), and the gravity stiffness d²V/dq_motor² from the closed form."""
    v = velocity_ratios(model, data, MOTOR)
    v[model.joint(PENDULUM).dofadr[0]] = -v[model.joint(ARM).dofadr[0]]
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    h = 1e-4
    q = THETA2_0 + float(data.qpos[model.joint(HORN).qposadr[0]])
    curvature = (holding_torque(q + h) - holding_torque(q - h)) / (2 * h)
    return float(v @ mass @ v), float(curvature) / RATIO**2


def test_a_small_servo_step_follows_its_linearised_loop_equation(free_machine):
    """J q'' + c q' + (k + G') (q - q_eq) = 0 at the motor: k = Kt kp / R, c = Kt (kd + Ke) / R plus
    the viscous friction reflected to the motor, J the reflected inertia; from the assembly pose
    (the pendulum hanging) to the goal less the loop's sag under the arm's weight."""
    model = free_machine.model
    data = free_machine.reset(0.0)
    q0 = float(data.qpos[free_machine.motor_qpos])
    inertia, gravity_stiffness = _reflected(model, data)
    gravity = float(velocity_ratios(model, data, MOTOR) @ data.qfrc_bias)
    kt, r, ke = (
        SHEET[k] for k in ("torque_constant_Nm_per_A", "resistance_ohm", "back_emf_V_s_per_rad")
    )
    kp, kd = SHEET["kp_V_per_rad"], SHEET["kd_V_s_per_rad"]
    k = kt * kp / r + gravity_stiffness
    c = (
        kt * (kd + ke) / r
        + SHEET["motor_viscous_Nm_s_per_rad"]
        + SHEET["output_viscous_Nm_s_per_rad"] / RATIO**2
    )
    step = -RATIO * math.radians(1.5)  # the horn 1.5 deg up: 5.2 rad at the motor
    goal = q0 + step
    settled = q0 + (kt * kp / r * step - gravity) / k
    wn, zeta = math.sqrt(k / inertia), c / (2 * math.sqrt(k * inertia))
    assert 0.3 < zeta < 0.7  # underdamped: the overshoot is seen
    run = mechanism.simulate(free_machine, voltage_V={MOTOR: goal}, duration_s=0.2)
    t, q = run.time_s, run.joints[f"{MOTOR}_pos_rad"]
    wd = wn * math.sqrt(1 - zeta**2)
    expected = settled + (q0 - settled) * np.exp(-zeta * wn * t) * (
        np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t)
    )
    assert np.max(np.abs(q - expected)) < 0.01 * abs(step)
    volts = kp * (goal - q) - kd * run.joints[f"{MOTOR}_vel_rad_s"]
    assert np.max(np.abs(volts)) < SHEET["supply_V"]  # never saturated: the linear loop holds


# --------------------------------------------------------------------------- every verb


@pytest.mark.slow
def test_every_verb_runs_on_the_shipped_description(cli_here, tmp_path):
    runs = {
        "simulate": cli_here(
            "simulate",
            "--machine",
            "servo_arm",
            "--goal",
            f"{MOTOR}=-5",
            "--duration",
            "0.2",
            "--csv",
            tmp_path / "s.csv",
        ),
        "probe": cli_here(
            "probe",
            "--machine",
            "servo_arm",
            "--part",
            "PAYLOAD-1",
            "--quantity",
            "position",
            "--cycle",
            "--csv",
            tmp_path / "p.csv",
        ),
        "clearance": cli_here(
            "clearance",
            "--machine",
            "servo_arm",
            "--pairs",
            "COUPLER-1:SERVO_CASE-1",
            "--csv",
            tmp_path / "c.csv",
        ),
        "view": cli_here(
            "view", "--machine", "servo_arm", "--html", tmp_path / "v.html", "--frames", "5"
        ),
        "testbench": cli_here(
            "testbench",
            "--machine",
            "servo_arm",
            "--effect",
            "none",
            "--duration",
            "4",
            "-o",
            tmp_path / "rec.csv",
        ),
    }
    for verb, run in runs.items():
        assert run.returncode == 0, (verb, run.stderr)
    assert "pass" in runs["clearance"].stdout
    header = next(
        line for line in (tmp_path / "s.csv").read_text().splitlines() if not line.startswith("#")
    )
    assert f"{MOTOR}_input_rad" in header and f"{PENDULUM}_pos_rad" in header
    # a voltage is refused for the servo, in one line
    line = cli_here(
        "simulate", "--machine", "servo_arm", "--voltage", "5", "--duration", "0.1", "--summary"
    ).assert_bad_input()
    assert "--goal" in line
