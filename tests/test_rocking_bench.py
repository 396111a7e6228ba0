"""The virtual bench and the diagnosis on a drive that rocks between stops.

The truth model's gravity, inertia and stops are checked against a pendulum's closed forms
(a hand-built drive, no CAD); the bench on a CAD four-bar that cannot turn a whole revolution
(a draft from `mechanism init`) stays inside its travel and reverses, its clean recording
gives no finding and a concealed friction effect is named."""

import math
import textwrap

import numpy as np
import pytest

from tests.helpers.exports import FourBar

G = 9.81


def _pendulum_nominal(
    mass=0.2, radius=0.05, travel_deg=(-60.0, 60.0), ke=1e-6, kt=0.05, resistance=2.0
):
    """A point mass on a massless arm, hanging at shaft angle 0, driven directly (1:1): its
    gravity torque m g r sin(theta) and inertia m r^2 as a linkage table over the travel."""
    from mechanism.dynamics.lumped import DriveNominal, MotorConstants
    from mechanism.kinematics.linkage import LinkageTables

    lo, hi = (math.radians(v) for v in travel_deg)
    angle = np.linspace(lo, hi, 721)
    inertia = mass * radius**2
    tables = LinkageTables(
        angle,
        np.full_like(angle, inertia),
        np.zeros_like(angle),
        mass * G * radius * np.sin(angle),
        ratios={},
        positions={},
        periodic=False,
    )
    return DriveNominal(
        MotorConstants(resistance, kt, ke, 1.0),
        inertia_kgm2=inertia,
        coulomb_shaft_Nm=0.0,
        viscous_shaft_Nm_s_per_rad=0.0,
        zero_meaning="the arm hanging straight down",
        linkage=tables,
        travel_rad=(lo, hi),
    )


def _held(nominal, volts, duration_s, start_rad, **extra):
    from mechanism.testbench import make_recording

    return make_recording(
        "none",
        seed=1,
        duration_s=duration_s,
        nominal=nominal,
        randomize_baseline=False,
        coulomb_arm_Nm=0.0,
        viscous_motor_side_Nm_s_per_rad=0.0,
        voltage_plateaus=[(duration_s, volts)],
        start_angle_rad=start_rad,
        current_noise_A=0.0,
        **extra,
    )


def test_the_truth_swings_as_a_small_angle_pendulum():
    """No friction, no back-emf worth the name: the period is 2 pi sqrt(r / g)."""
    radius = 0.05
    rec = _held(_pendulum_nominal(radius=radius), 0.0, 3.0, 0.05)
    angle = rec.traces["arm_angle_rad"]
    crossings = rec.time[1:][(angle[:-1] > 0) & (angle[1:] <= 0)]
    period = float(np.mean(np.diff(crossings)))
    assert period == pytest.approx(2 * math.pi * math.sqrt(radius / G), rel=2e-3)
    assert np.max(np.abs(angle)) == pytest.approx(0.05, rel=1e-3)  # no energy lost or gained


def test_a_held_voltage_balances_gravity_where_kt_v_over_r_is_m_g_r_sin():
    mass, radius, kt, resistance, volts = 0.2, 0.05, 0.05, 2.0, 1.5
    nominal = _pendulum_nominal(mass, radius, ke=0.05, kt=kt, resistance=resistance)
    rec = _held(nominal, volts, 10.0, 0.0)  # back-emf damping only (zeta 0.09): settled in 10 s
    expected = math.asin(kt * volts / resistance / (mass * G * radius))
    assert rec.traces["arm_angle_rad"][-1] == pytest.approx(expected, abs=1e-4)
    assert abs(rec.traces["arm_velocity_rad_s"][-1]) < 1e-4 * math.sqrt(G / radius)


def test_the_truth_stops_at_the_limits_and_stays_there():
    nominal = _pendulum_nominal(ke=0.05)
    lo, hi = nominal.travel_rad
    for volts, end in ((12.0, hi), (-12.0, lo)):
        rec = _held(nominal, volts, 1.0, 0.0)
        angle = rec.traces["arm_angle_rad"]
        assert angle.min() >= lo - 1e-12 and angle.max() <= hi + 1e-12
        assert angle[-1] == pytest.approx(end, abs=1e-12)
        assert rec.traces["arm_velocity_rad_s"][-1] == 0.0
        # stalled against the stop: the whole voltage drives the current
        assert rec.traces["current_A"][-1] == pytest.approx(volts / 2.0, rel=1e-3)


def test_the_python_twin_agrees_with_the_compiled_truth_on_a_rocker():
    nominal = _pendulum_nominal(ke=0.05)
    native = _held(nominal, 1.0, 0.3, -0.5)
    twin = _held(nominal, 1.0, 0.3, -0.5, integrator="python")
    np.testing.assert_allclose(
        twin.traces["arm_angle_rad"], native.traces["arm_angle_rad"], atol=1e-9
    )


# --- the CAD four-bar that cannot turn (a draft from init) ----------------------------------

DRAFT = """\
[machine]
name = "fourbar"
model = "fourbar.xml"
[drive]
motor_joint = "ground--crank"
shaft_joint = "ground--crank"
zero_site = "crank_end"
[motor]
type = "dc"
resistance_ohm = 2.0
torque_constant_Nm_per_A = 0.03
back_emf_V_s_per_rad = 0.03
[friction."ground--crank"]
coulomb_Nm = 0.0
viscous_Nm_s_per_rad = 0.0
[limits."ground--crank"]
lower_deg = -180.913
upper_deg = 20.9134
[tool]
site = "crank_end"
plate = "frame"
"""


