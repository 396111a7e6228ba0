"""The motor's optional physics against locked-rotor references: the electrical time
constant L/R, the cogging torque's shape, and the winding's thermal steady state."""

import mujoco
import numpy as np
import pytest
from scipy.optimize import brentq

from mechanism.physics.motor import DCMotor, Thermal, motor_current

R, KT, KE = 1.1, 0.017, 0.021
LOCKED = """<mujoco><option timestep="0.0001" integrator="implicitfast"/><worldbody><body>
  <joint name="motor" type="hinge" axis="1 0 0"/><inertial pos="0 0 0" mass="1" diaginertia="1e6 1e6 1e6"/>
</body></worldbody></mujoco>"""  # a rotor that cannot turn in the test's time: locked

from tests.helpers.machines import thesis_motor


def locked(motor: DCMotor, angle: float = 0.0):
    spec = mujoco.MjSpec.from_string(LOCKED)
    motor.add_to_spec(spec, joint="motor", name="motor")
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[0] = angle
    return model, data


def test_winding_inductance_gives_the_electrical_time_constant():
    inductance = 0.002
    model, data = locked(thesis_motor(inductance_H=inductance))
    data.ctrl[0] = 5.0
    tau = inductance / R
    for _ in range(int(round(tau / model.opt.timestep))):
        mujoco.mj_step(model, data)
    # i(t) = V/R (1 - exp(-t/tau)): 63.2 % of the stall current after one time constant
    assert motor_current(
        model, data, thesis_motor(inductance_H=inductance), "motor"
    ) == pytest.approx(5.0 / R * (1 - np.exp(-1)), rel=0.01)


@pytest.mark.parametrize("angle", [0.0, 0.05, 0.2, 1.0])
def test_cogging_torque_has_twelve_periods_per_motor_turn(angle):
    motor = thesis_motor(cogging_Nm=0.002, cogging_phase_rad=0.3)
    model, data = locked(motor, angle)
    mujoco.mj_forward(model, data)  # no voltage, no speed: only the cogging torque
    assert data.actuator_force[0] == pytest.approx(0.002 * np.sin(12 * angle + 0.3), abs=1e-12)
    assert motor_current(model, data, motor, "motor") == pytest.approx(0.0, abs=1e-12)


def test_winding_heats_to_rth_times_copper_loss_and_the_current_falls():
    thermal = Thermal(resistance_K_W=8.0, time_constant_s=0.05)
    motor = thesis_motor(thermal=thermal)
    model, data = locked(motor)
    data.ctrl[0] = 1.5
    for _ in range(int(1.0 / model.opt.timestep)):  # 20 time constants
        mujoco.mj_step(model, data)
    alpha = thermal.tempcoef_per_K
    # steady state: dT = Rth * V^2 / R(T) with R(T) = R (1 + alpha dT)
    rise = brentq(lambda t: t - thermal.resistance_K_W * 1.5**2 / (R * (1 + alpha * t)), 0.0, 500.0)
    assert data.act[0] == pytest.approx(rise, rel=0.01)
    assert motor_current(model, data, motor, "motor") == pytest.approx(
        1.5 / (R * (1 + alpha * rise)), rel=0.01
    )
