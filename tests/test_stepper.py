"""Stepper models (PM25S-048): thesis sequence, linearised dynamics, static torque, pull-out."""

from __future__ import annotations

import ctypes
import math
import re

import numpy as np
import pytest

from mechanism import steppers
from mechanism.steppers import step_profiles
from mechanism.errors import UserError
from mechanism.data.reference import thesis

KINDS = ("circuit", "physical")


@pytest.fixture(scope="module")
def params():
    return steppers.pm25s048()


@pytest.fixture(scope="module")
def thread_cut_runs():
    runs = {}
    for kind in KINDS:
        runs[kind, "full", "abrupt"] = steppers.simulate(step_profiles.thread_cut(), kind)
        for mode in ("micro16",):
            runs[kind, mode, "abrupt"] = steppers.simulate(step_profiles.thread_cut(), kind, mode)
            runs[kind, mode, "ramped"] = steppers.simulate(
                step_profiles.thread_cut(ramp_steps=25), kind, mode
            )
    return runs


def thesis_thread_cut():
    """(forward s, back s, steps/s) as the reference file states them."""
    ref = thesis()["stepper_motors"]
    match = re.search(r"forward ([0-9.]+) s then back .*? ([0-9.]+) s", ref["thread_cut_sequence"])
    assert match, ref["thread_cut_sequence"]
    return float(match.group(1)), float(match.group(2)), float(ref["assumed_step_rate_steps_per_s"])


def thesis_stroke_deg():
    ref = thesis()["stepper_motors"]
    forward_s, _, rate = thesis_thread_cut()
    return forward_s * rate * ref["step_angle_deg"]


def test_the_machine_description_carries_the_thesis_numbers():
    # the library reads the shipped description; the thesis's numbers there must be the reference file's
    from mechanism.machine.machine import resolve_description

    ref = thesis()["stepper_motors"]
    description = resolve_description(None)
    stepper = description.section("stepper")
    assert stepper["step_angle_deg"] == ref["step_angle_deg"]
    assert stepper["pole_pairs"] == ref["poles_in_torque_equation"]
    assert ref["type"].startswith(stepper["type"])
    assert (
        description.section("thread_cut")["forward_s"],
        description.section("thread_cut")["back_s"],
        stepper["step_rate_steps_s"],
    ) == thesis_thread_cut()
    assert step_profiles.thread_cut_timing() == thesis_thread_cut()


def test_parameters_follow_the_thesis(params):
    ref = thesis()["stepper_motors"]
    assert params.step_angle_deg == ref["step_angle_deg"]
    assert params.pole_pairs == ref["poles_in_torque_equation"]
    # a two-phase motor: four full steps per electrical period
    assert 4 * params.pole_pairs * params.step_angle_deg == pytest.approx(360.0)
    with pytest.raises(UserError):
        params.replace(step_angle_deg=15.0)


def test_thread_cut_sequence_is_the_thesis_one():
    forward_s, back_s, rate = thesis_thread_cut()
    profile = step_profiles.thread_cut()
    assert profile.duration_s == pytest.approx(forward_s + back_s)
    assert profile.peak_steps() == pytest.approx(forward_s * rate)
    assert profile.reversal_times_s() == [pytest.approx(forward_s)]
    assert float(profile.position_steps(profile.duration_s)) == pytest.approx(0.0, abs=1e-9)
    ramped = step_profiles.thread_cut(ramp_steps=25)
    assert ramped.peak_steps() == pytest.approx(forward_s * rate)
    assert float(ramped.position_steps(ramped.duration_s)) == pytest.approx(0.0, abs=1e-9)
    # the ramp is linear: the rate falls to zero at the reversal
    t_rev = ramped.reversal_times_s()[0]
    assert float(ramped.rate_steps_s(t_rev)) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_thread_cut_peaks_at_the_stroke_and_returns(kind, thread_cut_runs, params):
    run = thread_cut_runs[kind, "full", "abrupt"]
    s = run.summary
    stroke = thesis_stroke_deg()
    assert s["peak_command_deg"] == pytest.approx(stroke)
    assert stroke - params.step_angle_deg < s["peak_position_deg"] < stroke + params.step_angle_deg
    assert abs(s["final_position_deg"]) < params.step_angle_deg
    assert s["lost_steps"] == 0 and s["slips"] == []
    # the reversal overshoots (thesis fig. 20): the rotor passes the turning point
    reversal = s["reversals"][0]
    assert reversal["overshoot_deg"] > 0.5
    # more than the slew speed
    assert reversal["peak_speed_error_rad_s"] > 1.5 * params.step_rad * 1000


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_ramped_reversal_reduces_the_oscillation(kind, thread_cut_runs):
    """With microstepping the ramp to rest removes the reversal's overshoot and speed
    spike. (In full step the last slow steps of a ramp ring like single steps; the README
    gives those numbers.)"""
    abrupt = thread_cut_runs[kind, "micro16", "abrupt"].summary["reversals"][0]
    ramped = thread_cut_runs[kind, "micro16", "ramped"].summary
    assert ramped["lost_steps"] == 0
    reversal = ramped["reversals"][0]
    assert reversal["overshoot_deg"] < 0.3 * abrupt["overshoot_deg"]
    assert reversal["peak_speed_error_rad_s"] < 0.3 * abrupt["peak_speed_error_rad_s"]
    slew = 1000 * steppers.pm25s048().step_rad
    assert abrupt["peak_speed_rad_s"] > 1.5 * slew  # the spike of the thesis's figure 20
    assert reversal["peak_speed_rad_s"] < 1.3 * slew


