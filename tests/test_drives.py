"""Several motors and drive kinds: [motor."JOINT"] tables, dc / servo / current drives, their inputs
on the command line and in a profile, and the per-joint CSV columns. Checked against closed forms
on two disks turning about vertical axes (no gravity torque): a servo's step response from its loop
equation, a current drive's constant acceleration, a dc motor's no-load speed."""

import math
import textwrap

import numpy as np
import pytest

DISKS = """\
<mujoco model="disks">
  <compiler angle="radian"/>
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="table"><geom name="table" type="box" size="0.2 0.1 0.01" pos="0 0 -0.02" mass="2"/></body>
    <body name="disk_a" pos="-0.1 0 0">
      <joint name="spin_a" type="hinge" axis="0 0 1"/>
      <geom name="disk_a" type="cylinder" size="0.05 0.005" mass="0.4"/>
      <site name="rim_a" pos="0.05 0 0"/>
    </body>
    <body name="disk_b" pos="0.1 0 0">
      <joint name="spin_b" type="hinge" axis="0 0 1"/>
      <geom name="disk_b" type="cylinder" size="0.05 0.005" mass="0.4"/>
    </body>
  </worldbody>
</mujoco>
"""
INERTIA = 0.5 * 0.4 * 0.05**2  # a uniform disk about its axis [kg m^2]
HEAD = """\
[machine]
name = "disks"
model = "disks.xml"
[drive]
shaft_joint = "spin_a"
zero_angle_deg = 0.0
"""


def _machine(folder, motors: str):
    (folder / "disks.xml").write_text(DISKS)
    path = folder / "disks.toml"
    path.write_text(HEAD + textwrap.dedent(motors))
    return path


SERVO_A = """
    [motor."spin_a"]
    type = "servo"
    resistance_ohm = 4.0
    torque_constant_Nm_per_A = 0.02
    back_emf_V_s_per_rad = 0.02
    supply_V = 6.0
    kp_V_per_rad = 20.0
    kd_V_s_per_rad = 0.05
    [motor."spin_b"]
    type = "current"
    torque_constant_Nm_per_A = 0.05
    """


def test_motor_tables_parse_with_the_first_as_the_main_motor(tmp_path):
    from mechanism.machine.description import read_description

    described = read_description(_machine(tmp_path, SERVO_A))
    assert described.motor_joint == "spin_a" and list(described.motors) == ["spin_a", "spin_b"]
    assert described.motors["spin_b"]["type"] == "current"


@pytest.mark.parametrize(
    "motors, fragment",
    [
        (
            '[motor."spin_a"]\ntype = "servo"\nresistance_ohm = 4.0\ntorque_constant_Nm_per_A = 0.02\n'
            "back_emf_V_s_per_rad = 0.02\nkp_V_per_rad = 20.0\n",
            "supply_V: missing",
        ),
        (
            '[motor."spin_a"]\ntype = "current"\ntorque_constant_Nm_per_A = 0.02\nresistance_ohm = 1.0\n',
            "not a key of a current drive",
        ),
        (
            '[motor]\ntype = "dc"\nresistance_ohm = 1.0\ntorque_constant_Nm_per_A = 0.02\nback_emf_V_s_per_rad = 0.02\n',
            "motor_joint: missing",
        ),
        (
            '[motor]\ntype = "dc"\n[motor."spin_a"]\ntype = "current"\ntorque_constant_Nm_per_A = 0.02\n',
            "not both",
        ),
    ],
)
def test_bad_motor_tables_are_one_error_line(tmp_path, cli_here, motors, fragment):
    path = _machine(tmp_path, motors)
    line = cli_here(
        "simulate", "--machine", path, "--voltage", "5", "--duration", "0.1", "--summary"
    ).assert_bad_input()
    assert fragment in line


