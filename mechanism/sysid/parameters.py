"""Typed model parameters: name, unit, meaning, nominal value and bounds.

A :class:`Parameter` knows how it is presented to the optimiser: strictly positive
quantities spanning decades (inertia, a Stribeck velocity, a resonance frequency) are
fitted in log space, signed amplitudes linearly, both scaled by ``scale`` so that every
optimiser variable is of order one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np


@dataclass(frozen=True)
class Parameter:
    name: str  # JSON key, with its unit: "coulomb_arm_Nm"
    nominal: float
    lower: float
    upper: float
    meaning: str = ""
    scale: float = 0.0  # typical magnitude; 0 = from the bounds
    log: bool = False  # fit log(value) (needs lower > 0)
    # A prior (what the model already knows, with its stated tolerance): 1-sigma of the value
    # around ``nominal`` (of log(value) for a log parameter); 0 = none. The fit is regularised
    # towards the nominal (mechanism.sysid.identification.fit).
    prior_sd: float = 0.0

    def __post_init__(self):
        if not self.lower <= self.nominal <= self.upper:
            raise ValueError(
                f"{self.name}: nominal {self.nominal} outside [{self.lower}, {self.upper}]"
            )
        if self.log and self.lower <= 0:
            raise ValueError(f"{self.name}: a log-scaled parameter needs a positive lower bound")

    @property
    def typical(self) -> float:
        if self.scale:
            return self.scale
        if self.log:
            return self.nominal
        span = max(abs(self.lower), abs(self.upper))
        return span if math.isfinite(span) and span > 0 else 1.0

    def to_internal(self, value: float) -> float:
        value = min(max(value, self.lower), self.upper)
        return math.log(value / self.typical) if self.log else value / self.typical

    def from_internal(self, x: float) -> float:
        return self.typical * math.exp(x) if self.log else x * self.typical

    def internal_bounds(self) -> tuple[float, float]:
        if self.log:
            return math.log(self.lower / self.typical), math.log(self.upper / self.typical)
        return self.lower / self.typical, self.upper / self.typical


def internal_vector(params: Sequence[Parameter], values: dict[str, float]) -> np.ndarray:
    return np.array([p.to_internal(values.get(p.name, p.nominal)) for p in params], dtype=float)


def internal_bounds(params: Sequence[Parameter]) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = zip(*(p.internal_bounds() for p in params)) if params else ((), ())
    return np.array(lo, dtype=float), np.array(hi, dtype=float)


def values_from_internal(params: Sequence[Parameter], x: np.ndarray) -> dict[str, float]:
    return {p.name: p.from_internal(float(v)) for p, v in zip(params, x)}


def prior_weights(params: Sequence[Parameter]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices, internal nominal values and internal 1-sigmas of the parameters with a prior."""
    index = [i for i, p in enumerate(params) if p.prior_sd > 0]
    centre = np.array([params[i].to_internal(params[i].nominal) for i in index], dtype=float)
    sd = np.array(
        [
            params[i].prior_sd if params[i].log else params[i].prior_sd / params[i].typical
            for i in index
        ],
        dtype=float,
    )
    return np.array(index, dtype=int), centre, sd


def internal_derivative(params: Sequence[Parameter], x: np.ndarray) -> np.ndarray:
    """d(value)/d(internal) for each parameter, to carry uncertainties back to values."""
    return np.array(
        [p.typical * math.exp(v) if p.log else p.typical for p, v in zip(params, x)], dtype=float
    )