def ringing_frequency_hz(run, start_s=0.0008, crossings=8):
    """Mean frequency of the oscillation about the final position (zero crossings)."""
    x = run.rotor_deg - run.rotor_deg[-1]
    keep = run.time_s > start_s
    t, x = run.time_s[keep], x[keep]
    k = np.flatnonzero(np.sign(x[1:]) != np.sign(x[:-1]))[:crossings]
    # linear interpolation of each crossing
    tz = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    return 1.0 / (2 * np.mean(np.diff(tz)))


@pytest.mark.parametrize("kind", KINDS)
def test_small_step_rings_at_the_linearised_frequency(kind, params):
    """One 1/16 microstep: small enough for the linearised model. Stiffness from the
    torque equations by hand (not from the library's helper)."""
    mode = steppers.drive_mode("micro16")
    run = steppers.simulate(step_profiles.move(1 / 16, 1000), kind, mode, params, settle_s=0.03)
    p, current = params.pole_pairs, params.rated_current_A
    phi = math.pi / 2 / 16  # electrical angle of the new position
    if kind == "circuit":  # T = p psi I sin(phi - p th) - Tdm sin(4 p th)
        stiffness = (
            p * p * params.flux_linkage_Vs * current
            + 4 * p * params.detent_torque_Nm * math.cos(4 * phi)
        )
    else:  # T = Kt (Vs/R) |i|/(sqrt2 I) sin(phi - p th), one phase-vector magnitude I
        stiffness = (
            p * params.physical_kt_Nm_A * params.supply_V / params.resistance_ohm / math.sqrt(2)
        )
    expected = math.sqrt(stiffness / params.inertia_kg_m2) / (2 * math.pi)
    assert ringing_frequency_hz(run) == pytest.approx(expected, rel=0.05)
    assert run.summary["lost_steps"] == 0


@pytest.mark.parametrize("kind", KINDS)
def test_holding_torque_is_sinusoidal_with_the_stated_amplitude(kind, params):
    p = params.pole_pairs
    displacement = np.linspace(-2, 2, 25) * params.step_rad  # one electrical period
    torque = steppers.holding_torque(displacement, kind)
    # full step rests at p th0 = pi/4, where the detent term -Tdm sin(4 p th) = +Tdm sin(4 p d)
    basis = np.column_stack([-np.sin(p * displacement), np.sin(4 * p * displacement)])
    (amplitude, detent), *_ = np.linalg.lstsq(basis, torque, rcond=None)
    assert np.max(np.abs(basis @ [amplitude, detent] - torque)) < 0.01 * params.holding_torque_Nm
    # the chopper holds the peak current at the set value: its mean is a little lower
    assert amplitude == pytest.approx(params.holding_torque_Nm, rel=0.02)
    assert amplitude <= params.holding_torque_Nm * 1.001
    expected_detent = params.detent_torque_Nm if kind == "circuit" else 0.0
    assert detent == pytest.approx(expected_detent, abs=0.02 * params.detent_torque_Nm)


