"""Sensor probes against the analytic slider-crank and hand-calculated static loads."""

import mujoco
import numpy as np
import pytest

from tests.helpers import mechanisms as M
from mechanism.kinematics.cycle import cycle_angles, kinematic_cycle, set_state
from mechanism.errors import UserError
from mechanism.inspection.probes import Probe, parse_probes, probe_cycle

RPM = 600.0
OMEGA = RPM * 2 * np.pi / 60


@pytest.fixture(scope="module")
def needle_cycle():
    probes = [Probe("needle_tip", q) for q in ("position", "velocity", "acceleration")]
    probes.append(Probe("needle_bar", "position", point_mm=(0, 0, -M.TIP_BELOW_BAR * 1e3)))
    return probe_cycle(
        M.needle_and_plate(), probes, speed_rpm=RPM, resolution_deg=2.0, driver="arm_shaft"
    ).columns


def test_needle_tip_position_velocity_acceleration(needle_cycle):
    theta = needle_cycle["arm_shaft_angle_rad"]
    np.testing.assert_allclose(
        needle_cycle["needle_tip_z_mm"], M.needle_tip_z(theta) * 1e3, atol=0.01
    )
    np.testing.assert_allclose(needle_cycle["needle_tip_x_mm"], M.OFFSET * 1e3, atol=1e-6)
    np.testing.assert_allclose(
        needle_cycle["needle_tip_vz_m_s"], OMEGA * M.needle_tip_dz(theta), atol=1e-6
    )
    acceleration = OMEGA**2 * M.needle_tip_d2z(theta)
    np.testing.assert_allclose(
        needle_cycle["needle_tip_az_m_s2"], acceleration, atol=1e-5 * np.abs(acceleration).max()
    )
    np.testing.assert_allclose(needle_cycle["time_s"], theta / OMEGA)


def test_point_in_the_part_frame(needle_cycle):
    """The bar's frame moved down by the tip offset is the needle tip."""
    label = Probe("needle_bar", "position", point_mm=(0, 0, -M.TIP_BELOW_BAR * 1e3)).label
    np.testing.assert_allclose(
        needle_cycle[f"{label}_z_mm"], needle_cycle["needle_tip_z_mm"], atol=1e-9
    )


def _static_loads(theta, rod_mass=1e-7):
    """Static probes with a (nearly) massless rod, and the hand calculation."""
    spec = M.needle_and_plate(rod_mass=rod_mass)
    probes = [
        Probe("needle_bar", "force"),  # the slide joint: the needle-bar bushing
        Probe("crank_pin", "force"),  # tree hinge joint between crank and rod
        Probe("rod_end", "force"),  # loop joint (two connects) between rod and needle bar
        Probe("arm_shaft", "torque"),
    ]
    columns = probe_cycle(
        spec, probes, speed_rpm=0.0, resolution_deg=theta / 3, driver="arm_shaft"
    ).columns
    row = {name: values[3] for name, values in columns.items()}  # the sample at theta
    model = spec.compile()
    weight = -model.opt.gravity[2] * model.body("needle_bar").subtreemass
    z_slider = M.needle_tip_z(np.radians(theta)) + M.TIP_BELOW_BAR
    crank_pin = np.array([M.R * np.sin(np.radians(theta)), 0, M.R * np.cos(np.radians(theta))])
    rod = (np.array([0, 0, z_slider]) - crank_pin) / M.L  # unit vector crank pin -> slider pin
    push = weight / rod[2]  # compression in the two-force rod
    return row, weight, rod, push