@pytest.mark.slow
def test_a_servo_step_follows_its_loop_equation(tmp_path, cli):
    """Small step (no voltage limit): J q'' = Kt/R (kp (g - q) - (kd + Ke) q'), a damped second-order
    response with wn^2 = Kt kp / (R J) and 2 zeta wn = Kt (kd + Ke) / (R J)."""
    path = _machine(tmp_path, SERVO_A)
    goal = 0.05
    result = cli(
        "simulate",
        "--machine",
        path,
        "--goal",
        f"spin_a={goal}",
        "--duration",
        "0.4",
        "--csv",
        tmp_path / "run.csv",
    )
    assert result.returncode == 0, result.stderr
    lines = [
        line for line in (tmp_path / "run.csv").read_text().splitlines() if not line.startswith("#")
    ]
    header = lines[0].split(",")
    table = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    column = {name: table[:, i] for i, name in enumerate(header)}
    for name in (
        "spin_a_pos_rad",
        "spin_a_vel_rad_s",
        "spin_b_pos_rad",
        "spin_a_input_rad",
        "spin_a_current_A",
        "spin_b_input_A",
        "spin_b_current_A",
    ):
        assert name in column, name
    t, q = column["time_s"], column["spin_a_pos_rad"]
    kt, r, kp, kd, ke = 0.02, 4.0, 20.0, 0.05, 0.02
    wn = math.sqrt(kt * kp / (r * INERTIA))
    zeta = kt * (kd + ke) / (r * INERTIA) / (2 * wn)
    assert zeta < 1  # underdamped: the test sees the overshoot
    wd = wn * math.sqrt(1 - zeta**2)
    expected = goal * (
        1
        - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))
    )
    assert np.max(np.abs(q - expected)) < 0.01 * goal
    # never saturated
    assert np.max(np.abs(kp * (goal - q) - kd * column["spin_a_vel_rad_s"])) < 6.0
    assert column["spin_a_input_rad"] == pytest.approx(goal)
    # the current is the motor's: (V - Ke w) / R
    current = (
        kp * (goal - q) - kd * column["spin_a_vel_rad_s"] - ke * column["spin_a_vel_rad_s"]
    ) / r
    assert column["spin_a_current_A"] == pytest.approx(current, abs=1e-9)


def test_a_large_servo_step_is_limited_by_its_supply(tmp_path):
    """A 2 rad step asks 40 V of a 6 V supply: the motor starts at its stall torque Kt 6 / R."""
    import mechanism
    from mechanism.dynamics.simulation import simulate

    machine = mechanism.load_machine(_machine(tmp_path, SERVO_A))
    result = simulate({"spin_a": 2.0}, 0.02, machine=machine)
    velocity = result.joints["spin_a_vel_rad_s"]
    early = result.time_s < 0.003
    acceleration = np.polyfit(result.time_s[early], velocity[early], 1)[0]
    assert acceleration == pytest.approx(0.02 * 6.0 / 4.0 / INERTIA, rel=0.05)
    assert np.max(np.abs(result.joints["spin_a_current_A"])) <= 6.0 / 4.0 + 1e-9


@pytest.mark.slow
def test_two_motors_each_take_their_own_input(tmp_path, cli):
    """A dc motor on one disk, a current drive on the other: the dc disk runs up towards its
    no-load speed V / Ke as 1 - exp(-t / tau), the current-driven one accelerates at Kt i / J."""
    motors = """
        [motor."spin_a"]
        type = "dc"
        resistance_ohm = 4.0
        torque_constant_Nm_per_A = 0.02
        back_emf_V_s_per_rad = 0.02
        [motor."spin_b"]
        type = "current"
        torque_constant_Nm_per_A = 0.05
        max_current_A = 2.0
        """
    path = _machine(tmp_path, motors)
    profile = tmp_path / "inputs.csv"
    profile.write_text("time_s,spin_a_V,spin_b_A\n0,3.0,0.2\n0.5,3.0,5.0\n")
    result = cli(
        "simulate",
        "--machine",
        path,
        "--profile",
        profile,
        "--duration",
        "1.0",
        "--csv",
        tmp_path / "run.csv",
    )
    assert result.returncode == 0, result.stderr
    lines = [
        line for line in (tmp_path / "run.csv").read_text().splitlines() if not line.startswith("#")
    ]
    header = lines[0].split(",")
    table = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    column = {name: table[:, i] for i, name in enumerate(header)}
    t = column["time_s"]
    tau = INERTIA * 4.0 / (0.02 * 0.02)  # the mechanical time constant J R / (Kt Ke): 5 s
    assert column["spin_a_vel_rad_s"] == pytest.approx(
        3.0 / 0.02 * (1 - np.exp(-t / tau)), rel=0.01, abs=1e-3
    )
    first = t < 0.5
    slope = np.polyfit(t[first], column["spin_b_vel_rad_s"][first], 1)[0]
    assert slope == pytest.approx(0.05 * 0.2 / INERTIA, rel=0.01)
    later = t > 0.55
    slope = np.polyfit(t[later], column["spin_b_vel_rad_s"][later], 1)[0]
    assert slope == pytest.approx(0.05 * 2.0 / INERTIA, rel=0.01)  # 5 A asked, 2 A given
    assert column["spin_b_current_A"][-1] == pytest.approx(2.0)
    # the same on the command line
    again = cli(
        "simulate",
        "--machine",
        path,
        "--voltage",
        "spin_a=3",
        "--current",
        "spin_b=0.2",
        "--duration",
        "0.3",
        "--summary",
    )
    assert again.returncode == 0, again.stderr
    wrong = cli(
        "simulate", "--machine", path, "--goal", "spin_b=1", "--duration", "0.3", "--summary"
    ).assert_bad_input()
    assert "--current spin_b=" in wrong


