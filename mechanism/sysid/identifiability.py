"""Is a recording identifiable? Judged by the information it carries on the baseline's
parameters, not by how far the shaft turns.

The baseline's drive equation is linear in its friction and inertia parameters (the
equation-error form used for the fit's starting point)::

    g U - c_emf w - G(theta) = J w' + d w + Fc sgn(w) + tau_0

so the recording's regressor -- the columns w', w, sgn(w) and 1 over the moving samples,
each in torque at the described value -- says what the recording can determine. A parameter
is *not determined* when its column is absent (the speed never changes: no acceleration for
the inertia) or when the other columns reproduce it (a shaft running at one speed: viscous
and Coulomb friction give the same torque). The measure is the column's independent
fraction, ``sqrt(1 - R^2)`` of its regression on the others (``1 / sqrt(VIF)``): a recording
is refused only when one falls below :data:`~mechanism.tolerances.MIN_INDEPENDENT_FRACTION`,
and the refusal names the parameter and says why in words. A pendulum swinging through a
few radians, a servo under a position loop and an axis moving back and forth all carry
plenty; the old rule (at least one revolution) refused them.

The Fisher information of the same regression (the residual's variance, inflated by its
correlation length) gives each parameter's relative 1-sigma for the JSON.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mechanism.dynamics.lumped import DriveNominal
from mechanism.sysid.recording import Recording, check_excitation, smoothed_velocity
from mechanism.tolerances import (
    BOTH_WAYS_FRACTION,
    MIN_INDEPENDENT_FRACTION,
    MIN_MOVING_SAMPLES,
    MOVING_SPEED_RAD_S,
)

WORDS = {
    "inertia": "the inertia",
    "viscous": "the viscous friction",
    "coulomb": "the Coulomb friction",
    "offset": "the constant offset torque",
}


def correlation_length(r: np.ndarray, max_lag: int = 2000) -> float:
    """Integral correlation length [samples] of a residual (>= 1)."""
    r = r - r.mean()
    n = len(r)
    if n < 8 or not np.any(r):
        return 1.0
    spec = np.fft.rfft(r, 2 * n)
    acf = np.fft.irfft(spec * np.conj(spec))[: min(max_lag, n)]
    acf = acf / acf[0]
    first_negative = np.flatnonzero(acf < 0)
    cut = first_negative[0] if first_negative.size else len(acf)
    return float(max(1.0, 1.0 + 2.0 * acf[1:cut].sum()))


@dataclass
class Identifiability:
    identifiable: bool
    reason: str
    independent_fraction: dict  # parameter -> sqrt(1 - R^2) of its column on the others
    relative_sd: dict  # parameter -> 1-sigma relative to its described value (Fisher information)
    turns_both_ways: bool

    def to_json(self) -> dict:
        # screening statistics: 4 digits say all they can, and the same on any BLAS or thread count
        def shown(values: dict) -> dict:
            return {name: float(f"{value:.4g}") for name, value in values.items()}

        return {
            "identifiable": self.identifiable,
            "reason": self.reason,
            "independent_fraction": shown(self.independent_fraction),
            "relative_uncertainty_1sigma_fraction": shown(self.relative_sd),
            "rule": (
                f"a baseline parameter is determined when at least {MIN_INDEPENDENT_FRACTION:.0%} of its "
                f"regressor column (w', w, sgn w, 1 over the moving samples) is independent of the others"
            ),
        }


def turns_both_ways(velocity: np.ndarray) -> bool:
    """The shaft moves each way for at least :data:`BOTH_WAYS_FRACTION` of its moving samples."""
    moving = velocity[np.abs(velocity) > MOVING_SPEED_RAD_S]
    if len(moving) < MIN_MOVING_SAMPLES:
        return False
    forward = float(np.mean(moving > 0))
    return min(forward, 1.0 - forward) >= BOTH_WAYS_FRACTION


def check_information(
    rec: Recording, nominal: DriveNominal, gravity_Nm: np.ndarray | None = None
) -> Identifiability:
    """Whether ``rec`` determines the baseline's inertia, viscous and Coulomb friction (and a
    constant offset torque when the shaft turns both ways); see the module docstring."""
    excitation = check_excitation(rec)
    w = rec.velocity_rad_s
    both = turns_both_ways(w)
    if not excitation.identifiable:
        return Identifiability(False, excitation.reason, {}, {}, both)
    moving = np.abs(w) > MOVING_SPEED_RAD_S
    if moving.sum() < MIN_MOVING_SAMPLES:
        seconds = float(moving.sum() * rec.dt)
        return Identifiability(
            False,
            f"the shaft moves (faster than {MOVING_SPEED_RAD_S:g} rad/s) for only {seconds:.2g} s "
            f"of the recording: too little motion to determine its inertia and friction",
            {},
            {},
            both,
        )
    acc = smoothed_velocity(w, rec.dt)
    n = nominal.ratio
    scales = {
        "inertia": nominal.inertia_kgm2,
        "viscous": nominal.viscous_motor_side * n * n,
        "coulomb": nominal.torque_scale_Nm,
    }
    columns = {"inertia": acc, "viscous": w, "coulomb": np.sign(w)}
    if both:
        scales["offset"] = nominal.torque_scale_Nm
        columns["offset"] = np.ones(len(w))
    names = list(columns)
    X = np.column_stack([columns[k][moving] * scales[k] for k in names])
    norms = np.sqrt(np.sum(X * X, axis=0))
    fractions = {}
    for k, name in enumerate(names):
        if not norms[k] > 0:
            fractions[name] = 0.0
            continue
        others = np.delete(X, k, axis=1)
        coef, *_ = np.linalg.lstsq(others, X[:, k], rcond=None)
        fractions[name] = float(np.linalg.norm(X[:, k] - others @ coef) / norms[k])
    # Fisher information of the equation-error regression: each parameter's relative 1-sigma
    motor = nominal.motor
    y = motor.gain_arm * rec.voltage_V - motor.emf_damping_arm * w
    if gravity_Nm is not None:
        y = y - gravity_Nm
    relative_sd = {}
    if np.all(norms > 0):
        coef, *_ = np.linalg.lstsq(X, y[moving], rcond=None)
        r = y[moving] - X @ coef

        s2 = float(r @ r) / max(len(r) - len(names), 1) * correlation_length(r)
        with np.errstate(all="ignore"):
            cov = s2 * np.linalg.pinv(X.T @ X)
        relative_sd = {name: float(math.sqrt(max(cov[k, k], 0.0))) for k, name in enumerate(names)}
    weakest = min(fractions, key=fractions.__getitem__)
    if fractions[weakest] < MIN_INDEPENDENT_FRACTION:
        return Identifiability(
            False,
            _why(weakest, names, X, norms, w[moving], acc[moving], fractions[weakest]),
            fractions,
            relative_sd,
            both,
        )
    return Identifiability(True, excitation.reason, fractions, relative_sd, both)


def _why(
    name: str,
    names: list[str],
    X: np.ndarray,
    norms: np.ndarray,
    w: np.ndarray,
    acc: np.ndarray,
    fraction: float,
) -> str:
    k = names.index(name)
    if not norms[k] > 0:
        return f"{WORDS[name]} is not determined: the recording never excites it"
    cosine = {
        other: abs(float(X[:, k] @ X[:, j]) / (norms[k] * norms[j]))
        for j, other in enumerate(names)
        if j != k and norms[j] > 0
    }
    partner = max(cosine, key=cosine.__getitem__)
    pair = {name, partner}
    speed = float(np.median(np.abs(w)))
    spread = float(np.std(np.abs(w)))
    share = f"only {100 * fraction:.2g} % of its signature in the recording is independent of the other parameters'"
    if name == "inertia":
        return (
            f"the inertia is not determined: the speed hardly changes (acceleration {float(np.sqrt(np.mean(acc * acc))):.2g} "
            f"rad/s^2 rms at {speed:.3g} rad/s), so {share}"
        )
    if pair == {"viscous", "coulomb"} or pair == {"viscous", "offset"}:
        return (
            f"viscous and Coulomb friction cannot be told apart: the shaft runs at nearly one speed "
            f"({speed:.3g} rad/s, spread {spread:.2g} rad/s), where a speed-proportional and a constant friction "
            f"torque are the same; vary the speed (several voltage levels)"
        )
    return f"{WORDS[name]} cannot be told from {WORDS[partner]}: {share}"