@pytest.mark.parametrize("theta", [40.0, 120.0])
def test_static_bearing_loads_match_the_hand_calculation(theta):
    row, weight, rod, push = _static_loads(theta)
    # bushing: the lateral force W tan(phi) that balances the rod's push; nothing along the slide
    assert row["needle_bar_Fx_N"] == pytest.approx(weight * -rod[0] / rod[2], rel=0.01)
    assert abs(row["needle_bar_Fz_N"]) < 1e-3 * weight
    # crank pin: the crank pushes the rod along its axis with W / cos(phi)
    for axis, component in zip("xz", (0, 2)):
        assert row[f"crank_pin_F{axis}_N"] == pytest.approx(push * rod[component], rel=0.01)
    assert row["crank_pin_F_N"] == pytest.approx(push, rel=0.01)
    # the loop joint at the rod's end: the needle bar pushes back on the rod (body1)
    assert row["rod_end_Fx_N"] == pytest.approx(-push * rod[0], rel=0.01)
    assert row["rod_end_Fz_N"] == pytest.approx(-push * rod[2], rel=0.01)
    # holding torque under gravity, by virtual work: tau = W dz/dtheta
    holding = weight * M.needle_tip_dz(np.radians(theta))
    assert row["arm_shaft_drive_torque_Nm"] == pytest.approx(holding, rel=0.01)
    assert row["arm_shaft_My_Nm"] == pytest.approx(holding, rel=0.01)


def test_drive_torque_is_the_rate_of_change_of_energy():
    """Over a constant-speed cycle with real masses, tau = dE/dtheta (no friction)."""
    model = M.needle_and_plate().compile()
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    angles = cycle_angles(1.0, 1.0)
    states = kinematic_cycle(model, angles, OMEGA, "arm_shaft", data)
    torque, energy = [], []
    for i in range(len(angles)):
        torque.append(
            set_state(model, data, states.qpos[i], states.qvel[i], states.qacc[i], "arm_shaft")
        )
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        energy.append(data.energy.sum())
    torque, energy = np.array(torque), np.array(energy)
    step = angles[1] - angles[0]
    rate = (np.roll(energy, -1) - np.roll(energy, 1)) / (2 * step)  # periodic central difference
    assert np.abs(rate - torque).max() < 1e-3 * np.abs(torque).max()
    assert abs(torque.mean()) < 1e-6 * np.abs(torque).max()  # no net work over a revolution


def test_bad_probe_names_and_quantities():
    with pytest.raises(UserError, match="close matches: needle_tip"):
        probe_cycle(M.needle_and_plate(), [Probe("needle_tpi", "position")], driver="arm_shaft")
    with pytest.raises(UserError, match="close matches.*crank_pin"):
        probe_cycle(M.needle_and_plate(), [Probe("crank_pn", "force")], driver="arm_shaft")
    with pytest.raises(UserError, match="unknown probe quantity"):
        Probe("needle_tip", "jerk")
    with pytest.raises(UserError, match="X,Y,Z"):
        Probe("needle_tip", "position", point_mm=(1, 2))
    with pytest.raises(UserError, match="X,Y,Z"):
        parse_probes(["needle_tip"], ["position"], ["1,2"])
    with pytest.raises(
        UserError, match="no joint given"
    ):  # it was a TypeError in the 'close matches' hint
        probe_cycle(M.needle_and_plate(), [Probe("needle_tip", "position")], driver=None)


def test_dynamic_probes_obey_newtons_law_on_the_needle_bar():
    """Probes along a dynamic simulation (motor, friction): bushing + rod + weight = m a."""
    from pathlib import Path

    from mechanism.inspection.probes import probe_simulation

    toy = Path(__file__).parent / "models" / "toy_sewing_machine.toml"
    probes = [
        Probe("needle_bar_bushing", "force"),  # tree slide joint
        Probe("a", "force"),  # the two loop connects (loads on their body1, the crank link)
        Probe("b", "force"),
        Probe("needle_bar", "acceleration", point_mm=(0, 0, -30)),  # its centre of mass
    ]
    columns = probe_simulation(probes, voltage=12.0, duration_s=0.3, description=toy).columns
    mass = 0.08
    assert np.abs(columns["needle_bar_at_0_0_-30_az_m_s2"]).max() > 5.0  # it really moves
    for axis, gravity in (("x", 0.0), ("z", -9.81)):
        total = (
            columns[f"needle_bar_bushing_F{axis}_N"]
            - columns[f"a_F{axis}_N"]
            - columns[f"b_F{axis}_N"]
            + mass * gravity
        )
        inertial = mass * columns[f"needle_bar_at_0_0_-30_a{axis}_m_s2"]
        assert (
            np.abs(total - inertial).max()
            < 0.01 * np.abs(mass * columns["needle_bar_at_0_0_-30_az_m_s2"]).max() + 1e-6
        )
