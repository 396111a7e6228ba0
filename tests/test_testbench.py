"""The virtual test bench's truth model against independent references: the thesis's
Table 2, energy conservation, analytic breakaway thresholds, the slider-crank geometry,
two-inertia resonance, and each concealed effect's own signature."""

from __future__ import annotations

import ast
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.optimize import curve_fit

from mechanism.errors import UserError
from mechanism.data.reference import thesis
from mechanism.files.tables import check_increasing, read_table
from mechanism.testbench import ANGLE_STEP_RAD, EFFECTS, write_recording

from tests.helpers.nominal import bench_recording as make_recording

from tests.conftest import REPO_ROOT

THESIS = thesis()
RATIO = THESIS["mechanism"]["motor_to_arm_ratio"]


def clean_thesis_machine(volts_profile, effects=(), **overrides):
    """The thesis's parameters exactly, driven by [(duration_s, volts), ...]."""
    duration = sum(d for d, _ in volts_profile)
    return make_recording(
        effects,
        seed=0,
        duration_s=duration,
        randomize_baseline=False,
        voltage_plateaus=volts_profile,
        **overrides,
    )


def breakaway_voltage(base, friction_arm_Nm):
    """Voltage whose stall torque through the belt equals a friction torque on the arm."""
    return (
        friction_arm_Nm
        * base["resistance_ohm"]
        / (base["belt_ratio"] * base["torque_constant_Nm_per_A"])
    )


def slider_kinematics(theta, crank, rod, delta=1e-6):
    """Needle-bar height and dz/dtheta by central differences of the plain geometry."""

    def z(t):
        return crank * np.cos(t) + np.sqrt(rod**2 - (crank * np.sin(t)) ** 2)

    return z(theta), (z(theta + delta) - z(theta - delta)) / (2 * delta)