@pytest.fixture(scope="module")
def rocker(tmp_path_factory):
    """(description path, DriveNominal) of the non-Grashof four-bar, as init drafts it."""
    import mechanism
    from mechanism.api import drive_nominal

    folder = tmp_path_factory.mktemp("rocking_bench")
    FourBar(
        crank=35.0, coupler=40.0, rocker=45.0, ground=70.0, crank_angle0=math.radians(80.0)
    ).export(folder)
    path = folder / "draft.toml"
    path.write_text(textwrap.dedent(DRAFT))
    return path, drive_nominal(mechanism.load_machine(path))


@pytest.mark.slow
def test_a_rocking_recording_stays_inside_the_travel_and_reverses(rocker, tmp_path):
    from mechanism.testbench import make_recording, write_recording

    _, nominal = rocker
    lo, hi = nominal.travel_rad
    rec = make_recording("none", seed=0, duration_s=10.0, nominal=nominal)
    true = rec.traces["arm_angle_rad"]
    assert lo < true.min() and true.max() < hi  # never at a stop: the bench keeps it in its travel
    span = hi - lo
    assert np.ptp(true) > 0.5 * span  # and uses most of it
    velocity = rec.traces["arm_velocity_rad_s"]
    reversals = np.count_nonzero(np.diff(np.sign(velocity[np.abs(velocity) > 0.5])))
    assert reversals >= 4
    assert rec.voltage.min() < 0 < rec.voltage.max()
    assert np.max(np.abs(rec.voltage)) <= 24.0
    csv, _ = write_recording(rec, tmp_path / "rock.csv")
    header = csv.read_text().splitlines()[1]
    assert "0 = crank_end at its top" in header and "needle" not in header


@pytest.mark.slow
def test_a_rocking_bench_refuses_effects_that_need_whole_turns(rocker, cli, tmp_path):
    from mechanism.errors import UserError
    from mechanism.sysid.effects import library
    from mechanism.testbench import make_recording

    path, nominal = rocker
    result = cli(
        "testbench",
        "--machine",
        path,
        "--effect",
        "torque_ripple",
        "-o",
        tmp_path / "r.csv",
        "--duration",
        "1",
    )
    result.assert_bad_input()
    assert "torque_ripple" in result.stderr and "rocks" in result.stderr
    assert not (tmp_path / "r.csv").exists()
    for effect in ("needle_penetration", "encoder_eccentricity", "linkage_dynamics"):
        with pytest.raises(UserError, match=f"{effect} does not apply to a shaft that rocks"):
            make_recording(effect, duration_s=0.1, nominal=nominal)
    # a switch distortion anchored at 4.5 and 12 V means nothing for a drive the bench moves with ~1.6 V
    with pytest.raises(UserError, match="anchored at 4.5 and 12 V"):
        make_recording("voltage_nonlinearity", duration_s=0.1, nominal=nominal)
    # and the diagnosis does not offer those that need whole turns
    offered = set(library(nominal))
    assert not offered & {
        "torque_ripple",
        "needle_penetration",
        "encoder_eccentricity",
        "linkage_dynamics",
    }
    assert {"position_friction", "stribeck"} <= offered


def _diagnosis(nominal, effect, tmp_path, seed=0, duration_s=20.0):
    """The bench's recording of ``effect`` written and read back as any recording, diagnosed
    with the baseline the command line picks for a rocking machine."""
    from types import SimpleNamespace

    from mechanism.cli.identify import resolve_baseline
    from mechanism.sysid.diagnosis import diagnose
    from mechanism.sysid.recording import read_recording
    from mechanism.testbench import make_recording, write_recording

    csv, _ = write_recording(
        make_recording(effect, seed=seed, duration_s=duration_s, nominal=nominal),
        tmp_path / "rec.csv",
    )
    baseline = resolve_baseline(SimpleNamespace(baseline=None), nominal)
    return diagnose(read_recording(csv), baseline, nominal=nominal, workers=1).to_json()


@pytest.mark.slow
def test_a_rocking_machine_is_diagnosed_with_its_multibody_baseline_by_default(rocker):
    from types import SimpleNamespace

    from mechanism.api import drive_nominal
    from mechanism.cli.identify import resolve_baseline

    _, nominal = rocker
    assert resolve_baseline(SimpleNamespace(baseline=None), nominal) == "multibody"
    assert resolve_baseline(SimpleNamespace(baseline="lumped"), nominal) == "lumped"
    # the sewing machine turns
    assert resolve_baseline(SimpleNamespace(baseline=None), drive_nominal(None)) == "lumped"


@pytest.mark.slow
def test_a_clean_rocking_recording_is_fitted_to_its_noise_and_nothing_is_named(rocker, tmp_path):
    _, nominal = rocker
    data = _diagnosis(nominal, "none", tmp_path)
    assert data["baseline"]["name"] == "multibody"
    assert [item["name"] for item in data["effects"]] == []
    # the baseline's validation error stays below the recording's noise floor
    assert data["baseline"]["rmse"] < data["noise_floor"]["rmse_rad_s"]
    assert data["baseline"]["params"]["cad_gravity_scale"] == pytest.approx(1.0, abs=0.05)


@pytest.mark.slow
def test_a_concealed_position_friction_on_a_rocker_is_named(rocker, tmp_path):
    _, nominal = rocker
    data = _diagnosis(nominal, "position_friction", tmp_path)
    found = [item["name"] for item in data["effects"]]
    assert found[:1] == ["position_friction"]
    assert data["final"]["rmse"] < 0.1 * data["baseline"]["rmse"]
    evidence = data["effects"][0]["evidence"]
    assert "needle" not in evidence and "crank_end at its top" in evidence and "travel" in evidence