def test_models_agree_within_half_a_step_at_low_rate(params):
    profile = step_profiles.move(20, 100)
    circuit = steppers.simulate(profile, "circuit", settle_s=0.05)
    physical = steppers.simulate(profile, "physical", settle_s=0.05)
    other = np.interp(circuit.time_s, physical.time_s, physical.rotor_deg)
    assert np.max(np.abs(circuit.rotor_deg - other)) < params.step_angle_deg / 2
    assert circuit.summary["final_position_deg"] == pytest.approx(
        20 * params.step_angle_deg, abs=0.5
    )


def lost(kind, rate, params=None):
    result = steppers.sweep_rates([rate], kind, params=params)[0]
    return result["lost_steps"] > 0 or result["slips"] > 0


@pytest.mark.slow
def test_circuit_model_pulls_out_where_the_physical_model_does_not(params):
    assert not lost("circuit", 3000) and not lost("physical", 3000)
    assert lost("circuit", 4000)
    assert not lost("physical", 4000)
    # the chopper's voltage limit is what stops it: a higher supply keeps it in step
    assert not lost("circuit", 4000, params.replace(supply_V=2 * params.supply_V))


def test_lost_steps_are_counted_and_timed(params):
    profile = step_profiles.from_rates("overspeed", [0, 0.1, 0.15, 0.25], [0, 6000, 6000, 0])
    run = steppers.simulate(profile, "circuit", settle_s=0.05)
    s = run.summary
    assert s["lost_steps"] > 0
    # every slip is a whole electrical period, and they add up to the final error
    assert all(abs(n) % 4 == 0 for _, n in s["slips"])
    assert sum(n for _, n in s["slips"]) == pytest.approx(
        s["final_error_deg"] / params.step_angle_deg, abs=0.5
    )
    assert all(0 < t < profile.duration_s for t, _ in s["slips"])


def test_drive_tables(params):
    current = params.rated_current_A
    full = steppers.drive_mode("full")
    half = steppers.drive_mode("half")
    micro = steppers.drive_mode("micro16")
    steps = np.arange(8)
    _, a, b = steppers.drive(params, full, steppers.rest_angle_rad(params, full, steps))
    assert np.all(np.abs(a) == current) and np.all(np.abs(b) == current)
    _, a, b = steppers.drive(params, half, steppers.rest_angle_rad(params, half, steps / 2))
    # one and two phases on, alternating
    assert sorted(set(np.count_nonzero([a, b], axis=0))) == [
        1,
        2,
    ]
    phi, a, b = steppers.drive(params, micro, steppers.rest_angle_rad(params, micro, steps / 16))
    np.testing.assert_allclose(np.hypot(a, b), current)
    np.testing.assert_allclose(np.diff(phi), math.pi / 2 / 16)
    with pytest.raises(UserError):
        steppers.drive_mode("micro1000")


def test_python_fallback_matches_the_compiled_callbacks(params):
    if steppers._callbacks._native() is None:
        pytest.skip("no C compiler: only the Python callbacks exist")
    profile = step_profiles.move(4, 500)
    for kind in KINDS:
        native = steppers.simulate(profile, kind, "half", settle_s=0.005, backend="native")
        python = steppers.simulate(profile, kind, "half", settle_s=0.005, backend="python")
        assert python.backend == "python"
        np.testing.assert_allclose(python.rotor_deg, native.rotor_deg, atol=1e-9)
        np.testing.assert_allclose(python.current_a_A, native.current_a_A, atol=1e-9)
        np.testing.assert_allclose(python.torque_Nm, native.torque_Nm, atol=1e-12)


