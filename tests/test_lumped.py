"""The lumped drive kernel against analytic solutions and the thesis's numbers."""

import math

import numpy as np
import pytest

from mechanism.dynamics.lumped import (
    Drive,
    MotorConstants,
    Segments,
    Signals,
    angle_from_velocity,
    lagged_voltage,
    simulate,
    simulate_numpy,
    windowed_dot,
)
from mechanism.sysid.lumped_baseline import LumpedBaseline
from mechanism.data.reference import thesis

from tests.helpers.nominal import SAPPHIRE

DT = 1e-3


def one_segment(n):
    return Segments(np.array([0]), n, np.array([0]), np.array([n]), np.array([True]))


def signals_for(voltage, angle=None):
    n = len(voltage)
    t = np.arange(n) * DT
    return Signals(
        t, np.asarray(voltage, float), np.zeros(n) if angle is None else angle, np.zeros(n), DT, 8.0
    )


def thesis_drive(voltage, warm=False):
    ref = thesis()["identified_parameters"]
    s = signals_for(voltage)
    d = ref["viscous_warm_Nm_s_per_rad" if warm else "viscous_cold_Nm_s_per_rad"]
    return Drive.constant(
        s, s.voltage_V, ref["total_inertia_kgm2"] * 64, d * 64, ref["kinetic_friction_arm_Nm"]
    )


def test_steady_state_speeds_match_the_formula_and_thesis_table_2():
    ref = thesis()
    table = np.array(ref["steady_state_speed_table_2"]["rows"], float)
    motor = SAPPHIRE.motor
    for volts, rpm_cold in zip(table[:, 1], table[:, 4]):
        drive = thesis_drive(np.full(3000, volts))
        w = simulate(drive, motor, one_segment(3000), np.zeros(1), DT)[0]
        c = motor.emf_damping_arm + drive.viscous_Nm_s[0]
        analytic = (motor.gain_arm * volts - drive.coulomb_Nm[0]) / c
        assert w[-1] == pytest.approx(analytic, rel=1e-6)
        if volts <= 20:  # the thesis's model is valid to 20 V: within 5 % of its own Table 2
            assert w[-1] * 60 / (2 * math.pi) == pytest.approx(rpm_cold, rel=0.05)


def test_step_response_time_constant_is_J_over_total_damping():
    drive = thesis_drive(np.full(2000, 12.0))
    drive.coulomb_Nm[:] = 0.0
    motor = SAPPHIRE.motor
    w = simulate(drive, motor, one_segment(2000), np.zeros(1), DT)[0]
    c = motor.emf_damping_arm + drive.viscous_Nm_s[0]
    tau = drive.inertia_kgm2[0] / c
    t = np.arange(2000) * DT
    np.testing.assert_allclose(
        w, motor.gain_arm * 12 / c * (1 - np.exp(-t / tau)), rtol=1e-9, atol=1e-9
    )


def test_stick_below_breakaway_and_stop_at_zero_voltage():
    motor = SAPPHIRE.motor
    fc = thesis()["identified_parameters"]["kinetic_friction_arm_Nm"]
    breakaway_V = fc / motor.gain_arm
    u = np.r_[np.full(500, 0.95 * breakaway_V), np.full(1500, 10.0), np.zeros(1500)]
    w = simulate(thesis_drive(u), motor, one_segment(len(u)), np.zeros(1), DT)[0]
    assert np.all(w[:501] == 0.0)  # stuck below the breakaway voltage
    assert w[1900] > 40
    assert np.all(w[-500:] == 0.0)  # stopped by Coulomb friction, and stays stopped
    assert np.all(w >= 0.0)  # never reverses