@pytest.mark.slow
def test_probe_and_view_take_the_inputs_of_every_motor(tmp_path, cli):
    path = _machine(tmp_path, SERVO_A)
    probe = cli(
        "probe",
        "--machine",
        path,
        "--part",
        "disk_a",
        "--quantity",
        "position",
        "--goal",
        "spin_a=0.3",
        "--current",
        "spin_b=0.1",
        "--duration",
        "0.2",
        "--csv",
        tmp_path / "p.csv",
    )
    assert probe.returncode == 0, probe.stderr
    view = cli(
        "view",
        "--machine",
        path,
        "--goal",
        "spin_a=0.3",
        "--duration",
        "0.2",
        "--frames",
        "10",
        "--html",
        tmp_path / "v.html",
    )
    assert view.returncode == 0, view.stderr
    line = cli(
        "probe",
        "--machine",
        path,
        "--part",
        "disk_a",
        "--quantity",
        "position",
        "--voltage",
        "5",
        "--duration",
        "0.2",
        "--csv",
        tmp_path / "q.csv",
    ).assert_bad_input()
    assert "--goal spin_a=" in line


def test_the_servo_limit_python_twin_matches_the_compiled_callback(tmp_path):
    """Both callbacks add Kt/R (clip(V) - V) on the servo's joint; a saturated state tells them apart
    from doing nothing."""
    import mujoco

    import mechanism
    from mechanism.physics.motor import python_servo_limit

    machine = mechanism.load_machine(_machine(tmp_path, SERVO_A))
    if not machine.native:
        pytest.skip("no C compiler: only the Python twin is in use")
    model, data = machine.model, machine.data
    joint = model.joint("spin_a")
    data.qpos[joint.qposadr[0]], data.qvel[joint.dofadr[0]] = 0.1, 3.0
    # 20 (2 - 0.1) - 0.05 x 3 = 37.85 V asked of 6 V
    data.ctrl[model.actuator("drive_motor").id] = 2.0
    mujoco.mj_forward(model, data)
    native = data.qfrc_passive[joint.dofadr[0]]
    data.qfrc_passive[:] = 0.0
    python_servo_limit(model, data)
    twin = data.qfrc_passive[joint.dofadr[0]]
    assert twin == pytest.approx(0.02 / 4.0 * (6.0 - 37.85))
    assert native == pytest.approx(twin, rel=1e-9)


def test_a_recording_with_one_input_column_per_motor_is_read_for_the_main_motor(tmp_path):
    from mechanism.sysid.recording import read_recording

    t = np.arange(0, 3.0, 0.001)
    rows = "\n".join(f"{x:.3f},{6.0:.3f},{0.5:.3f},{x:.6f},{0.1 * x:.6f}" for x in t)
    path = tmp_path / "bench.csv"
    path.write_text("time_s,spin_a_V,spin_b_A,shaft_angle,spin_b_angle\n" + rows + "\n")
    recording = read_recording(path, motor_joint="spin_a")
    assert recording.voltage_V == pytest.approx(np.full(len(t), 6.0))
    assert recording.arm_angle_rad == pytest.approx(t, abs=1e-6)
