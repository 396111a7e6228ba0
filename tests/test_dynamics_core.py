"""Motor, friction and simulation plumbing on a small hand-written machine (no CAD needed).

References: the thesis's lumped steady state (eq. 5 with the belt), Ohm's law for the
current, and statics for break-away.
"""

from pathlib import Path

import mujoco
import numpy as np
import pytest

from mechanism.physics.friction import FrictionLaw, python_friction
from mechanism.physics.inputs import VoltageProfile
from mechanism.errors import UserError
from mechanism.machine.machine import Machine, MachineConfig, duty_map_from
from mechanism.dynamics.simulation import simulate
from tests.helpers.machines import shipped_description
from tests.helpers.machines import thesis_motor, velocities_with_passive


PWM = duty_map_from(shipped_description())

TOY = Path(__file__).parent / "models" / "toy_sewing_machine.xml"
TOY_MACHINE = TOY.with_suffix(".toml")
KT, KE, R, N = 0.017, 0.021, 1.1, 8


def lumped_steady_rpm(voltage, coulomb_arm=0.18, viscous_motor=2.2e-5):
    motor = (KT / R * voltage - coulomb_arm / N) / (KT * KE / R + viscous_motor)
    return motor / N * 60 / (2 * np.pi)


def no_position_friction():
    return {
        "arm_shaft": FrictionLaw(
            coulomb=0.18, static=0.2394, stribeck="tustin", stribeck_velocity=0.5
        )
    }


@pytest.fixture(scope="module")
def toy():
    return Machine(TOY_MACHINE, MachineConfig(friction=no_position_friction()))


@pytest.mark.parametrize("voltage", [4.48, 12.49, 19.6])
def test_steady_speed_and_current_follow_the_thesis_motor_equations(toy, voltage):
    result = simulate(voltage, 3.0, machine=toy)
    summary = result.speed_summary(1.0)
    # The toy's linkage makes the speed ripple a little; its mean follows eq. 5 with the belt.
    assert summary["mean_rpm"] == pytest.approx(lumped_steady_rpm(voltage), rel=0.01)
    last = result.window(1.0)
    expected_current = (voltage - KE * result.motor_velocity_rad_s[last]) / R
    np.testing.assert_allclose(result.current_A[last], expected_current, atol=0.02)


def test_dcmotor_keeps_kt_and_ke_distinct():
    # <dcmotor> alone would use K = sqrt(Kt Ke) for both: torque at stall must be Kt V / R.
    spec = mujoco.MjSpec.from_file(str(TOY))
    thesis_motor().add_to_spec(spec, joint="motor", name="motor")
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[0] = 10.0
    mujoco.mj_forward(model, data)
    assert data.actuator_force[0] == pytest.approx(KT / R * 10.0, rel=1e-9)


@pytest.mark.slow
def test_machine_sticks_below_break_away_and_starts_above():
    no_gravity = Machine(
        TOY_MACHINE, MachineConfig(friction={"arm_shaft": FrictionLaw(coulomb=0.18, static=0.24)})
    )
    no_gravity.model.opt.gravity[:] = 0
    # Stall torque at the arm is N Kt V / R: break-away at V = 0.24 R / (N Kt).
    breakaway_V = 0.24 * R / (N * KT)
    stuck = simulate(0.97 * breakaway_V, 2.0, machine=no_gravity)
    moving = simulate(1.03 * breakaway_V, 2.0, machine=no_gravity)
    assert abs(stuck.arm_angle_rad[-1] - stuck.arm_angle_rad[0]) < 2e-3
    assert moving.arm_angle_rad[-1] - moving.arm_angle_rad[0] > 1.0


