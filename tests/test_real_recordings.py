"""Real recordings of machines of other kinds (tests/data/real/README.md): a geared servo
holding a pendulum and a current-controlled positioning axis. Every recording is accepted, the
baseline's held-out error is within 1.25x that of the published simplest model, and the
diagnosis's final error is at or below that of the published best model, each replayed by the
same protocol (the same segments, the same simulator, the same velocity definition)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

from mechanism.api import diagnose, drive_nominal
from mechanism.dynamics.lumped import DriveNominal, MotorConstants
from mechanism.kinematics.linkage import LinkageTables
from mechanism.machine.machine import load_machine
from mechanism.sysid.effects import Effect, Stribeck
from mechanism.sysid.identification import ModelStructure, identify
from mechanism.sysid.lumped_baseline import LumpedBaseline
from mechanism.sysid.recording import read_recording

REAL = Path(__file__).parent / "data" / "real"
WITHIN = 1.25  # the baseline's error at most this multiple of the published simplest model's

# bam's published M1 for the XL330 (params/xl330/m1.json at the fixtures' commit)
XL330 = {
    "armature": 0.001643216859746982,
    "friction_base": 0.0069659724474934286,
    "friction_viscous": 0.010494765451601431,
    "q_offset": 0.01795252374733891,
    "mass": 0.49,
    "length": 0.1,
}
# bam's published best model for the XL330, M6 "Stribeck load-dependent directional quadratic"
# (params/xl330/m6.json at the fixtures' commit; the law is bam/model.py Model.compute_frictions
# there, the paper's eq. for M6). At that commit the XL330 has M1, M2 and M6 identified; M6 is the
# richest and the one the paper (arXiv:2410.08650, Fig. 5: four other servos) finds best. Its
# motor constants differ from M1's: kt 0.3036 N m/A, R 2.445 ohm.
XL330_M6 = {
    "kt": 0.303609876267925,
    "R": 2.444951107725838,
    "armature": 0.0020566024734211697,
    "q_offset": 0.02113563649978374,
    "friction_base": 0.0004496236724962162,
    "friction_stribeck": 8.98236594176617e-05,
    "load_friction_motor": 0.28425109160327744,
    "load_friction_external": 0.13631427926858256,
    "load_friction_motor_stribeck": 0.000962295552186495,
    "load_friction_external_stribeck": 0.07756269586185101,
    "load_friction_motor_quad": 0.0052586872345423965,
    "load_friction_external_quad": 0.009015695123707009,
    "dtheta_stribeck": 0.7791999762669103,
    "alpha": 1.8121453469382847,
    "friction_viscous": 0.008178654749130088,
}
# the physics bam's analysis names for a servo's friction (Stribeck M2, load-dependent and
# directional M3-M6), in this library's names
XL330_PUBLISHED_EFFECTS = {"stribeck", "gear_load_friction"}
# the EMPS benchmark's IDIM-LS model (Simulation_EMPS.m) and the fixtures' virtual shaft radius
EMPS = {
    "M": 95.1089,
    "Fv": 203.5034,
    "Fc": 20.3935,
    "OF": -3.1648,
    "gtau": 35.15065188,
    "radius": 0.01,
}


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
    tables = LinkageTables(
        angle, np.full(720, inertia), np.zeros(720), mgl * np.sin(angle + XL330["q_offset"]), {}, {}
    )
    baseline = LumpedBaseline(dataclasses.replace(nominal, linkage=tables), gravity=True)
    n = nominal.ratio
    values = {
        "inertia_motor_side_kgm2": inertia / n**2,
        "viscous_motor_side_Nm_s_per_rad": XL330["friction_viscous"] / n**2,
        "coulomb_arm_Nm": XL330["friction_base"],
        "electrical_time_constant_s": 1e-5,
        "gravity_scale": 1.0,
    }
    return problem.rmse(ModelStructure(baseline), values, "val")


class PublishedLoadFriction(Effect):
    """bam's M6 load-dependent terms, replayed with the published numbers (bam/model.py at
    af22604, Model.compute_frictions, directional, Stribeck and quadratic): with tm the motor's
    torque and te the external (gravity) torque, both as torques applied to the output,

        kinetic  += |ke te - km tm|
        static   += |kes te - kms tm| + [sgn te != sgn tm] (|te| < |tm| ? kqe te^2 : |te| > |tm| ? kqm tm^2 : 0)

    the static part decaying as bam's Stribeck coefficient exp(-(|w|/ws)^alpha) (this
    simulator's Stribeck term). The library's gear_load_friction is another parametrisation of
    the same physics (a share of |tm| by the direction of the power flow, no te term), so the
    published law is replayed here as published. One difference of protocol: tm is taken at the
    logged voltage and the measured speed (as gear_load_friction does), bam's at its simulated
    speed."""

    name = "published_load_friction"
    enters = "friction"

    def apply(self, v, s, drive):
        p = XL330_M6
        w = s.velocity_rad_s
        tm = p["kt"] / p["R"] * drive.voltage_V - p["kt"] ** 2 / p["R"] * w
        # the baseline's gravity torque, resisting; bam's bias torque is applied
        te = -drive.tau_arm_Nm
        drive.coulomb_Nm = drive.coulomb_Nm + np.abs(
            p["load_friction_external"] * te - p["load_friction_motor"] * tm
        )
        quadratic = (np.sign(te) != np.sign(tm)) * np.where(
            np.abs(te) < np.abs(tm),
            p["load_friction_external_quad"] * te**2,
            np.where(np.abs(te) > np.abs(tm), p["load_friction_motor_quad"] * tm**2, 0.0),
        )
        drive.static_excess_Nm = (
            drive.static_excess_Nm
            + np.abs(
                p["load_friction_external_stribeck"] * te - p["load_friction_motor_stribeck"] * tm
            )
            + quadratic
        )


def xl330_published_best_rmse(problem, nominal: DriveNominal) -> float:
    """bam's M6 in this tool's simulator: the pendulum (M6's armature and angle offset), M6's
    motor constants, Coulomb and viscous friction, the library's Stribeck term with M6's base
    Stribeck friction, velocity and exponent, and M6's load-dependent terms; no winding lag."""
    p = XL330_M6
    angle = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    mgl = XL330["mass"] * 9.80665 * XL330["length"]
    inertia = p["armature"] + XL330["mass"] * XL330["length"] ** 2
    tables = LinkageTables(
        angle, np.full(720, inertia), np.zeros(720), mgl * np.sin(angle + p["q_offset"]), {}, {}
    )
    described = dataclasses.replace(nominal, linkage=tables)
    baseline = LumpedBaseline(described, free=("R", "Kt", "Ke"), gravity=True)
    n = nominal.ratio
    values = {
        "inertia_motor_side_kgm2": inertia / n**2,
        "viscous_motor_side_Nm_s_per_rad": p["friction_viscous"] / n**2,
        "coulomb_arm_Nm": p["friction_base"],
        "electrical_time_constant_s": 1e-5,
        "gravity_scale": 1.0,
        "motor_resistance_ohm": p["R"],
        "motor_torque_constant_Nm_per_A": p["kt"] / n,
        "motor_back_emf_V_s_per_rad": p["kt"] / n,
        "static_excess_arm_Nm": p["friction_stribeck"],
        "stribeck_velocity_arm_rad_s": p["dtheta_stribeck"],
        "stribeck_exponent": p["alpha"],
    }
    structure = ModelStructure(baseline, (Stribeck(described), PublishedLoadFriction(described)))
    return problem.rmse(structure, values, "val")


@pytest.mark.parametrize("path", xl330_recordings(), ids=lambda p: p.stem)
def test_a_servo_holding_a_pendulum_is_accepted_and_its_baseline_matches_the_published_model(
    path, xl330_nominal
):
    result = identify(read_recording(path), nominal=xl330_nominal)  # refused recordings raise
    terms = result.to_json()["baseline_terms"]
    assert terms["model_gravity_torque"], terms["why"]
    published = xl330_published_rmse(result.problem, xl330_nominal)
    assert result.rmse <= WITHIN * published, (result.rmse, published)
    assert abs(result.params["gravity_scale"] - 1) < 0.3  # a prior: the pendulum's gravity is known


@pytest.mark.slow
@pytest.mark.parametrize("path", xl330_recordings(), ids=lambda p: p.stem)
def test_a_servo_holding_a_pendulum_is_diagnosed_at_or_below_the_published_best_model(
    path, xl330_nominal
):
    """The diagnosis (the API the CLI calls) ends at or below bam's best model (M6) replayed by
    the same protocol, and what it names is friction of the kinds bam's analysis found, or it
    says the residual is unexplained, with its numbers."""
    machine = load_machine(REAL / "xl330" / "xl330_pendulum.toml")
    result = diagnose(machine, path)
    published = xl330_published_best_rmse(result.problem, xl330_nominal)
    final = result.final.rmse_val
    print(
        f"{path.stem}: baseline {result.baseline.rmse_val:.3f}, final {final:.3f} rad/s {result.effect_names}; "
        f"published M6 {published:.3f}, M1 {xl330_published_rmse(result.problem, xl330_nominal):.3f} rad/s"
    )
    assert final <= published, (final, published, result.effect_names)
    named = set(result.effect_names)
    if not named <= XL330_PUBLISHED_EFFECTS:
        assert result.unexplained is not None, result.effect_names
        numbers = result.unexplained.to_json()
        print(
            f"  unexplained: {numbers['times_noise_floor']:.1f}x the noise floor ({numbers['noise_floor_rad_s']:.3f} rad/s)"
        )
        assert numbers["rmse"] == pytest.approx(final) and numbers["times_noise_floor"] > 1, numbers


def emps_described_wrongly() -> DriveNominal:
    """EMPS described 1.5x too heavy, with half the Coulomb and twice the viscous friction; a
    current-controlled drive: no back-emf damping."""
    r = EMPS["radius"]
    motor = MotorConstants(1.0, EMPS["gtau"] * r, 1e-6, 1.0)
    return DriveNominal(
        motor,
        inertia_kgm2=1.5 * EMPS["M"] * r**2,
        coulomb_shaft_Nm=0.5 * EMPS["Fc"] * r,
        viscous_shaft_Nm_s_per_rad=2 * EMPS["Fv"] * r**2,
    )


def emps_published_rmse(problem, described: DriveNominal) -> float:
    """The benchmark's IDIM-LS model (Coulomb, viscous, offset) replayed by the tool's protocol."""
    r = EMPS["radius"]
    values = {
        "inertia_motor_side_kgm2": EMPS["M"] * r**2,
        "viscous_motor_side_Nm_s_per_rad": EMPS["Fv"] * r**2,
        "coulomb_arm_Nm": EMPS["Fc"] * r,
        "electrical_time_constant_s": 1e-5,
        "offset_torque_arm_Nm": EMPS["OF"] * r,
    }
    return problem.rmse(ModelStructure(LumpedBaseline(described, offset=True)), values, "val")


def test_a_positioning_axis_baseline_matches_the_published_model_with_its_offset():
    """EMPS, described 1.5x too heavy, with half the Coulomb and twice the viscous friction:
    the baseline (which carries a constant offset force: the axis moves both ways) lands on the
    benchmark's model and its held-out error."""
    r = EMPS["radius"]
    described = emps_described_wrongly()
    result = identify(read_recording(REAL / "emps.csv"), nominal=described)
    published = emps_published_rmse(result.problem, described)
    assert result.rmse <= WITHIN * published, (result.rmse, published)
    p = result.params
    assert p["inertia_motor_side_kgm2"] == pytest.approx(EMPS["M"] * r**2, rel=0.15)
    assert p["coulomb_arm_Nm"] == pytest.approx(EMPS["Fc"] * r, rel=0.15)
    assert p["viscous_motor_side_Nm_s_per_rad"] == pytest.approx(EMPS["Fv"] * r**2, rel=0.15)
    assert p["offset_torque_arm_Nm"] == pytest.approx(EMPS["OF"] * r, rel=0.3)


@pytest.mark.slow
def test_a_positioning_axis_is_diagnosed_at_or_below_the_published_model():
    """EMPS: the benchmark's only published model is its reference (IDIM-LS, Coulomb-viscous with
    an offset), so the best published model is the simplest; the diagnosis, started from the
    same wrong description as above, ends at or below its held-out error."""
    from mechanism.sysid.diagnosis import diagnose as diagnose_recording

    described = emps_described_wrongly()
    result = diagnose_recording(read_recording(REAL / "emps.csv"), nominal=described)
    published = emps_published_rmse(result.problem, described)
    final = result.final.rmse_val
    print(
        f"EMPS: baseline {result.baseline.rmse_val:.4f}, final {final:.4f} rad/s {result.effect_names}; "
        f"published IDIM-LS {published:.4f} rad/s"
    )
    assert final <= published, (final, published, result.effect_names)
