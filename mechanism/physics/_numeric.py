"""The custom numeric blocks the compiled passive callback reads (``native/machine.c``)."""

from __future__ import annotations

import mujoco
import numpy as np


def numeric_block(model: mujoco.MjModel, name: str) -> np.ndarray | None:
    """The data of the model's custom numeric ``name``, or None where the model has none
    (the part that owns it is not in this model)."""
    try:
        return model.numeric(name).data
    except KeyError:
        return None
