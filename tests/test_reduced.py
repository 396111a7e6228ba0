"""The reduced 1-DOF model: its tables against MuJoCo's own energies, and its motion
against the full multibody simulation."""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from mechanism.physics.inputs import VoltageProfile
from mechanism.kinematics.pose import solve_pose, velocity_ratios
from mechanism.machine.machine import Machine
from mechanism.dynamics.reduced import ReducedModel
from mechanism.kinematics.linkage import compute_tables, periodic_derivative
from mechanism.dynamics.simulation import simulate

TOY = Path(__file__).parent / "models" / "toy_sewing_machine.xml"
TOY_MACHINE = TOY.with_suffix(".toml")


@pytest.fixture(scope="module")
def model():
    m = mujoco.MjModel.from_xml_string(TOY.read_text())
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    return m


def test_tables_agree_with_mujoco_energies(model):
    tables = compute_tables(model, "arm_shaft", "needle_tip", n=360)
    data = mujoco.MjData(model)
    potential = []
    for angle, inertia in zip(tables.angle_rad[::15], tables.inertia_kgm2[::15]):
        solve_pose(model, data, {"arm_shaft": angle})
        data.qvel[:] = 2.5 * velocity_ratios(model, data, "arm_shaft")  # arm at 2.5 rad/s
        mujoco.mj_forward(model, data)
        # Kinetic energy of every body, computed by MuJoCo, equals ½ J(θ) ω².
        assert data.energy[1] == pytest.approx(0.5 * inertia * 2.5**2, rel=1e-9)
    for angle in tables.angle_rad:
        solve_pose(model, data, {"arm_shaft": angle})
        mujoco.mj_forward(model, data)
        potential.append(data.energy[0])
    # Gravity torque is the slope of MuJoCo's potential energy over the revolution.
    np.testing.assert_allclose(
        tables.gravity_torque_Nm, periodic_derivative(np.array(potential)), atol=1e-6
    )


def test_spectral_derivative_is_exact_for_harmonics():
    angle = np.arange(64) * 2 * np.pi / 64
    np.testing.assert_allclose(
        periodic_derivative(np.sin(3 * angle) + 0.5 * np.cos(angle)),
        3 * np.cos(3 * angle) - 0.5 * np.sin(angle),
        atol=1e-12,
    )


@pytest.fixture(scope="module")
def machine():
    return Machine(TOY_MACHINE)


def profile():
    return VoltageProfile(np.array([0, 1.0, 2.0, 3.0, 3.5]), np.array([4.0, 12.0, 20.0, 0.0, 7.0]))


def test_reduced_model_tracks_the_full_model_within_one_percent(machine):
    full = simulate(profile(), 5.0, machine=machine)
    reduced = ReducedModel(machine).simulate(profile(), 5.0)
    error = reduced.arm_velocity_rad_s - full.arm_velocity_rad_s
    rms = np.sqrt(np.mean(error**2)) / np.sqrt(np.mean(full.arm_velocity_rad_s**2))
    assert rms < 0.01
    stopped = (full.time_s > 3.2) & (full.time_s < 3.5)  # 0 V: both at rest
    assert np.all(reduced.arm_velocity_rad_s[stopped] == 0.0)


def test_python_fallback_matches_the_compiled_kernel(machine):
    reduced = ReducedModel(machine)
    compiled = reduced.simulate(profile(), 0.5)
    out = np.zeros((500, 3))
    volts = profile()(np.arange(1000) * 0.0005)
    reduced._run_python(volts, 0.0005, 2, 0.0, 0.0, out)
    np.testing.assert_allclose(out[:, 1], compiled.arm_velocity_rad_s, atol=1e-8)
