"""The pose solver against the analytic slider-crank (closed loop + belt coupling)."""

import mujoco
import numpy as np
import pytest

from mechanism.errors import UserError
from mechanism.kinematics.pose import PoseError, solve_pose, sweep, velocity_ratios

R, L = 0.0165, 0.05  # crank radius and rod length [m]

SLIDER_CRANK = f"""
<mujoco>
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="motor" pos="0.1 0 0">
      <joint name="motor" type="hinge" axis="0 1 0"/>
      <geom type="cylinder" size="0.01 0.01" mass="0.1"/>
    </body>
    <body name="crank">
      <joint name="arm_shaft" type="hinge" axis="0 1 0"/>
      <geom type="cylinder" size="0.02 0.005" mass="0.2" euler="90 0 0"/>
      <body name="rod" pos="0 0 {R}">
        <joint name="crank_pin" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 {L}" size="0.003" mass="0.02"/>
      </body>
    </body>
    <body name="slider" pos="0 0 {R + L}">
      <joint name="bushing" type="slide" axis="0 0 1"/>
      <geom type="cylinder" size="0.004 0.03" mass="0.05"/>
    </body>
  </worldbody>
  <equality>
    <connect name="loop:pin_a" body1="rod" body2="slider" anchor="0 0.01 {L}"/>
    <connect name="loop:pin_b" body1="rod" body2="slider" anchor="0 -0.01 {L}"/>
    <joint name="coupling:belt" joint1="motor" joint2="arm_shaft" polycoef="0 8 0 0 0"/>
  </equality>
</mujoco>
"""


def slider_z(theta):
    return R * np.cos(theta) + np.sqrt(L**2 - (R * np.sin(theta)) ** 2)


def slider_dz(theta):
    s, c = np.sin(theta), np.cos(theta)
    return -R * s - R**2 * s * c / np.sqrt(L**2 - (R * s) ** 2)


@pytest.fixture
def model():
    return mujoco.MjModel.from_xml_string(SLIDER_CRANK)


def test_sweep_matches_analytic_slider_crank_and_belt_ratio(model):
    angles = np.linspace(0, 2 * np.pi, 361)
    poses = sweep(model, angles, "arm_shaft")
    slide = poses[:, model.joint("bushing").qposadr[0]]
    np.testing.assert_allclose(slide + R + L, slider_z(angles), atol=1e-9)
    motor = poses[:, model.joint("motor").qposadr[0]]
    np.testing.assert_allclose(motor, 8 * angles, atol=1e-9)


def test_velocity_ratios_are_the_analytic_derivative(model):
    data = mujoco.MjData(model)
    for theta in np.linspace(0.1, 6.2, 13):
        solve_pose(model, data, {"arm_shaft": theta})
        ratios = velocity_ratios(model, data, "arm_shaft")
        assert ratios[model.joint("bushing").dofadr[0]] == pytest.approx(slider_dz(theta), abs=1e-9)
        assert ratios[model.joint("motor").dofadr[0]] == pytest.approx(8.0, abs=1e-9)


def test_unreachable_pose_and_unknown_joint_are_user_errors(model):
    data = mujoco.MjData(model)
    with pytest.raises(
        PoseError
    ):  # pulling the slider beyond the rod's reach cannot close the loop
        solve_pose(model, data, {"arm_shaft": 0.0, "bushing": 0.02})
    with pytest.raises(UserError, match="close matches: arm_shaft"):
        solve_pose(model, data, {"arm_shft": 0.0})