def test_python_fallback_matches_the_compiled_callback():
    laws = {
        "arm_shaft": FrictionLaw(
            coulomb=0.18,
            static=0.26,
            stribeck="hess-soom",
            stribeck_velocity=2.0,
            position_amplitude=0.1,
            static_position_amplitude=0.03,
            position_phase_rad=1.0,
        )
    }
    compiled = Machine(TOY_MACHINE, MachineConfig(friction=laws))
    reference = simulate(
        VoltageProfile(np.array([0.0, 0.3]), np.array([3.0, 6.0])), 0.6, machine=compiled
    )
    # Same model, friction stepped in Python instead of C.
    velocities = velocities_with_passive(
        compiled, python_friction, lambda t: 3.0 if t < 0.3 else 6.0, 0.6
    )
    np.testing.assert_allclose(velocities, reference.arm_velocity_rad_s, atol=1e-6)


def test_pwm_duty_follows_table_2_and_rejects_out_of_range():
    assert PWM(50) == pytest.approx(12.49)
    assert PWM(25) == pytest.approx((4.48 + 7.0) / 2)
    # The thesis started the machine at 12-14 % duty, where the current-drive break-away
    # torques 0.2384 / 0.2771 N m need T R / (8 Kt) at the motor terminals.
    assert PWM(12) == pytest.approx(0.2384 * R / (N * KT))
    assert PWM(14) == pytest.approx(0.2771 * R / (N * KT))
    assert 0 < PWM(5) < PWM(12)
    with pytest.raises(UserError):
        PWM(120)


def test_bad_durations_and_voltages_are_user_errors(toy):
    with pytest.raises(UserError, match="duration"):
        simulate(5.0, -1.0, machine=toy)
    with pytest.raises(UserError, match="outside"):
        simulate(31.0, 1.0, machine=toy)


@pytest.mark.parametrize("rest_angle", [0.0, np.pi])
def test_break_away_follows_the_static_position_amplitude(rest_angle):
    # Static level 0.24 (1 + 0.1 cos θ): 0.264 N m at θ = 0, 0.216 N m at θ = π; the running
    # amplitude (0.3 here) must not change when the machine starts.
    law = FrictionLaw(
        coulomb=0.18, static=0.24, position_amplitude=0.3, static_position_amplitude=0.1
    )
    machine = Machine(TOY_MACHINE, MachineConfig(friction={"arm_shaft": law}))
    machine.model.opt.gravity[:] = 0
    breakaway_V = law.static_at(rest_angle) * R / (N * KT)
    assert law.static_at(rest_angle) == pytest.approx(0.24 * (1 + 0.1 * np.cos(rest_angle)))
    stuck = simulate(0.98 * breakaway_V, 1.5, machine=machine, start_angle_rad=rest_angle)
    moving = simulate(1.02 * breakaway_V, 1.5, machine=machine, start_angle_rad=rest_angle)
    assert abs(stuck.arm_angle_rad[-1] - rest_angle) < 2e-3
    assert moving.arm_angle_rad[-1] - rest_angle > 0.5


@pytest.mark.parametrize("kernel", ["machine", "reduced"])
def test_each_compiled_kernel_has_the_python_stribeck_law_point_by_point(kernel):
    """One law, written in Python (FrictionLaw.stribeck_shape) and in C: the same numbers."""
    import ctypes

    from mechanism import native
    from mechanism.physics.friction import STRIBECK_LAWS

    library = native.load(kernel)
    if library is None:
        pytest.skip("no C compiler: the Python twin runs instead")
    shape = library.mechanism_stribeck_shape
    shape.restype = ctypes.c_double
    shape.argtypes = [ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.c_double]
    for law in ("tustin", "hess-soom", "none"):
        for vs, delta in ((0.5, 1.0), (2.0, 0.6), (7.0, 2.0)):
            python = FrictionLaw(
                coulomb=0.1, static=0.2, stribeck=law, stribeck_velocity=vs, tustin_exponent=delta
            )
            for v in np.linspace(-30.0, 30.0, 61):
                assert shape(STRIBECK_LAWS[law], v, vs, delta) == pytest.approx(
                    float(python.stribeck_shape(v)), abs=1e-15
                )
