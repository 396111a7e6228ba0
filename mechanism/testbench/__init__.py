"""The virtual test bench: bench recordings from a truth model with concealed effects.

A separate code path from identification and diagnosis (it never imports them), so that
diagnosing its recordings is a real test. The truth model is the thesis's lumped sewing
machine (DC motor, 8:1 belt, arm shaft with Coulomb + viscous friction and true
stick-slip), randomised per seed, plus any of the effects in :data:`EFFECTS`.

    from mechanism.testbench import make_recording, write_recording
    rec = make_recording(["torque_ripple"], seed=3)
    write_recording(rec, "rec.csv")      # rec.csv + rec.truth.json
"""

from mechanism.testbench.recording import Recording, make_recording, truth_path_for, write_recording
from mechanism.testbench.truth import ANGLE_STEP_RAD, EFFECTS, parse_effects

__all__ = [
    "ANGLE_STEP_RAD",
    "EFFECTS",
    "Recording",
    "make_recording",
    "parse_effects",
    "truth_path_for",
    "write_recording",
]
