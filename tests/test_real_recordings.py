"""Real recordings of machines of other kinds (tests/data/real/README.md): a geared servo
holding a pendulum and a current-controlled positioning axis. Every recording is accepted and
the baseline's held-out error is within 1.25x that of the published simplest model, replayed
by the same protocol (the same segments, the same simulator, the same velocity definition)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

from mechanism.api import drive_nominal
from mechanism.dynamics.lumped import DriveNominal, MotorConstants
from mechanism.kinematics.linkage import LinkageTables
from mechanism.machine.machine import load_machine
from mechanism.sysid.identification import ModelStructure, identify
from mechanism.sysid.lumped_baseline import LumpedBaseline
from mechanism.sysid.recording import read_recording

REAL = Path(__file__).parent / "data" / "real"
WITHIN = 1.25  # the baseline's error at most this multiple of the published simplest model's

# bam's published M1 for the XL330 (params/xl330/m1.json at the fixtures' commit)
XL330 = {"armature": 0.001643216859746982, "friction_base": 0.0069659724474934286,
         "friction_viscous": 0.010494765451601431, "q_offset": 0.01795252374733891, "mass": 0.49, "length": 0.1}
# the EMPS benchmark's IDIM-LS model (Simulation_EMPS.m) and the fixtures' virtual shaft radius
EMPS = {"M": 95.1089, "Fv": 203.5034, "Fc": 20.3935, "OF": -3.1648, "gtau": 35.15065188, "radius": 0.01}


def xl330_recordings() -> list[Path]:
    found = sorted((REAL / "xl330").glob("*.csv"))
    extra = os.environ.get("MECHANISM_REAL_RECORDINGS")
    if extra:
        found += sorted(Path(extra, "xl330").glob("*.csv"))
    return found


@pytest.fixture(scope="module")
def xl330_nominal() -> DriveNominal:
    return drive_nominal(load_machine(REAL / "xl330" / "xl330_pendulum.toml"))


def xl330_published_rmse(problem, nominal: DriveNominal) -> float:
    """bam's M1 in this tool's simulator: the pendulum's inertia and gravity (with M1's angle
    offset), the servo's armature, Coulomb and viscous friction; no winding lag."""
    angle = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    mgl = XL330["mass"] * 9.80665 * XL330["length"]
    inertia = XL330["armature"] + XL330["mass"] * XL330["length"] ** 2
    tables = LinkageTables(angle, np.full(720, inertia), np.zeros(720), mgl * np.sin(angle + XL330["q_offset"]), {}, {})
    baseline = LumpedBaseline(dataclasses.replace(nominal, linkage=tables), gravity=True)
    n = nominal.ratio
    values = {"inertia_motor_side_kgm2": inertia / n**2, "viscous_motor_side_Nm_s_per_rad": XL330["friction_viscous"] / n**2,
              "coulomb_arm_Nm": XL330["friction_base"], "electrical_time_constant_s": 1e-5, "gravity_scale": 1.0}
    return problem.rmse(ModelStructure(baseline), values, "val")


@pytest.mark.parametrize("path", xl330_recordings(), ids=lambda p: p.stem)
def test_a_servo_holding_a_pendulum_is_accepted_and_its_baseline_matches_the_published_model(path, xl330_nominal):
    result = identify(read_recording(path), nominal=xl330_nominal)  # refused recordings raise
    terms = result.to_json()["baseline_terms"]
    assert terms["model_gravity_torque"], terms["why"]
    published = xl330_published_rmse(result.problem, xl330_nominal)
    assert result.rmse <= WITHIN * published, (result.rmse, published)
    assert abs(result.params["gravity_scale"] - 1) < 0.3  # a prior: the pendulum's gravity is known


def test_a_positioning_axis_baseline_matches_the_published_model_with_its_offset():
    """EMPS, described 1.5x too heavy, with half the Coulomb and twice the viscous friction:
    the baseline (which carries a constant offset force: the axis moves both ways) lands on the
    benchmark's model and its held-out error."""
    r = EMPS["radius"]
    motor = MotorConstants(1.0, EMPS["gtau"] * r, 1e-6, 1.0)  # a current-controlled drive: no back-emf damping
    described = DriveNominal(motor, inertia_kgm2=1.5 * EMPS["M"] * r**2, coulomb_shaft_Nm=0.5 * EMPS["Fc"] * r,
                             viscous_shaft_Nm_s_per_rad=2 * EMPS["Fv"] * r**2)
    result = identify(read_recording(REAL / "emps.csv"), nominal=described)
    published_values = {"inertia_motor_side_kgm2": EMPS["M"] * r**2, "viscous_motor_side_Nm_s_per_rad": EMPS["Fv"] * r**2,
                        "coulomb_arm_Nm": EMPS["Fc"] * r, "electrical_time_constant_s": 1e-5,
                        "offset_torque_arm_Nm": EMPS["OF"] * r}
    published = result.problem.rmse(ModelStructure(LumpedBaseline(described, offset=True)), published_values, "val")
    assert result.rmse <= WITHIN * published, (result.rmse, published)
    p = result.params
    assert p["inertia_motor_side_kgm2"] == pytest.approx(EMPS["M"] * r**2, rel=0.15)
    assert p["coulomb_arm_Nm"] == pytest.approx(EMPS["Fc"] * r, rel=0.15)
    assert p["viscous_motor_side_Nm_s_per_rad"] == pytest.approx(EMPS["Fv"] * r**2, rel=0.15)
    assert p["offset_torque_arm_Nm"] == pytest.approx(EMPS["OF"] * r, rel=0.3)
