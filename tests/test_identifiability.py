"""Identifiability is judged by the information a recording carries on the baseline's
parameters, not by the shaft turning a revolution: machines that swing back and forth are
accepted, a recording that cannot separate two parameters is refused with both named."""

import math

import numpy as np
import pytest

from mechanism.sysid.identifiability import check_information
from mechanism.sysid.identification import NotIdentifiable, identify
from mechanism.sysid.recording import make_recording
from tests.helpers.oscillating import AXIS, PENDULUM_SERVO, record


def travel(rec) -> float:
    return float(np.abs(np.diff(rec.arm_angle_rad)).sum())


@pytest.mark.parametrize("seed", [0, 1])
def test_a_swinging_pendulum_servo_is_identifiable(seed):
    """6 s at 200 Hz under a position loop, a few radians of travel in all (the old rule
    refused anything under one revolution)."""
    rec = record(PENDULUM_SERVO, seed=seed)
    assert travel(rec) < 2.5 * math.pi and np.ptp(rec.arm_angle_rad) < 2 * math.pi
    info = check_information(rec, PENDULUM_SERVO.nominal())
    assert info.identifiable, info.reason
    assert info.turns_both_ways and set(info.independent_fraction) == {
        "inertia",
        "viscous",
        "coulomb",
        "offset",
    }
    result = identify(rec, nominal=PENDULUM_SERVO.nominal())
    assert np.isfinite(result.rmse)


def test_an_axis_moving_back_and_forth_is_identified_with_its_offset():
    """A positioning axis under a position loop, never a revolution in one direction: accepted,
    and its constant offset torque is part of the baseline (the shaft turns both ways)."""
    rec = record(AXIS, seed=3, fs=1000.0, duration_s=20.0, amplitude_rad=3.0, kp=4.0, kd=0.2)
    assert np.ptp(rec.arm_angle_rad) < 2 * math.pi
    result = identify(rec, nominal=AXIS.nominal())
    p = result.params
    assert p["offset_torque_arm_Nm"] == pytest.approx(AXIS.offset_Nm, rel=0.15)
    assert p["coulomb_arm_Nm"] == pytest.approx(AXIS.coulomb_Nm, rel=0.15)
    assert p["inertia_motor_side_kgm2"] == pytest.approx(AXIS.inertia_kgm2, rel=0.1)
    assert result.to_json()["baseline_terms"]["constant_offset_torque"] is True


def test_one_speed_each_way_is_refused_naming_viscous_and_coulomb_friction():
    """A triangle move at one speed each way: viscous and Coulomb friction give the same torque
    (their regressor columns are collinear), whatever the travel."""
    t = np.arange(20000) / 1000.0
    phase = (t % 4.0) / 4.0
    angle = 3.0 * np.where(phase < 0.5, 4 * phase - 1, 3 - 4 * phase)
    rec = make_recording(t, np.where(phase < 0.5, 3.0, -3.0), angle)
    info = check_information(rec, AXIS.nominal())
    assert not info.identifiable
    assert "viscous" in info.reason and "Coulomb" in info.reason and "rad/s" in info.reason
    with pytest.raises(NotIdentifiable, match="cannot be told apart"):
        identify(rec, nominal=AXIS.nominal())
    # the same shaft at several speeds is accepted
    speed = np.where(phase < 0.5, 1.0, -1.0) * (1.0 + (t // 4.0) % 3)
    varied = make_recording(t, speed, np.cumsum(speed) / 1000.0)
    assert check_information(varied, AXIS.nominal()).identifiable


def test_a_shaft_that_hardly_moves_is_refused_in_words():
    t = np.arange(5000) / 1000.0
    rec = make_recording(t, np.where(t < 2.5, 2.0, -2.0), 1e-4 * np.sin(t))  # a stuck shaft
    info = check_information(rec, AXIS.nominal())
    assert not info.identifiable and "moves" in info.reason and "[" not in info.reason
