"""Passive joints and runaways: joints the motor does not drive are simulated as they are (gravity,
limits, damping); one without a limit or damping is named in a warning; a body that leaves the
machine ends the run with one error naming its joint and the simulated time."""

import math
import textwrap

import numpy as np
import pytest

ARM_MJCF = """\
<mujoco model="arm">
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="stand">
      <geom name="stand" type="box" size="0.05 0.05 0.01" mass="1"/>
      <site name="stand"/>
    </body>
    <body name="arm" pos="0 0 0.1">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom name="arm" type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.2"/>
      <site name="arm_tip" pos="0.2 0 0"/>
      <body name="bob" pos="0.2 0 0">
        <joint name="swing" type="hinge" axis="0 1 0"/>
        <geom name="bob" type="sphere" pos="{bob}" size="0.01" mass="0.05"/>
        <site name="bob" pos="{bob}"/>
      </body>
      <body name="ball" pos="0.1 0 0.03">
        <joint name="roll" type="slide" axis="1 0 0"/>
        <geom name="ball" type="sphere" size="0.01" mass="0.02"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _arm(folder, extra="", bob_deg=0.0):
    """``bob_deg``: the pendulum's bob placed that far about the swing axis (its pose at swing = 0)."""
    angle = math.radians(bob_deg)
    (folder / "arm.xml").write_text(
        ARM_MJCF.replace("{bob}", f"{0.1 * math.sin(angle):.9g} 0 {-0.1 * math.cos(angle):.9g}")
    )
    path = folder / "arm.toml"
    path.write_text(
        textwrap.dedent("""\
        [machine]
        name = "arm"
        model = "arm.xml"
        [drive]
        motor_joint = "shoulder"
        shaft_joint = "shoulder"
        zero_site = "arm_tip"
        [motor]
        type = "dc"
        resistance_ohm = 2.0
        torque_constant_Nm_per_A = 0.05
        back_emf_V_s_per_rad = 0.05
        [limits."shoulder"]
        lower_deg = 0.0
        upper_deg = 30.0
        """)
        + textwrap.dedent(extra)
    )
    return path


def test_passive_joints_without_limit_or_damping_are_named_once(tmp_path):
    import mechanism

    with pytest.warns(UserWarning) as caught:
        machine = mechanism.load_machine(_arm(tmp_path))
    assert set(machine.passive_joints) == {"swing", "roll"}
    named = [str(w.message) for w in caught if "passive joint" in str(w.message)]
    assert any("swing" in text for text in named) and any("roll" in text for text in named)
    assert not any("shoulder" in text for text in named)


def test_a_limited_or_damped_passive_joint_is_not_warned_about(tmp_path):
    import warnings

    import mechanism

    extra = """
        [limits."roll"]
        lower_mm = -90.0
        upper_mm = 90.0
        [friction."swing"]
        viscous_Nm_s_per_rad = 0.001
        """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        machine = mechanism.load_machine(_arm(tmp_path, extra))
    assert not [w for w in caught if "passive joint" in str(w.message)]
    roll = machine.model.joint("roll").id
    assert machine.model.jnt_limited[roll] and machine.model.jnt_range[roll] == pytest.approx(
        [-0.09, 0.09]
    )


@pytest.mark.slow
def test_a_ball_that_rolls_off_ends_the_run_naming_its_joint_and_time(tmp_path, cli):
    path = _arm(tmp_path)
    result = cli("simulate", "--machine", path, "--voltage", "0", "--duration", "4", "--summary")
    line = result.assert_bad_input()
    assert "roll" in line and "t = " in line and " s" in line
    assert "np.float64" not in line
    assert "warning: passive joint" in result.stderr


def test_a_held_ball_stays_and_the_pendulum_swings_at_its_period(tmp_path):
    """The arm rests on its upper stop (30 deg down) under gravity, the ball between its stops; the
    pendulum (a 10 mm ball at L = 0.1 m), released 3 deg off its hanging pose, swings with the
    small-oscillation period 2 pi sqrt(I / (m g L)), I = m (L^2 + 2/5 r^2)."""
    import mechanism
    from mechanism.dynamics.simulation import simulate

    extra = """
        [limits."roll"]
        lower_mm = -90.0
        upper_mm = 90.0
        """
    # 3 deg off hanging on the arm tilted 30 deg
    machine = mechanism.load_machine(_arm(tmp_path, extra, bob_deg=27.0))
    swing = machine.model.joint("swing")
    result = simulate(0.0, 2.0, machine=machine, start_angle_rad=math.radians(30.0))
    assert np.degrees(result.arm_angle_rad) == pytest.approx(30.0, abs=1.0)  # held by its stop
    angle = result.state[:, 1 + swing.qposadr[0]] + math.radians(3.0)  # 0 where it hangs
    # small oscillations (the ball's landing on its stop adds a little)
    assert np.max(np.abs(angle)) < math.radians(6.0)
    crossings = result.time_s[1:][(angle[:-1] < 0) & (angle[1:] >= 0)]
    crossings = crossings[crossings > 0.5]
    period = float(np.mean(np.diff(crossings)))
    length, radius = 0.1, 0.01
    expected = 2 * math.pi * math.sqrt((length**2 + 0.4 * radius**2) / (9.81 * length))
    assert period == pytest.approx(expected, rel=0.01)
    ball = machine.model.joint("roll").qposadr[0]
    # the ball stays between its stops
    assert np.all(np.abs(result.state[:, 1 + ball]) <= 0.09 + 1e-3)


def test_the_runaway_guard_names_an_overspeeding_motor():
    import mechanism
    from mechanism.dynamics.simulation import runaway_guard
    from mechanism.errors import UserError

    machine = mechanism.load_machine("press")
    guard = runaway_guard(machine, np.array([12.0]))
    nq = machine.model.nq
    states = np.zeros((10, 1 + nq + machine.model.nv))
    states[:, 1 : 1 + nq] = machine.model.qpos0
    guard(states, 0.0)  # at rest: fine
    states[5:, 1 + nq + machine.motor_dof] = 3 * 12.0 / machine.motor.back_emf_V_s_rad
    with pytest.raises(UserError, match=rf"{machine.motor_joint} turned at .* rpm at t = 0\.003"):
        guard(states, 0.0)