def test_callbacks_leave_other_actuators_to_their_owner(params):
    """MuJoCo callbacks are process-global: an actuator without our marker keeps the
    callback that was installed before ours."""
    import mujoco

    if steppers._callbacks._native() is None:
        pytest.skip("no C compiler")
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b")
    body.add_geom(size=[0.01, 0, 0])
    body.add_joint(name="j", type=mujoco.mjtJoint.mjJNT_HINGE)
    other = spec.add_actuator(name="other", target="j", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    other.biastype = mujoco.mjtBias.mjBIAS_USER
    other.gainprm[0] = 0
    steppers.add_stepper(spec, "j", params, "physical", "full", name="stepper")
    model = spec.compile()
    callback_type = ctypes.CFUNCTYPE(
        ctypes.c_double, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int
    )
    foreign = callback_type(lambda m, d, i: 1.5)
    saved = mujoco.get_mjcb_act_dyn(), mujoco.get_mjcb_act_bias()
    try:
        mujoco.set_mjcb_act_dyn(None)
        mujoco.set_mjcb_act_bias(foreign)
        assert steppers.install("native") == "native"
        data = mujoco.MjData(model)
        data.qpos[0] = 0.01
        mujoco.mj_forward(model, data)
        assert data.actuator_force[0] == 1.5  # the other part's callback still serves its actuator
        expected = steppers.physical_torque(params, steppers.drive_mode("full"), 0.01, 0.0, 0.0)
        assert data.actuator_force[1] == pytest.approx(float(expected))
    finally:
        mujoco.set_mjcb_act_dyn(None)
        mujoco.set_mjcb_act_bias(None)
        steppers._callbacks._native().stepper_set_next(None, None)
        if saved[0] is not None or saved[1] is not None:
            steppers.install("native")


def test_load_torque_sets_the_quasi_static_lag(params):
    """A Coulomb load Tl (eq. 19) on a slow microstepped move: the rotor trails until the
    spring torque (T_hold/sqrt 2 for sine/cosine currents) balances it."""
    load = 0.4 * params.holding_torque_Nm
    loaded = params.replace(load_torque_Nm=load)
    run = steppers.simulate(step_profiles.move(2, 20), "physical", "micro16", loaded, settle_s=0.02)
    middle = (run.time_s > 0.03) & (run.time_s < 0.07)
    lag_deg = float(np.mean(run.command_deg[middle] - run.rotor_deg[middle]))
    expected = math.degrees(
        math.asin(load * math.sqrt(2) / params.holding_torque_Nm) / params.pole_pairs
    )
    assert lag_deg == pytest.approx(expected, rel=0.1)
    # at rest the friction holds the rotor anywhere inside that band
    assert abs(run.summary["final_error_deg"]) <= expected


def _shipped_description_text():
    from mechanism.machine.models import DEFAULT_DESCRIPTION

    return DEFAULT_DESCRIPTION.read_text()


def test_another_described_stepper_is_read_from_its_description(tmp_path):
    text = _shipped_description_text()
    path = tmp_path / "other.toml"
    path.write_text(
        text.replace("pole_pairs = 12", "pole_pairs = 6")
        .replace("step_angle_deg = 7.5", "step_angle_deg = 15.0")
        .replace("holding_torque_Nm = 0.025", "holding_torque_Nm = 0.05")
        .replace("forward_s = 0.35", "forward_s = 0.2")
    )
    params = steppers.described_stepper(path, load_torque_Nm=0.001)
    assert (
        params.pole_pairs,
        params.step_angle_deg,
        params.holding_torque_Nm,
        params.load_torque_Nm,
    ) == (6, 15.0, 0.05, 0.001)
    assert params.resistance_ohm == steppers.pm25s048().resistance_ohm
    assert step_profiles.thread_cut_stroke_steps(path) == 200  # 0.2 s at 1000 steps/s
    assert step_profiles.thread_cut(machine=path).peak_steps() == pytest.approx(200)


@pytest.mark.parametrize(
    "edit, expected",
    [
        (
            lambda t: t.replace("step_angle_deg = 7.5", "step_angle_deg = 15.0"),
            "[stepper] step_angle_deg",
        ),
        (lambda t: re.sub(r"^supply_V = .*\n", "", t, flags=re.M), "[stepper] supply_V: missing"),
        (lambda t: re.sub(r"^step_rate_steps_s = .*\n", "", t, flags=re.M), "[thread_cut]"),
        (
            lambda t: t.replace("inductance_H = 0.012", "inductance_H = -1"),
            "[stepper] inductance_H",
        ),
    ],
)
def test_bad_stepper_sections_are_one_user_error(tmp_path, edit, expected):
    path = tmp_path / "bad.toml"
    path.write_text(edit(_shipped_description_text()))
    with pytest.raises(UserError, match=re.escape(expected)):
        steppers.described_stepper(path)


def test_a_machine_without_a_stepper_says_so(tmp_path):
    text = _shipped_description_text()
    start, end = text.index("[stepper]"), text.index("[inspect]")
    path = tmp_path / "none.toml"
    path.write_text(text[:start] + text[end:])
    with pytest.raises(UserError, match="no stepper"):
        steppers.described_stepper(path)
    with pytest.raises(UserError, match="no thread cut"):
        step_profiles.thread_cut_timing(path)