def cumulative_integral(values):
    """Trapezoid integral from the first sample to each sample (1 ms steps)."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (values[:-1] + values[1:]) * 1e-3)])


# --- baseline: the thesis's numbers and conservation laws ----------------------------------


def test_steady_speeds_match_the_thesis_table_2_cold_column():
    table = THESIS["steady_state_speed_table_2"]
    columns = table["columns"]
    for row in table["rows"]:
        volts, rpm_cold = row[columns.index("motor_voltage_V")], row[columns.index("rpm_cold")]
        if volts > THESIS["main_motor"]["model_validity_V"][1]:
            continue  # the thesis's model is valid up to 20 V
        rec = clean_thesis_machine([(3.0, volts)])
        rpm = rec.traces["arm_velocity_rad_s"][-500:].mean() * 60 / (2 * math.pi)
        assert abs(rpm - rpm_cold) / rpm_cold < 0.05, (volts, rpm, rpm_cold)


def energy_imbalance(rec, stored, dissipation_power):
    """Electrical input minus (losses + change of stored energy) from the start to each sample.

    The motor follows thesis eq. 1-5 with L = 0: i = (U - Ke w) / R over each interval (U held).
    """
    base = rec.truth["baseline"]
    u = rec.traces["applied_voltage_V"][:-1]
    wm = rec.traces["motor_velocity_rad_s"]
    R, Kt, Ke = (
        base["resistance_ohm"],
        base["torque_constant_Nm_per_A"],
        base["back_emf_constant_V_s_per_rad"],
    )
    i_start, i_end = (u - Ke * wm[:-1]) / R, (u - Ke * wm[1:]) / R

    def running(start, end):
        return np.concatenate([[0.0], np.cumsum(0.5 * (start + end) * 1e-3)])

    energy_in = running(u * i_start, u * i_end)
    copper = running(R * i_start**2, R * i_end**2)
    # Kt != Ke: the part of the back-emf power that never becomes shaft torque is lost in the motor
    conversion = running((Ke - Kt) * i_start * wm[:-1], (Ke - Kt) * i_end * wm[1:])
    viscous = cumulative_integral(base["viscous_motor_side_Nm_s_per_rad"] * wm**2)
    coulomb = cumulative_integral(base["coulomb_arm_Nm"] * np.abs(rec.traces["arm_velocity_rad_s"]))
    losses = copper + conversion + viscous + coulomb + cumulative_integral(dissipation_power)
    return energy_in, energy_in - losses - (stored - stored[0])


def test_energy_balance_of_the_lumped_machine():
    rec = clean_thesis_machine([(0.5, 0), (2, 12), (1, 4), (1.5, 18), (2, 0)], inductance_H=0.0)
    base, wm = rec.truth["baseline"], rec.traces["motor_velocity_rad_s"]
    energy_in, imbalance = energy_imbalance(
        rec, 0.5 * base["inertia_motor_side_kgm2"] * wm**2, 0.0 * wm
    )
    assert rec.traces["arm_velocity_rad_s"][-1] == 0.0 and energy_in[-1] > 10.0
    assert np.abs(imbalance).max() < 2e-3 * energy_in[-1]


def test_energy_balance_with_the_slider_crank_checks_inertia_gravity_and_the_half_j_prime_term():
    rec = clean_thesis_machine(
        [(0.5, 0), (2.5, 19.6), (1.5, 8), (2, 0)],
        effects=["linkage_dynamics"],
        inductance_H=0.0,
        linkage_dynamics={"reciprocating_mass_kg": 0.15},
    )
    base, link = rec.truth["baseline"], rec.truth["effect_params"]["linkage_dynamics"]
    crank, rod, mass, g = (
        base["crank_radius_m"],
        base["rod_length_m"],
        link["reciprocating_mass_kg"],
        link["gravity_m_s2"],
    )
    theta, wa = rec.traces["arm_angle_rad"], rec.traces["arm_velocity_rad_s"]
    grid = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    mean_dz2 = np.mean(slider_kinematics(grid, crank, rod)[1] ** 2)
    z, dz = slider_kinematics(theta, crank, rod)
    inertia = RATIO**2 * base["inertia_motor_side_kgm2"] + mass * (dz**2 - mean_dz2)
    energy_in, imbalance = energy_imbalance(rec, 0.5 * inertia * wa**2 + mass * g * z, 0.0 * wa)
    # within each turn the linkage trades ~this much energy with the rest: a wrong inertial or
    # gravity term shows up as an imbalance of its size
    swing = 0.5 * mass * (dz**2).max() * wa.max() ** 2
    assert np.abs(imbalance).max() < 2e-3 * energy_in[-1] and np.abs(imbalance).max() < 0.05 * swing


def test_energy_balance_with_the_elastic_belt():
    rec = clean_thesis_machine(
        [(0.3, 0), (1.0, 16), (0.7, 5), (1.0, 0)],
        effects=["belt_compliance"],
        inductance_H=0.0,
        belt_compliance={"resonance_Hz": 30.0, "damping_ratio": 0.05},
    )
    base, belt = rec.truth["baseline"], rec.truth["effect_params"]["belt_compliance"]
    t = rec.traces
    rotor = belt["motor_inertia_fraction"] * base["inertia_motor_side_kgm2"]
    arm = RATIO**2 * (1 - belt["motor_inertia_fraction"]) * base["inertia_motor_side_kgm2"]
    stretch = t["motor_angle_rad"] / RATIO - t["arm_angle_rad"]
    stretch_rate = t["motor_velocity_rad_s"] / RATIO - t["arm_velocity_rad_s"]
    k, c = belt["stiffness_arm_side_Nm_per_rad"], belt["damping_arm_side_Nm_s_per_rad"]
    stored = (
        0.5 * rotor * t["motor_velocity_rad_s"] ** 2
        + 0.5 * arm * t["arm_velocity_rad_s"] ** 2
        + 0.5 * k * stretch**2
    )
    energy_in, imbalance = energy_imbalance(rec, stored, c * stretch_rate**2)
    belt_loss = cumulative_integral(c * stretch_rate**2)[-1]
    assert (
        np.abs(imbalance).max() < 3e-3 * energy_in[-1] and np.abs(imbalance).max() < 0.1 * belt_loss
    )


# --- stick-slip ----------------------------------------------------------------------------


def test_machine_stays_stopped_below_breakaway_and_starts_above_it():
    base = clean_thesis_machine([(0.1, 0)]).truth["baseline"]
    threshold = breakaway_voltage(base, base["coulomb_arm_Nm"])
    below = clean_thesis_machine([(2.0, 0.97 * threshold)])
    above = clean_thesis_machine([(2.0, 1.03 * threshold)])
    assert np.ptp(below.traces["arm_angle_rad"]) == 0.0 and np.all(
        below.traces["arm_velocity_rad_s"] == 0
    )
    assert np.ptp(above.traces["arm_angle_rad"]) > 0.05


def test_machine_stops_at_zero_volts_and_stays_stopped():
    rec = clean_thesis_machine(
        [(0.3, 0), (1.5, 15), (2.5, 0)], effects=["linkage_dynamics", "torque_ripple"]
    )
    last = slice(-1500, None)
    assert np.all(rec.traces["arm_velocity_rad_s"][last] == 0.0)
    assert np.ptp(rec.traces["arm_angle_rad"][last]) == 0.0 and np.ptp(rec.arm_angle[last]) == 0.0


# --- sensors and format ----------------------------------------------------------------------


def test_angles_are_quantised_to_exactly_one_encoder_count():
    rec = make_recording([], seed=4, duration_s=20)
    counts = rec.arm_angle / ANGLE_STEP_RAD
    assert ANGLE_STEP_RAD == 2 * math.pi / 20000
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    steps = np.abs(np.diff(np.round(counts)))
    assert steps[steps > 0].min() == 1
    # floor quantisation: the logged angle is within one count below the true one
    error = rec.traces["arm_angle_rad"] - rec.arm_angle
    assert error.min() >= -1e-9 and error.max() < ANGLE_STEP_RAD


def test_csv_round_trip_through_read_table(tmp_path):
    rec = make_recording(["torque_ripple"], seed=5, duration_s=10)
    csv_path, truth_path = write_recording(rec, tmp_path / "rec.csv")
    assert truth_path == tmp_path / "rec.truth.json"
    table = read_table(csv_path, required=["time", "voltage", "arm_angle"], optional=["current"])
    check_increasing(table["time"], "rec")
    np.testing.assert_allclose(np.diff(table["time"]), 1e-3, atol=1e-9)
    np.testing.assert_array_equal(
        np.round(table["arm_angle"] / ANGLE_STEP_RAD), np.round(rec.arm_angle / ANGLE_STEP_RAD)
    )
    np.testing.assert_allclose(table["voltage"], rec.voltage)
    np.testing.assert_allclose(table["current"], rec.current, atol=1e-9)
    truth = json.loads(truth_path.read_text())
    assert (
        truth["effects"] == ["torque_ripple"]
        and truth["seed"] == 5
        and truth["recording"] == "rec.csv"
    )
    # the CSV conceals the truth: no effect name or parameter appears in it
    text = csv_path.read_text()
    assert "torque_ripple" not in text and "seed" not in text


def test_profile_is_plateaus_between_4_and_20_volts_with_stops():
    rec = make_recording([], seed=7)
    levels = [v for _, v in rec.truth["voltage_plateaus"]]
    running = [v for v in levels if v > 0]
    assert all(4.0 <= v <= 20.0 for v in running) and levels.count(0.0) >= 3
    assert min(running) < 7 and max(running) > 15
    assert rec.time[-1] == pytest.approx(59.999) and set(np.unique(rec.voltage)) == set(levels)


def test_current_is_noisy_but_centred_on_the_motor_current():
    rec = make_recording([], seed=2, duration_s=20)
    noise = rec.current - rec.traces["current_A"]
    assert abs(noise.mean()) < 2e-3 and 0.005 < noise.std() < 0.04


def test_each_seed_is_deterministic_and_effects_leave_the_rest_of_the_seed_alone():
    a, b = (
        make_recording(["stribeck"], seed=11, duration_s=5),
        make_recording(["stribeck"], seed=11, duration_s=5),
    )
    np.testing.assert_array_equal(a.arm_angle, b.arm_angle)
    np.testing.assert_array_equal(a.current, b.current)
    assert a.truth == b.truth
    other = make_recording(["stribeck"], seed=12, duration_s=5)
    assert (
        other.truth["baseline"] != a.truth["baseline"]
        and other.truth["voltage_plateaus"] != a.truth["voltage_plateaus"]
    )
    clean = make_recording([], seed=11, duration_s=5)
    for key in ("baseline", "voltage_plateaus", "start_arm_angle_rad", "sensors"):
        assert clean.truth[key] == a.truth[key]
    pair = make_recording(["stribeck", "torque_ripple"], seed=11, duration_s=5)
    assert pair.truth["effect_params"]["stribeck"] == a.truth["effect_params"]["stribeck"]


def test_unknown_effects_and_overrides_are_user_errors():
    with pytest.raises(UserError, match="did you mean torque_ripple"):
        make_recording(["torque_rippel"])
    with pytest.raises(UserError, match="named twice"):
        make_recording("stribeck,stribeck")
    with pytest.raises(UserError, match="unknown override"):
        make_recording([], coulomb_arm=0.2)
    with pytest.raises(UserError, match="has no parameter"):
        make_recording(["stribeck"], stribeck={"nonsense": 1})


def test_compiled_and_python_integrators_agree():
    for effects in (
        [name for name in EFFECTS if name != "belt_compliance"],
        ["belt_compliance", "linkage_dynamics", "torque_ripple", "stribeck", "needle_penetration"],
    ):
        kwargs = dict(seed=3, duration_s=0.6, voltage_plateaus=[(0.1, 0), (0.5, 14)])
        native = make_recording(effects, **kwargs)
        python = make_recording(effects, integrator="python", **kwargs)
        assert (
            native.truth["integrator"]["solver"] == "native"
            and python.truth["integrator"]["solver"] == "python"
        )
        for name, values in native.traces.items():
            np.testing.assert_allclose(
                python.traces[name], values, rtol=1e-9, atol=1e-9, err_msg=name
            )


# --- the effects' signatures -------------------------------------------------------------------


def spectrum_peak(signal, rate_hz, low_hz, high_hz):
    signal = (signal - signal.mean()) * np.hanning(len(signal))
    amplitude = np.abs(np.fft.rfft(signal, 8 * len(signal)))
    freqs = np.fft.rfftfreq(8 * len(signal), 1 / rate_hz)
    band = (freqs >= low_hz) & (freqs <= high_hz)
    return freqs[band][np.argmax(amplitude[band])]


@pytest.mark.parametrize(
    "component, volts, per_arm_rev", [("once", 10.0, RATIO), ("cogging", 4.0, 12 * RATIO)]
)
def test_torque_ripple_appears_at_its_motor_order(component, volts, per_arm_rev):
    ripple = (
        {"once_per_motor_rev_Nm": 0.012, "cogging_Nm": 0.0}
        if component == "once"
        else {"once_per_motor_rev_Nm": 0.0, "cogging_Nm": 0.004}
    )
    rec = clean_thesis_machine([(6.0, volts)], effects=["torque_ripple"], torque_ripple=ripple)
    speed = rec.traces["arm_velocity_rad_s"][2000:]
    arm_hz = speed.mean() / (2 * math.pi)
    peak = spectrum_peak(speed, 1000, 0.5 * arm_hz, 490)
    assert peak == pytest.approx(per_arm_rev * arm_hz, rel=0.02)


def test_linkage_inertial_torque_grows_with_speed_at_twice_the_arm_rate():
    amplitudes, speeds = [], []
    for volts in (10.0, 19.0):
        rec = clean_thesis_machine(
            [(4.0, volts)],
            effects=["linkage_dynamics"],
            linkage_dynamics={"reciprocating_mass_kg": 0.1},
        )
        speed, theta = rec.traces["arm_velocity_rad_s"][2000:], rec.traces["arm_angle_rad"][2000:]
        arm_hz = speed.mean() / (2 * math.pi)
        assert spectrum_peak(speed, 1000, 1.5 * arm_hz, 10 * arm_hz) == pytest.approx(
            2 * arm_hz, rel=0.02
        )
        basis = np.column_stack([np.ones_like(theta), np.sin(2 * theta), np.cos(2 * theta)])
        amplitudes.append(math.hypot(*np.linalg.lstsq(basis, speed, rcond=None)[0][1:]))
        speeds.append(speed.mean())
    # an inertial torque ~ omega^2 acting for a time ~ 1/omega: a speed ripple ~ omega
    assert amplitudes[1] / amplitudes[0] > 0.7 * speeds[1] / speeds[0]


def test_stribeck_raises_breakaway_and_slows_the_machine_at_low_speed():
    base = clean_thesis_machine([(0.1, 0)]).truth["baseline"]
    strib = {"static_over_kinetic_fraction": 0.33, "stribeck_velocity_arm_rad_s": 10.0}
    volts = breakaway_voltage(base, 1.15 * base["coulomb_arm_Nm"])  # between kinetic and static
    clean = clean_thesis_machine([(2.0, volts)])
    sticky = clean_thesis_machine([(2.0, volts)], effects=["stribeck"], stribeck=strib)
    assert (
        np.ptp(clean.traces["arm_angle_rad"]) > 0.05
        and np.ptp(sticky.traces["arm_angle_rad"]) == 0.0
    )
    slow_clean = clean_thesis_machine([(3.0, 5.0)])
    slow_sticky = clean_thesis_machine([(3.0, 5.0)], effects=["stribeck"], stribeck=strib)
    assert (
        slow_sticky.traces["arm_velocity_rad_s"][-500:].mean()
        < slow_clean.traces["arm_velocity_rad_s"][-500:].mean() - 0.3
    )


def test_position_friction_makes_breakaway_depend_on_the_resting_angle():
    rec = clean_thesis_machine([(0.1, 0)], effects=["position_friction"])
    base, pf = rec.truth["baseline"], rec.truth["effect_params"]["position_friction"]

    def coulomb_at(theta):
        return base["coulomb_arm_Nm"] * (
            1
            + pf["first_harmonic_fraction"] * math.cos(theta - pf["first_harmonic_phase_rad"])
            + pf["second_harmonic_fraction"] * math.cos(2 * theta - pf["second_harmonic_phase_rad"])
        )

    grid = np.linspace(0, 2 * math.pi, 720, endpoint=False)
    levels = np.array([coulomb_at(t) for t in grid])
    highest, lowest = grid[levels.argmax()], grid[levels.argmin()]
    assert levels.max() / levels.min() - 1 > 0.1
    volts = breakaway_voltage(base, 0.5 * (levels.max() + levels.min()))
    stuck = clean_thesis_machine(
        [(1.0, volts)], effects=["position_friction"], start_angle_rad=highest
    )
    moving = clean_thesis_machine(
        [(1.0, volts)], effects=["position_friction"], start_angle_rad=lowest
    )
    assert (
        np.ptp(stuck.traces["arm_angle_rad"]) == 0.0
        and np.ptp(moving.traces["arm_angle_rad"]) > 0.01
    )


def test_thermal_drift_speeds_the_machine_up_as_its_friction_falls():
    drift = {
        "coulomb_drop_fraction": 0.3,
        "viscous_drop_fraction": 0.45,
        "warm_up_time_constant_s": 30.0,
    }
    rec = clean_thesis_machine(
        [(0.5, 0), (40.0, 6.0)], effects=["thermal_drift"], thermal_drift=drift
    )
    base, speed = rec.truth["baseline"], rec.traces["arm_velocity_rad_s"]
    start = np.argmax(speed > 0) / 1000
    R, Kt, Ke = (
        base["resistance_ohm"],
        base["torque_constant_Nm_per_A"],
        base["back_emf_constant_V_s_per_rad"],
    )
    for t in (10.0, 25.0, 40.0):
        warm = 1 - math.exp(-(t - start) / drift["warm_up_time_constant_s"])
        coulomb = base["coulomb_arm_Nm"] * (1 - drift["coulomb_drop_fraction"] * warm)
        viscous = base["viscous_motor_side_Nm_s_per_rad"] * (
            1 - drift["viscous_drop_fraction"] * warm
        )
        # thesis eq. 5, steady
        motor_speed = (Kt * 6.0 / R - coulomb / RATIO) / (Kt * Ke / R + viscous)
        k = int(t * 1000) - 1
        assert speed[k] == pytest.approx(motor_speed / RATIO, rel=0.01)
    assert speed[-1] > 1.05 * speed[1500]


def test_needle_load_acts_only_while_the_needle_is_in_the_fabric():
    needle = {"layers": 12, "force_per_layer_N": 3.0}
    rec = clean_thesis_machine(
        [(5.0, 6.0)], effects=["needle_penetration"], needle_penetration=needle
    )
    base, params = rec.truth["baseline"], rec.truth["effect_params"]["needle_penetration"]
    t = rec.traces
    sl = slice(1500, -5)
    wm = t["motor_velocity_rad_s"]
    accel = np.gradient(wm, 1e-3)
    # torque the lumped model (thesis eq. 5 with the measured current) cannot account for, on the arm
    missing = (
        RATIO
        * (
            base["torque_constant_Nm_per_A"] * t["current_A"]
            - base["viscous_motor_side_Nm_s_per_rad"] * wm
            - base["inertia_motor_side_kgm2"] * accel
        )
        - base["coulomb_arm_Nm"]
    )
    theta = np.mod(t["arm_angle_rad"], 2 * math.pi)[sl]
    missing = missing[sl]
    z, _ = slider_kinematics(theta, base["crank_radius_m"], base["rod_length_m"])
    z_bdc, _ = slider_kinematics(np.pi, base["crank_radius_m"], base["rod_length_m"])
    tip_above_plate = z - z_bdc - params["needle_depth_below_plate_at_bdc_m"]
    fabric_top = params["layers"] * params["layer_thickness_m"]
    clear = tip_above_plate > fabric_top + 1e-3  # a margin for the derivative's smoothing
    assert missing.max() > 0.15
    assert np.abs(missing[clear]).max() < 0.02 * missing.max() + 5e-3
    peak = theta[np.argmax(missing)]
    assert params["entry_arm_angle_rad"] < peak < math.pi


def test_belt_resonance_is_the_two_inertia_frequency():
    rec = clean_thesis_machine(
        [(0.3, 0), (1.0, 12), (0.5, 18)],
        effects=["belt_compliance"],
        belt_compliance={"resonance_Hz": 40.0, "damping_ratio": 0.02},
    )
    base, belt = rec.truth["baseline"], rec.truth["effect_params"]["belt_compliance"]
    rotor = RATIO**2 * belt["motor_inertia_fraction"] * base["inertia_motor_side_kgm2"]
    arm = RATIO**2 * (1 - belt["motor_inertia_fraction"]) * base["inertia_motor_side_kgm2"]
    expected = math.sqrt(belt["stiffness_arm_side_Nm_per_rad"] * (1 / rotor + 1 / arm)) / (
        2 * math.pi
    )
    t = rec.traces
    stretch = (t["motor_angle_rad"] / RATIO - t["arm_angle_rad"])[1300:1500]
    time = np.arange(len(stretch)) * 1e-3
    guess = spectrum_peak(stretch - np.polyval(np.polyfit(time, stretch, 2), time), 1000, 5, 200)

    def ringing(time, amp, decay, freq, phase, c0, c1, c2):
        return (
            amp * np.exp(-decay * time) * np.sin(2 * np.pi * freq * time + phase)
            + c0
            + c1 * time
            + c2 * time**2
        )

    popt, _ = curve_fit(
        ringing,
        time,
        stretch,
        p0=[np.ptp(stretch) / 2, 10, guess, 0, stretch.mean(), 0, 0],
        maxfev=20000,
    )
    assert abs(popt[2]) == pytest.approx(expected, rel=0.03)
    # and the arm's speed rings at the same frequency (what the encoder sees)
    speed = t["arm_velocity_rad_s"][1300:1500]
    assert spectrum_peak(
        speed - np.polyval(np.polyfit(time, speed, 3), time), 1000, 15, 200
    ) == pytest.approx(expected, rel=0.05)


def test_voltage_nonlinearity_follows_the_sign_of_table_2_errors():
    table = THESIS["steady_state_speed_table_2"]
    columns = table["columns"]
    rows = [
        r
        for r in table["rows"]
        if 0 < r[columns.index("duty_percent")] < 100 and r[columns.index("motor_voltage_V")] != 7.0
    ]
    for seed in range(4):
        for row in rows:
            volts, error = (
                row[columns.index("motor_voltage_V")],
                row[columns.index("voltage_error_percent")],
            )
            kwargs = dict(seed=seed, duration_s=2.5, voltage_plateaus=[(2.5, volts)])
            clean = make_recording([], **kwargs).traces["arm_velocity_rad_s"][-300:].mean()
            distorted = (
                make_recording(["voltage_nonlinearity"], **kwargs)
                .traces["arm_velocity_rad_s"][-300:]
                .mean()
            )
            assert np.sign(distorted - clean) == np.sign(error), (seed, volts)


def test_encoder_eccentricity_is_a_once_per_revolution_sensor_error():
    profile = [(0.3, 0), (3.0, 5.0), (3.0, 18.0)]
    kwargs = dict(seed=6, duration_s=6.3, voltage_plateaus=profile)
    clean, ecc = make_recording([], **kwargs), make_recording(["encoder_eccentricity"], **kwargs)
    amplitude = ecc.truth["effect_params"]["encoder_eccentricity"]["amplitude_rad"]
    # the machine is untouched
    np.testing.assert_array_equal(clean.traces["arm_angle_rad"], ecc.traces["arm_angle_rad"])
    theta = ecc.traces["arm_angle_rad"]
    error = ecc.arm_angle - theta
    basis = np.column_stack(
        [np.ones_like(theta)] + [f(k * theta) for k in (1, 2, 3) for f in (np.sin, np.cos)]
    )
    coef = np.linalg.lstsq(basis, error, rcond=None)[0]
    assert math.hypot(*coef[1:3]) == pytest.approx(amplitude, abs=ANGLE_STEP_RAD / 2)
    assert max(math.hypot(*coef[3:5]), math.hypot(*coef[5:7])) < ANGLE_STEP_RAD / 4
    # at the index pulse (TDC) the error vanishes
    index = np.abs(np.mod(theta + np.pi, 2 * np.pi) - np.pi) < 1e-3
    assert np.all(np.abs(error[index]) <= ANGLE_STEP_RAD)

    def speed_error_rms(window):
        def speed(angle):
            return (angle[10:] - angle[:-10]) / 0.01

        return np.sqrt(
            np.mean((speed(ecc.arm_angle[window]) - speed(clean.arm_angle[window])) ** 2)
        )

    slow, fast = slice(1800, 3300), slice(4800, 6300)
    speed_ratio = (
        clean.traces["arm_velocity_rad_s"][fast].mean()
        / clean.traces["arm_velocity_rad_s"][slow].mean()
    )
    assert speed_error_rms(fast) / speed_error_rms(slow) == pytest.approx(speed_ratio, rel=0.25)


@pytest.mark.slow
def test_every_effect_changes_the_arm_speed_visibly_somewhere():
    """Magnitudes are plausible yet detectable: >= 0.2 rad/s RMS in the most affected 2 s (0.2 s for
    the belt's transients) against the clean recording of the same seed (the velocity from a
    5000-line encoder at 1 kHz has ~0.15 rad/s RMS quantisation noise per sample)."""
    for seed in (0, 1):
        clean = make_recording([], seed=seed, duration_s=40)
        for name in EFFECTS:
            rec = make_recording([name], seed=seed, duration_s=40)
            if name in ("encoder_eccentricity", "sensor_delay"):  # the log only
                diff = np.gradient(rec.arm_angle - clean.arm_angle, 1e-3)
                diff = np.convolve(diff, np.ones(10) / 10, mode="same")
            else:
                diff = rec.traces["arm_velocity_rad_s"] - clean.traces["arm_velocity_rad_s"]
            window = 200 if name == "belt_compliance" else 2000
            rms = np.sqrt(
                (diff[: len(diff) // window * window].reshape(-1, window) ** 2).mean(axis=1)
            ).max()
            assert rms > 0.2, (name, seed, rms)


# --- separation from the diagnosis side, CLI and shipped recordings -------------------------------

FORBIDDEN = (
    "mechanism.sysid.identification",
    "mechanism.sysid.diagnosis",
    "mechanism.dynamics.lumped",
    "mechanism.sysid.effects",
)


def _testbench_sources():
    package = REPO_ROOT / "mechanism" / "testbench"
    return sorted(package.glob("*.py")) + [REPO_ROOT / "mechanism" / "cli" / "testbench.py"]


def test_truth_model_never_imports_the_diagnosis_side():
    for path in _testbench_sources():
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [
                    f"{node.module}.{alias.name}" for alias in node.names
                ]
            else:
                continue
            for name in names:
                assert not name.startswith(FORBIDDEN), f"{path.name} imports {name}"
    code = (
        "import sys, mechanism.testbench, mechanism.cli.testbench\n"
        "from types import SimpleNamespace as N\n"
        "from mechanism.testbench import make_recording\n"
        "motor = N(resistance_ohm=1.1, torque_constant_Nm_per_A=0.017, back_emf_V_s_per_rad=0.021)\n"
        "nominal = N(motor=motor, ratio=8.0, inertia_kgm2=1.8e-3, inertia_motor_side_kgm2=2.8e-5, viscous_motor_side=2.2e-5,\n"
        "            torque_scale_Nm=0.18, supply_V=24.0)\n"
        "make_recording(['torque_ripple'], duration_s=0.05, nominal=nominal)\n"
        f"bad = [m for m in sys.modules if m.startswith({FORBIDDEN!r})]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO_ROOT)


@pytest.mark.slow
def test_cli_lists_the_vocabulary_and_writes_a_recording(cli, tmp_path):
    listing = cli("testbench", "--list")
    assert listing.returncode == 0
    assert [line.split()[0] for line in listing.stdout.splitlines()] == ["none", *EFFECTS]
    out = cli(
        "testbench",
        "--effect",
        "position_friction,encoder_eccentricity",
        "--seed",
        "2",
        "--duration",
        "3",
        "-o",
        tmp_path / "r.csv",
    )
    assert out.returncode == 0, out.stderr
    truth = json.loads((tmp_path / "r.truth.json").read_text())
    assert (
        truth["effects"] == ["position_friction", "encoder_eccentricity"]
        and truth["duration_s"] == 3.0
    )
    assert len(read_table(tmp_path / "r.csv", required=["time", "voltage", "arm_angle"])) == 3000


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--effect", "belt"], "unknown effect 'belt'"),
        (["--effect", "none", "--duration", "0"], "duration"),
        (["--effect", "none"], "needs --effect"),
    ],
)
def test_cli_bad_input_is_one_error_line(cli_here, tmp_path, args, fragment):
    target = tmp_path / "r.csv"
    result = cli_here(
        "testbench", *args, *(["-o", target] if "--duration" in args or "belt" in args else [])
    )
    assert fragment in result.assert_bad_input()
    assert list(tmp_path.iterdir()) == []


def test_cli_refuses_a_name_without_csv_suffix_and_writes_nothing(cli_here, tmp_path):
    result = cli_here("testbench", "--effect", "none", "-o", tmp_path / "r.txt")
    assert "must end in .csv" in result.assert_bad_input()
    assert list(tmp_path.iterdir()) == []


def test_a_machine_without_a_tool_in_fabric_gets_no_needle_penetration_from_the_bench(
    cli_here, tmp_path
):
    """The press has no tool working in fabric: the diagnosis does not offer a needle piercing
    fabric, so the bench refuses to conceal one (before, it wrote a recording no library model
    could explain, diagnosed as a gear friction at 22x the noise)."""
    from dataclasses import replace

    from mechanism.sysid.effects import library
    from mechanism.testbench import make_recording
    from tests.helpers.nominal import SAPPHIRE

    result = cli_here(
        "testbench",
        "--machine",
        REPO_ROOT / "assets" / "machines" / "press.toml",
        "--effect",
        "needle_penetration",
        "-o",
        tmp_path / "r.csv",
    )
    assert "no tool working in fabric" in result.assert_bad_input()
    assert list(tmp_path.iterdir()) == []
    fabricless = replace(SAPPHIRE, tool_in_fabric=False)
    assert "needle_penetration" not in library(fabricless)
    with pytest.raises(UserError, match="no tool working in fabric"):
        make_recording("torque_ripple,needle_penetration", duration_s=0.1, nominal=fabricless)


SHIPPED = sorted((REPO_ROOT / "assets" / "recordings").glob("*.truth.json"))


def test_shipped_recordings_exist_with_a_clean_one_and_a_concealed_effect():
    effects = [json.loads(path.read_text())["effects"] for path in SHIPPED]
    assert [] in effects and any(effects)
    for path in SHIPPED:
        assert path.with_name(path.name.replace(".truth.json", ".csv")).is_file()


@pytest.mark.parametrize("truth_path", SHIPPED, ids=lambda p: p.name)
def test_shipped_recordings_are_reproducible_from_their_truth(truth_path):
    truth = json.loads(truth_path.read_text())
    table = read_table(
        truth_path.with_name(truth["recording"]),
        required=["time", "voltage", "arm_angle", "current"],
    )
    rec = make_recording(truth["effects"], seed=truth["seed"], duration_s=truth["duration_s"])
    np.testing.assert_allclose(table["voltage"], rec.voltage)
    counts = np.round(table["arm_angle"] / ANGLE_STEP_RAD) - np.round(
        rec.arm_angle / ANGLE_STEP_RAD
    )
    assert np.abs(counts).max() <= 1
    np.testing.assert_allclose(table["current"], rec.current, atol=1.5e-3)


def test_sensor_delay_logs_the_true_angle_late():
    """The logged angle is the true angle of delay_s ago, to within one encoder count."""
    rec = make_recording(["sensor_delay"], seed=3, duration_s=10)
    delay = rec.truth["effect_params"]["sensor_delay"]["delay_s"]
    true_then = np.interp(rec.time - delay, rec.time, rec.traces["arm_angle_rad"])
    assert np.abs(rec.arm_angle - true_then).max() <= ANGLE_STEP_RAD * 1.001


def test_a_late_eccentric_encoder_logs_both_its_errors():
    """With an eccentric encoder and a sensor delay in one machine, the log is the eccentric
    reading of delay_s ago: before, the eccentricity was computed from the true angle of now and
    the delay was lost (a 9.6 ms delay missing from a mix's log, its truth claiming it)."""
    kwargs = dict(seed=3, duration_s=10)
    both = make_recording(["sensor_delay", "encoder_eccentricity"], **kwargs)
    delay = both.truth["effect_params"]["sensor_delay"]["delay_s"]
    e = both.truth["effect_params"]["encoder_eccentricity"]
    theta = both.traces["arm_angle_rad"]
    reading = theta + e["amplitude_rad"] * (
        np.sin(theta + e["phase_rad"]) - math.sin(e["phase_rad"])
    )
    logged_then = np.interp(both.time - delay, both.time, reading)
    assert np.abs(both.arm_angle - logged_then).max() <= ANGLE_STEP_RAD * 1.001
    # and the delay shows: the log is not the reading of now
    assert np.abs(both.arm_angle - reading).max() > 100 * ANGLE_STEP_RAD


def test_winding_heating_follows_the_copper_energy_balance():
    """The resistance rises by alpha x temperature, the temperature being the first-order
    response to the I^2 R the winding dissipates (checked by integrating that balance again
    from the logged true current), and the warm motor runs slower at the same voltage."""
    rec = make_recording(["winding_heating"], seed=2, duration_s=40)
    heat = rec.truth["effect_params"]["winding_heating"]
    r = rec.traces["winding_resistance_ohm"]
    r0 = rec.truth["baseline"]["resistance_ohm"]
    kelvin, dt = 0.0, 1e-3
    for k in range(len(r)):
        kelvin += (
            dt
            * (rec.traces["current_A"][k] ** 2 * r[k] - kelvin / heat["thermal_resistance_K_per_W"])
            / heat["thermal_time_constant_s"]
            * heat["thermal_resistance_K_per_W"]
        )
    assert r[-1] == pytest.approx(r0 * (1 + heat["copper_coefficient_per_K"] * kelvin), rel=0.01)
    assert r[-1] > 1.05 * r0
    clean = make_recording([], seed=2, duration_s=40)
    assert (
        rec.traces["arm_velocity_rad_s"][-2000:].mean()
        < clean.traces["arm_velocity_rad_s"][-2000:].mean()
    )
