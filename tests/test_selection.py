"""The selection rule's parts that need no long recording: generic models say what physics
could be behind them, and the joint rule is stricter than the forward step."""

from mechanism.sysid import diagnosis
import numpy as np

from mechanism.dynamics.lumped import Signals
from mechanism.sysid.generic import (
    GenericChange,
    GenericSaturation,
    GenericShaftTorque,
    GenericSpeedFriction,
    evidence,
    peak_current_A,
)
from mechanism.sysid.identification import ModelStructure
from mechanism.sysid.lumped_baseline import LumpedBaseline
from tests.helpers.nominal import SAPPHIRE, effects


def test_generic_models_name_possible_physics_and_no_mechanism():
    for effect in (
        GenericSpeedFriction(SAPPHIRE, 40.0),
        GenericChange(SAPPHIRE, 10.0, 60.0),
        GenericShaftTorque(SAPPHIRE, "shaft", 1.0, [4]),
        GenericSaturation(SAPPHIRE, 15.0),
    ):
        values = {p.name: p.nominal for p in effect.parameters}
        text = evidence(effect, values, "periodic in the shaft angle", 0.2, 0.1)
        assert (
            effect.generic
            and "possible physics: " + effect.physics in text
            and "names no mechanism" in text
        )
        assert "50% lower" in text


def test_the_joint_rule_is_stricter_than_the_forward_step():
    assert diagnosis.STEP_GAIN < diagnosis.KEEP_GAIN_JOINT <= diagnosis.MIN_RELATIVE_GAIN
    assert diagnosis.GENERIC_GAIN == 0.30


def test_a_saturation_clips_the_motor_torque_at_its_current_and_its_null_is_the_model_it_extends():
    """Net motor torque n Kt clip(i, +/- limit) at the logged voltage and measured speed, i the
    described motor's current; at its null (the largest current the recording draws) nothing
    changes, to the last bit."""
    n = 400
    t = np.arange(n) * 1e-3
    speed = np.linspace(0.0, 120.0, n)
    signals = Signals(t, np.where(t < 0.2, 18.0, 6.0), np.cumsum(speed) * 1e-3, speed, 1e-3, 8.0)
    base = LumpedBaseline(SAPPHIRE)
    values = {p.name: p.nominal for p in base.parameters}
    m = SAPPHIRE.motor
    current = (signals.voltage_V - m.back_emf_V_s_per_rad * m.ratio * speed) / m.resistance_ohm
    peak = peak_current_A(SAPPHIRE, signals)
    assert peak == np.abs(current).max()
    effect = GenericSaturation(SAPPHIRE, peak)
    untouched = base.drive(values, signals).tau_motor_Nm.copy()
    drive = base.drive(values, signals)
    effect.apply({"current_limit_A": peak}, signals, drive)
    assert np.array_equal(drive.tau_motor_Nm, untouched)
    drive = base.drive(values, signals)
    effect.apply({"current_limit_A": 4.0}, signals, drive)
    net = m.gain_arm * drive.voltage_V - m.emf_damping_arm * speed - drive.tau_motor_Nm + untouched
    np.testing.assert_allclose(
        net, m.ratio * m.torque_constant_Nm_per_A * np.clip(current, -4.0, 4.0), atol=1e-12
    )
    assert np.abs(current).max() > 4.0 > np.abs(current).min()  # both sides of the limit tested


def test_one_transmission_holds_one_compliance():
    """A free play and an elastic belt both set the one transmission between motor and shaft:
    in one model the later overwrote the earlier, whose parameters then did nothing, and a
    diagnosis of a free play beside a warming winding named a belt as well (the pair's gain was
    only a new start for the same physics). A model holding either admits neither; every other
    library effect adds to the drive and joins beside them."""
    lib = effects()
    empty = ModelStructure(LumpedBaseline(SAPPHIRE))
    assert all(empty.admits(e) for e in lib.values())
    for held in ("backlash", "belt_compliance"):
        structure = empty.with_effect(lib[held])
        refused = {name for name, e in lib.items() if not structure.admits(e)}
        assert refused == {"backlash", "belt_compliance"}


def test_pairs_from_the_fit_half_need_a_clear_gain_there_and_are_asked_for():
    """Singles that cut the fit half's error and raise the validation half's are paired only
    where the caller asks for fit-half pairs (the search far above the noise) and only from a
    cut of at least the given fraction: added freedom always fits the fit half a little better,
    and pairing every such single cost an outside-library recording 18 s instead of 8."""
    from mechanism.sysid.identification import FitResult

    lib = effects()
    current = FitResult(ModelStructure(LumpedBaseline(SAPPHIRE)), {}, {}, 1.0, 1.0)

    class Runner:  # records the pairs it is asked to fit
        problem = object()

        def __init__(self):
            self.fitted = []

        def run(self, jobs):
            self.fitted += [set(structure.names) for structure, *_ in jobs]
            return [FitResult(structure, {}, {}, 0.5, 0.5) for structure, *_ in jobs]

    def paired(fit_rmse: dict[str, float], fit_gain):
        singles = {
            name: FitResult(current.structure.with_effect(lib[name]), {}, {}, rmse, 1.2)
            for name, rmse in fit_rmse.items()
        }
        runner = Runner()
        diagnosis._best_pair(
            runner.problem, current, singles, lib, lambda what: None, runner, fit_gain=fit_gain
        )
        return runner.fitted

    hidden = {"thermal_drift": 0.8, "winding_heating": 0.7}
    assert paired(hidden, None) == []
    assert paired(hidden, 0.1) == [{"thermal_drift", "winding_heating"}]
    marginal = {"winding_heating": 0.7, "stribeck": 0.97}
    assert paired(marginal, 0.1) == []
    assert paired(marginal, 0.02) == [{"winding_heating", "stribeck"}]