def test_native_kernel_equals_numpy_fallback_with_every_term_and_a_belt():
    rng = np.random.default_rng(1)
    n = 4000
    u = np.repeat(rng.uniform(0, 20, 8), n // 8)
    drive = thesis_drive(u)
    angle = np.cumsum(np.full(n, 0.05))
    drive.tau_arm_Nm += 0.02 * np.sin(angle)
    drive.tau_motor_Nm += 0.03 * np.sin(8 * angle)
    drive.coulomb_Nm += 0.01 * np.cos(angle)
    drive.static_excess_Nm += 0.05
    drive.quadratic_Nm_s2 += 1e-5 * np.cos(2 * angle)
    drive.inertia_kgm2 += 2e-5 * np.sin(2 * angle)
    seg = Segments(
        np.array([0, 1000, 2500]),
        1400,
        np.array([0, 100, 100]),
        np.array([1100, 1200, 1400]),
        np.array([True] * 3),
    )
    w0 = np.array([0.0, 30.0, 5.0])
    motor = SAPPHIRE.motor
    native = simulate(drive, motor, seg, w0, DT)
    np.testing.assert_allclose(
        native, simulate_numpy(drive, motor, seg, w0, DT), rtol=1e-10, atol=1e-10
    )
    drive.belt_stiffness_Nm_rad, drive.belt_damping_Nm_s, drive.motor_inertia_kgm2 = (
        40.0,
        0.01,
        5e-4,
    )
    np.testing.assert_allclose(
        simulate(drive, motor, seg, w0, DT),
        simulate_numpy(drive, motor, seg, w0, DT),
        rtol=1e-9,
        atol=1e-9,
    )


def test_the_compiled_angle_and_differentiator_equal_numpy_and_the_calculus(monkeypatch):
    """The trapezoid integral (bit for bit: the same operations in the same order) and the
    windowed differentiator of the fitting path, compiled and in numpy; a quadratic angle
    comes back as its exact derivative."""
    from mechanism.dynamics import lumped
    from mechanism.sysid.recording import velocity_coefficients

    rng = np.random.default_rng(3)
    w = rng.normal(20.0, 5.0, (7, 900))
    start = rng.uniform(-3.0, 300.0, 7)
    c = velocity_coefficients(DT)
    first = np.sort(rng.choice(7 * 900 - len(c), 500, replace=False))
    assert lumped._signal_kernels() is not None, "the test needs the compiled kernel"
    compiled_angle = angle_from_velocity(w, DT, start)
    compiled_velocity = windowed_dot(compiled_angle, first, c)
    monkeypatch.setattr(lumped, "_signal_kernels", lambda: None)
    angle = angle_from_velocity(w, DT, start)
    np.testing.assert_array_equal(compiled_angle, angle)
    np.testing.assert_allclose(
        compiled_velocity, windowed_dot(angle, first, c), rtol=1e-12, atol=1e-9
    )
    with pytest.raises(ValueError, match="beyond the signal"):
        windowed_dot(angle, np.array([7 * 900 - len(c) + 1]), c)
    # w = a + b t: trapezoids integrate it exactly, and the differentiator gives w back
    t = np.arange(900) * DT
    line = (4.0 + 30.0 * t)[None, :]
    exact = 1.5 + 4.0 * t + 15.0 * t**2
    np.testing.assert_allclose(angle_from_velocity(line, DT, np.array([1.5]))[0], exact, atol=1e-12)
    inner = np.arange(len(c), 900 - len(c))
    np.testing.assert_allclose(
        windowed_dot(exact, inner - len(c) // 2, c), line[0, inner], rtol=1e-9
    )


def test_belt_rings_at_its_analytic_resonance():
    motor = MotorConstants(1e9, 0.017, 0.021, 8.0)  # no electrical damping: a free two-mass system
    n = 4000
    drive = Drive.constant(signals_for(np.zeros(n)), np.zeros(n), 2e-3, 0.0, 0.0)
    jm, k = 6e-4, 30.0
    drive.belt_stiffness_Nm_rad, drive.motor_inertia_kgm2 = k, jm
    drive.tau_motor_Nm[:5] = -2.0  # a short kick on the motor
    w = simulate(drive, motor, one_segment(n), np.zeros(1), DT)[0]
    spectrum = np.abs(np.fft.rfft(w[100:] - w[100:].mean()))
    f = np.fft.rfftfreq(len(w) - 100, DT)
    expected = math.sqrt(k * (1 / jm + 1 / (2e-3 - jm))) / (2 * math.pi)
    assert f[np.argmax(spectrum)] == pytest.approx(expected, abs=0.5)


@pytest.mark.parametrize("use_native", [True, False])
def test_across_free_play_the_arm_coasts_and_the_motor_carries_the_viscous_friction(use_native):
    """The model's viscous friction is the motor's (its bearings; the thesis's b_m, referred to
    the motor): where a belt's free play separates motor and arm, the motor slows under it and the
    back-emf while the arm, with no Coulomb friction and no load, coasts at its speed exactly
    (with the viscous friction on the arm it slowed by c/J_arm, 2.5 % in these 20 ms)."""
    n = 200
    viscous, arm, motor_share = 1e-3, 2e-3, 5e-4
    drive = Drive.constant(signals_for(np.zeros(n)), np.zeros(n), arm, viscous, 0.0)
    drive.belt_stiffness_Nm_rad, drive.motor_inertia_kgm2 = 30.0, motor_share
    drive.belt_gap_rad = 1.0  # wide: no contact for the first tens of milliseconds
    motor = MotorConstants(1.1, 0.017, 0.021, 8.0)
    w = simulate(drive, motor, one_segment(n), np.array([50.0]), DT, use_native=use_native)[0]
    assert np.all(w[:20] == 50.0)
    # the motor's own deceleration (back-emf and viscous) closes the gap: later the arm is braked
    assert w[-1] < 50.0


def test_position_dependent_inertia_conserves_energy():
    # Without friction or drive, J(theta) w^2 / 2 is constant. Close the loop around the
    # kernel one step at a time (the diagnosis drives it with the measured angle instead).
    j0, a, w = 2e-3, 4e-4, 20.0
    motor = MotorConstants(1e12, 0.017, 0.021, 8.0)  # no motor damping
    theta, energy = 0.0, []
    for _ in range(1500):
        mid = theta + 0.5 * DT * w  # predictor for the mid-step angle
        s = signals_for(np.zeros(2), np.array([theta, 2 * mid - theta]))
        drive = Drive.constant(s, s.voltage_V, j0, 0.0, 0.0)
        drive.inertia_kgm2 = j0 + a * np.cos(2 * s.drive_angle_rad)
        drive.quadratic_Nm_s2 = -a * np.sin(2 * s.drive_angle_rad)
        w_next = simulate(drive, motor, one_segment(2), np.array([w]), DT)[0][1]
        theta += 0.5 * (w + w_next) * DT
        w = w_next
        energy.append(0.5 * (j0 + a * np.cos(2 * theta)) * w * w)
    energy = np.array(energy)
    assert theta > 4 * math.pi  # several swings of the inertia
    assert np.ptp(energy) < 2e-3 * energy.mean()  # kinetic energy exchanged, not lost or made


def test_lagged_voltage_is_the_exact_first_order_step_average():
    u = np.r_[np.zeros(10), np.full(40, 10.0)]
    tau = 3e-3
    y = lagged_voltage(u, tau, DT)
    k = np.arange(40)
    # average of 10 (1 - exp(-t/tau)) over [k dt, (k+1) dt]
    exact = 10 * (1 - tau / DT * (np.exp(-k * DT / tau) - np.exp(-(k + 1) * DT / tau)))
    np.testing.assert_allclose(y[10:], exact, rtol=1e-12)
    assert np.all(y[:10] == 0)
    assert lagged_voltage(u, 1e-9, DT) is u


def test_a_lag_on_a_few_windows_is_the_lag_on_the_whole_recording_read_there():
    """A part's windows (a few, spread over a long recording, one at its very start) get their
    winding lag from stretches around them alone: the whole recording's values to rounding, for
    every time constant, also where the stretches are most of the recording (then the whole)."""
    rng = np.random.default_rng(3)
    n = 20_000
    whole = signals_for(np.cumsum(rng.normal(0, 0.3, n)) + 12.0)
    whole.velocity_rad_s[:] = np.cumsum(rng.normal(0, 1.0, n))
    windows = [
        np.arange(0, 700),
        np.arange(4000, 5270),
        np.arange(9000, 10270),
        np.arange(19000, n),
    ]
    few = whole.subset(np.concatenate(windows))
    most = whole.subset(np.arange(100, n - 100))
    for tau in (1e-9, 1e-4, 1.3e-3, 0.02):
        for part in (few, most):
            index = part.parent_index
            np.testing.assert_allclose(
                part.lagged(tau), lagged_voltage(whole.voltage_V, tau, DT)[index], rtol=1e-14
            )
            speed = part.lag_filtered(
                "lagged_speed", tau, tau, lambda w: w.velocity_rad_s, lambda w: w * w
            )
            assert np.array_equal(speed, whole.velocity_rad_s[index] ** 2)
        # a window's own stretch: its first samples are read from the start of the recording on
        assert few._stretches(3) is not None and most._stretches(3) is None
    # windows laid end to end out of order still read their own samples
    shuffled = whole.subset(np.concatenate(windows[::-1]))
    np.testing.assert_allclose(
        shuffled.lagged(2e-3),
        lagged_voltage(whole.voltage_V, 2e-3, DT)[shuffled.parent_index],
        rtol=1e-14,
    )


def test_signals_advanced_by_a_delay_read_the_log_that_much_later():
    """A sensor delay: the machine's angle at t is the logged one at t + delay. On a steady
    turn (angle linear in time) linear interpolation is exact, also between samples and past
    the log's end; a window of the signals is the same window of the advanced whole."""
    n, speed = 200, 40.0
    t = np.arange(n) * DT
    angle = 0.3 + speed * t
    whole = Signals(t, np.full(n, 12.0), angle, np.full(n, speed), DT, 8.0)
    assert whole.advanced(0.0) is whole
    for delay in (2e-3, 3.7e-3, 0.05):
        ahead = whole.advanced(delay)
        np.testing.assert_allclose(ahead.arm_angle_rad, angle + speed * delay, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ahead.velocity_rad_s, speed)
        assert np.array_equal(ahead.voltage_V, whole.voltage_V)
        # the voltage is not delayed: its winding lag is the logged one's, computed once for every delay
        assert ahead.lagged(1e-3) is whole.lagged(1e-3)
        window = np.arange(150, 200)
        part = whole.subset(window)
        np.testing.assert_allclose(
            part.advanced(delay).arm_angle_rad, ahead.arm_angle_rad[window], rtol=0, atol=1e-12
        )
        np.testing.assert_allclose(
            part.advanced(delay).drive_angle_rad, ahead.drive_angle_rad[window], rtol=0, atol=1e-12
        )
    # between samples: a ramp of the velocity is read at the fraction of a sample
    ramp = Signals(t, np.zeros(n), np.zeros(n), t.copy(), DT, 8.0)
    np.testing.assert_allclose(ramp.advanced(2.5e-3).velocity_rad_s[:-3], t[:-3] + 2.5e-3)


def test_baseline_parameters_carry_the_thesis_numbers():
    base = LumpedBaseline(SAPPHIRE)
    nominal = {p.name: p.nominal for p in base.parameters}
    ref = thesis()["identified_parameters"]
    assert nominal["inertia_motor_side_kgm2"] == pytest.approx(ref["total_inertia_kgm2"], rel=1e-12)
    assert nominal["coulomb_arm_Nm"] == ref["kinetic_friction_arm_Nm"]
    assert {"R", "Kt"} <= set(LumpedBaseline(SAPPHIRE, ("R", "Kt")).free)


def test_baseline_bounds_scale_with_the_described_machine():
    """A press of 20x the inertia and a 12:1 gear gets starting values and bounds 20x/144
    the sewing machine's on the motor side: nothing of the sewing machine is left in them."""
    from tests.helpers.nominal import PRESS

    small = {p.name: p for p in LumpedBaseline(SAPPHIRE).parameters}
    large = {p.name: p for p in LumpedBaseline(PRESS).parameters}
    k = 20 * 64 / 144
    for key in ("nominal", "lower", "upper"):
        assert getattr(large["inertia_motor_side_kgm2"], key) == pytest.approx(
            k * getattr(small["inertia_motor_side_kgm2"], key)
        )
    assert large["coulomb_arm_Nm"].upper == pytest.approx(6 * small["coulomb_arm_Nm"].upper)


def _cos_sin_exactly(order: float, angle: float) -> tuple[float, float]:
    """cos/sin(order * angle) of the double ``angle``, the product and the reduction by 2 pi
    done in 60 digits (the reference a float64 evaluation is judged against)."""
    from decimal import Decimal, localcontext
    from fractions import Fraction

    with localcontext() as c:
        c.prec = 60
        two_pi = 2 * Decimal("3.14159265358979323846264338327950288419716939937510582097494")
        k = Fraction(order)
        phase = Decimal(k.numerator) / Decimal(k.denominator) * Decimal(angle) % two_pi
    return math.cos(float(phase)), math.sin(float(phase))


def test_harmonics_of_whole_orders_are_as_accurate_as_the_angle_allows():
    """cos/sin(k angle) of a 60 s run at 100 rad/s (6000 rad, 1e6 rad at the 192nd order): whole
    orders (negative ones too) come from powers of exp(i angle), within 1e-13 of the exact value
    for the rounded angle, where trigonometry of the rounded product k angle is 1e-10 off at order
    192; fractional orders from their definition, within that product's rounding."""
    n = 60_000
    t = np.arange(n) * DT
    s = Signals(t, np.zeros(n), 0.3 + 100.0 * t, np.full(n, 100.0), DT, 8.0)
    mid = s.drive_angle_rad
    at = [0, 1, 777, 31_337, n - 1]
    for order in (1, 2, 3, 5, 8, 16, 96, 192, 8.0, -3, 2.5, 0.37):
        cos, sin = s.harmonic(order, "cos"), s.harmonic(order, "sin")
        exact = np.array([_cos_sin_exactly(order, float(mid[i])) for i in at])
        tolerance = 1e-13 if float(order).is_integer() else 1e-13 + np.spacing(order * mid[at])
        assert np.all(np.abs(cos[at] - exact[:, 0]) < tolerance), order
        assert np.all(np.abs(sin[at] - exact[:, 1]) < tolerance), order


def test_remembered_effect_arrays_follow_every_parameter(tmp_path):
    """The needle's load, the linkage's inertia terms and the harmonic sums are remembered per
    parameter values on the signals: after any one parameter moves, the drive built on signals
    that remember earlier values is the one built on fresh signals, array for array."""
    from mechanism.sysid.identification import Problem, fit_baseline
    from mechanism.sysid.recording import read_recording
    from mechanism.testbench import write_recording

    from tests.helpers.nominal import bench_recording, effects

    path = tmp_path / "bench.csv"
    write_recording(bench_recording("torque_ripple", seed=2, duration_s=8.0), path)
    recording = read_recording(path)
    base = fit_baseline(Problem(recording, SAPPHIRE), "lumped")
    names = ("needle_penetration", "linkage_dynamics", "position_friction", "torque_ripple")
    structure = base.structure
    values = dict(base.values)
    for name in names:
        effect = effects()[name]
        structure = structure.with_effect(effect)
        values.update(
            {p.name: p.nominal if p.nominal else 0.3 * p.scale for p in effect.parameters}
        )
    remembering = Problem(recording, SAPPHIRE).signals
    structure.drive(values, remembering)
    for name in names:
        for parameter in effects()[name].parameters:
            moved = {**values, parameter.name: values[parameter.name] + 0.1 * parameter.scale}
            warm = structure.drive(moved, remembering).per_sample()
            cold = structure.drive(moved, Problem(recording, SAPPHIRE).signals).per_sample()
            for a, b in zip(warm, cold):
                np.testing.assert_array_equal(a, b, err_msg=parameter.name)
            # and back: the first values' arrays again, not the moved ones'
            again = structure.drive(values, remembering).per_sample()
            first = structure.drive(values, Problem(recording, SAPPHIRE).signals).per_sample()
            for a, b in zip(again, first):
                np.testing.assert_array_equal(a, b, err_msg=parameter.name)
