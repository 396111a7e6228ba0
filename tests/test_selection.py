"""The selection rule's parts that need no long recording: generic models say what physics
could be behind them, and the joint rule is stricter than the forward step."""

from mechanism.sysid import diagnosis
from mechanism.sysid.generic import (
    GenericChange,
    GenericShaftTorque,
    GenericSpeedFriction,
    evidence,
)
from tests.helpers.nominal import SAPPHIRE


def test_generic_models_name_possible_physics_and_no_mechanism():
    for effect in (
        GenericSpeedFriction(SAPPHIRE, 40.0),
        GenericChange(SAPPHIRE, 10.0, 60.0),
        GenericShaftTorque(SAPPHIRE, "shaft", 1.0, [4]),
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
