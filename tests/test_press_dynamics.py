"""The bench press as a Machine: its description loads, and the simulated steady speed is the
motor equation's with the described friction (computed here from the parameter file)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

import mechanism

REPO = Path(__file__).resolve().parent.parent
PARAMS = json.loads((REPO / "assets" / "cad" / "press" / "press.params.json").read_text())
DESCRIPTION = REPO / "assets" / "machines" / "press.toml"
DATASHEET = {key: entry["value"] for key, entry in PARAMS["datasheet"].items()}
RATIO = PARAMS["worm_gear"]["wheel_teeth"]["value"] / PARAMS["worm_gear"]["worm_starts"]["value"]

if not hasattr(mechanism, "load_machine"):
    pytest.skip("mechanism.load_machine is not there yet", allow_module_level=True)


def test_description_carries_the_parameter_files_datasheet():
    text = tomllib.loads(DESCRIPTION.read_text())
    motor, friction = text["motor"], text["friction"]
    assert motor["type"] == "dc"
    for key in ("resistance_ohm", "torque_constant_Nm_per_A", "back_emf_V_s_per_rad"):
        assert motor[key] == DATASHEET[key], key
    crank, rotor = friction[text["drive"]["shaft_joint"]], friction[text["drive"]["motor_joint"]]
    assert (crank["coulomb_Nm"], crank["viscous_Nm_s_per_rad"]) == (
        DATASHEET["crank_coulomb_Nm"],
        DATASHEET["crank_viscous_Nm_s_per_rad"],
    )
    assert (rotor["coulomb_Nm"], rotor["viscous_Nm_s_per_rad"]) == (
        DATASHEET["motor_coulomb_Nm"],
        DATASHEET["motor_viscous_Nm_s_per_rad"],
    )


@pytest.fixture(scope="module")
def press():
    return mechanism.load_machine("press")


def test_the_press_is_shipped_and_its_roles_resolve(press):
    assert "press" in mechanism.shipped_machines()
    # assembly pose = ram at top dead centre
    assert press.frame.zero_rad == pytest.approx(0.0, abs=1e-9)
    # a positive motor turn is a positive crank turn (right-hand worm)
    assert press.frame.direction == 1.0
    assert press.motor_ratio == pytest.approx(RATIO, rel=1e-9)
    # the ram tip over the die plate: 1.625 in at the top, 0.125 in at the bottom
    assert press.tool_height_mm_at(np.array([0.0, np.pi])) == pytest.approx(
        [41.275, 3.175], abs=1e-6
    )


def hand_speed(voltage: float) -> float:
    """ω = (n Kt V/R - F_c)/(n² Kt Ke/R + c): motor torque through the worm against the friction
    referred to the crank (F_c = F_crank + n F_motor, c = c_crank + n² c_motor)."""
    d, n = DATASHEET, RATIO
    coulomb = d["crank_coulomb_Nm"] + n * d["motor_coulomb_Nm"]
    viscous = d["crank_viscous_Nm_s_per_rad"] + n**2 * d["motor_viscous_Nm_s_per_rad"]
    drive = n * d["torque_constant_Nm_per_A"] / d["resistance_ohm"]
    return (drive * voltage - coulomb) / (drive * n * d["back_emf_V_s_per_rad"] + viscous)


@pytest.mark.parametrize("voltage", [12.0, 24.0])
def test_steady_speed_is_the_motor_equation_with_the_described_friction(press, voltage):
    """Over whole turns, power balance gives A mean(ω) = B mean(ω²) (A, B: numerator and denominator
    of hand_speed): the speed ripple from the varying inertia and the ram's weight lowers the mean
    by var(ω)/mean(ω), well under 1 % here."""
    columns = mechanism.simulate(press, voltage_V=voltage, duration_s=1.5).columns()
    time, speed = np.asarray(columns["time_s"]), np.asarray(columns["arm_velocity_rad_s"])
    steady = speed[time > 0.5]
    ripple = float(steady.var() / steady.mean())
    assert ripple < 0.002 * steady.mean()
    assert steady.mean() == pytest.approx(hand_speed(voltage) - ripple, rel=0.01)
    # the motor turns 20 times as fast, and the current is what the motor equation says
    motor = np.asarray(columns["motor_velocity_rad_s"])[time > 0.5]
    assert motor.mean() == pytest.approx(RATIO * steady.mean(), rel=1e-3)
    current = np.asarray(columns["current_A"])[time > 0.5]
    expected = (voltage - DATASHEET["back_emf_V_s_per_rad"] * motor.mean()) / DATASHEET[
        "resistance_ohm"
    ]
    assert current.mean() == pytest.approx(expected, rel=1e-3)
