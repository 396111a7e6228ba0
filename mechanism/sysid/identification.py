"""Identification: fit a model (a baseline plus candidate effects) to a recording by
simulation-error minimisation.

Pipeline: a :class:`~mechanism.sysid.recording.Recording` becomes a :class:`Problem` (the
measured signals, the multiple-shooting :class:`~mechanism.dynamics.lumped.Segments` split into fit
and validation parts, the measured velocity on each); a :class:`ModelStructure` (baseline
+ effects) maps a parameter vector to a :class:`~mechanism.dynamics.lumped.Drive`; the kernel
simulates every segment from the measured velocity at its start; the residual is the
measured minus the simulated arm velocity, both by the same Savitzky-Golay differentiator
of an angle (see :mod:`mechanism.sysid.recording`); ``scipy.optimize.least_squares`` minimises
it on the fit segments; the validation segments (interleaved with the fit ones) give the
rmse that every comparison uses.

Uncertainties: the covariance s^2 (J^T J)^-1 from the Jacobian at the optimum, inflated by
the residual's correlation length (neighbouring samples of a smoothed, model-error-dominated
residual are not independent; without the inflation the intervals would be far too narrow).

Why not ``mujoco.sysid``: it fits MuJoCo models through rollouts of an ``MjModel``; the
lumped drive is a 1-2 state ODE with stick-slip, not an ``MjModel``, integrated by a small C
loop at ~30 ns per sample, and ``mujoco.sysid`` needs the optional ``mujoco[sysid]`` extras
(absl, colorama, tabulate) that are not installed. We follow its structure instead: typed
parameters (:mod:`mechanism.sysid.parameters`), a residual, an optimiser, confidence intervals from
the Jacobian, a report kept apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from mechanism.sysid.identifiability import Identifiability, correlation_length
from mechanism.sysid.effects import Effect
from mechanism.errors import UserError
from mechanism.dynamics.lumped import (
    REST_SPEED_RAD_S,
    Drive,
    DriveNominal,
    MotorConstants,
    Segments,
    Signals,
    angle_from_velocity,
    lagged_voltage,
    make_segments,
    simulate,
    windowed_dot,
)
from mechanism.sysid.lumped_baseline import LumpedBaseline
from mechanism.sysid.parameters import (
    Parameter,
    internal_bounds,
    internal_derivative,
    internal_vector,
    prior_weights,
    values_from_internal,
)
from mechanism.sysid.recording import (
    Recording,
    at_fitting_rate,
    smoothed_velocity,
    velocity_coefficients,
)

# a simulated speed beyond this has diverged (its square would overflow the residual)
DIVERGED_RAD_S = 1e6
DIFF_STEP = 1e-3  # finite-difference step in the scaled parameters: the stick-slip makes the
#                   residual piecewise smooth, so derivatives need steps well above round-off


class ModelStructure:
    """A baseline plus an ordered tuple of effects: the parameter list and the drive."""

    def __init__(self, baseline, effects: Sequence[Effect] = ()):
        self.baseline = baseline
        self.effects = tuple(effects)
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate parameter names in {self}")

    @property
    def parameters(self) -> list[Parameter]:
        return [*self.baseline.parameters, *(p for e in self.effects for p in e.parameters)]

    @property
    def names(self) -> list[str]:
        return [e.name for e in self.effects]

    def admits(self, effect: Effect) -> bool:
        """Whether ``effect`` can join: not in the model yet, and no effect of its slot (a free
        play and an elastic belt are both the one transmission) is."""
        return effect.name not in self.names and not (
            effect.slot is not None and any(e.slot == effect.slot for e in self.effects)
        )

    def with_effect(self, effect: Effect) -> "ModelStructure":
        return ModelStructure(self.baseline, (*self.effects, effect))

    def drive(self, values: dict[str, float], signals: Signals) -> Drive:
        drive = self.baseline.drive(values, signals)
        applied = drive.voltage_V = self.voltage(values, signals)
        # the voltage itself is set above; the voltage effects' apply runs after the friction's
        # (a warming winding's change of the back-emf damping is no friction, which a bearing drift
        # scales: before, the drift scaled it, and the true pair ended at 6.6x the noise, now 1.6x),
        # the belt last (it reads the total inertia)
        for e in sorted(self.effects, key=lambda e: {"voltage": 2, "belt": 3}.get(e.enters, 1)):
            e.apply(values, signals, drive)
            if drive.voltage_V is not applied:  # the winding lag below would drop the change
                raise TypeError(
                    f"effect {e.name} changes the voltage in apply(); give it a voltage() method"
                )
        self.baseline.finish(values, signals, drive, lambda tau: self.lagged(values, signals, tau))
        return drive

    def _changing_voltage(self, values: dict[str, float]) -> tuple[list[Effect], tuple]:
        """The voltage effects, and what of them the applied voltage depends on (a memo key)."""
        changing = [e for e in self.effects if e.enters == "voltage"]
        return changing, tuple((e.name, *(values[p.name] for p in e.parameters)) for e in changing)

    def voltage(self, values: dict[str, float], signals: Signals) -> np.ndarray:
        """The voltage reaching the winding at the samples of ``signals``: the logged one as the
        voltage effects change it (before the winding's lag). Computed on the whole recording,
        once per value of what changes it (the lag below needs it there), and read at these
        samples."""
        changing, key = self._changing_voltage(values)
        if not changing:
            return signals.voltage_V

        def applied(whole: Signals) -> np.ndarray:
            u = whole.voltage_V
            for e in changing:
                u = e.voltage(values, whole, u)
            return u

        return signals.history("applied_voltage", key, applied)

    def lagged(self, values: dict[str, float], signals: Signals, tau_s: float) -> np.ndarray:
        """:meth:`voltage` behind the winding lag ``tau_s``. The lag filters over the samples
        before, so it runs on the whole recording and is read at these samples: a part's
        windows alone then give the drive exactly."""
        changing, key = self._changing_voltage(values)
        if not changing:
            return signals.lagged(tau_s)
        return signals.lag_filtered(
            "lagged_applied_voltage",
            (tau_s, key),
            tau_s,
            lambda whole: self.voltage(values, whole),
            lambda u: lagged_voltage(u, tau_s, signals.dt),
        )

    @property
    def per_sample(self) -> bool:
        """Whether the drive at a sample depends only on the signals at that sample (and on the
        past through :meth:`~mechanism.dynamics.lumped.Signals.history`, as the winding lag of a
        changed voltage does), so that a part's windows alone give it exactly. Not with a belt
        where the inertia varies: the belt is sized by the median inertia over the samples."""
        varies = self.baseline.varies_inertia or any(e.varies_inertia for e in self.effects)
        return not varies or all(e.enters != "belt" for e in self.effects)

    def delay_s(self, values: dict[str, float]) -> float:
        """How late the modelled sensor logs the angle (0 without a sensor delay)."""
        return sum(values[e.delay_parameter] for e in self.effects if e.delay_parameter)

    def true_signals(self, values: dict[str, float], signals: Signals) -> Signals:
        """The signals the machine itself saw: the logged ones, advanced by the sensor's delay."""
        return signals.advanced(self.delay_s(values))

    def measured_angle(
        self, values: dict[str, float], signals: Signals, angle: np.ndarray
    ) -> np.ndarray:
        for e in self.effects:
            if e.is_measurement:
                angle = e.measure(values, signals, angle)
        return angle

    def __repr__(self) -> str:
        return "+".join([self.baseline.name, *self.names])


class Problem:
    """A recording prepared for fitting: signals, segments, the measured velocity.

    Parts: ``fit`` and ``val`` (interleaved segments), ``all``, and ``screen`` (every second to
    fourth fit segment, at least ``MIN_SCREEN_SEGMENTS`` of them, for the cheap first look at each
    candidate). Fitting uses every
    ``FIT_STRIDE``-th scored sample: the smoothed velocity has no content above ~60 Hz,
    so 333 samples/s carry all of it, and the optimiser's linear algebra is 3x smaller.
    Every reported rmse uses every sample.
    """

    FIT_STRIDE = 3
    # a long recording is scored on this many segments spread over it (6 min of 1 s)
    MAX_SEGMENTS = 360

    def __init__(
        self, rec: Recording, nominal: DriveNominal, segment_s: float = 1.0, burn_in_s: float = 0.25
    ):
        self.recording = rec
        self.nominal = nominal
        self.dt = rec.dt
        self.coefficients = velocity_coefficients(rec.dt)
        self.pad = (len(self.coefficients) - 1) // 2
        whole = Signals(
            rec.time_s,
            rec.voltage_V,
            rec.arm_angle_rad,
            rec.velocity_rad_s,
            rec.dt,
            ratio=nominal.ratio,
        )
        every = make_segments(len(rec), rec.dt, segment_s, burn_in_s, self.pad)
        self.segments = _spread(every, self.MAX_SEGMENTS)
        self.signals, simulated = whole, self.segments
        if len(self.segments) * self.segments.length < len(rec):
            # a long recording: the model runs on its scored windows laid end to end (per-sample
            # work then no longer grows with the length; history effects read the whole one)
            index = self.segments.window_indices().ravel()
            self.signals = Signals(
                rec.time_s[index],
                rec.voltage_V[index],
                rec.arm_angle_rad[index],
                rec.velocity_rad_s[index],
                rec.dt,
                ratio=nominal.ratio,
                source_index=index,
                whole=whole,
            )
            s = self.segments
            simulated = Segments(
                np.arange(len(s), dtype=np.int64) * s.length,
                s.length,
                s.score_begin,
                s.score_end,
                s.is_fit,
            )
        original = _parts(self.segments)
        self.parts = _parts(simulated)
        self.strides = {"fit": self.FIT_STRIDE, "screen": self.FIT_STRIDE, "val": 1, "all": 1}
        self._window_first: dict[str, np.ndarray] = {}
        self.measured, self.scored = {}, {}
        for name, seg in self.parts.items():
            window_rows, window_offsets = [], []
            for i, (b, e) in enumerate(zip(seg.score_begin, seg.score_end)):
                offsets = np.arange(b, e, self.strides[name])
                window_rows.append(np.full(len(offsets), i))
                window_offsets.append(offsets)
            rows, cols = np.concatenate(window_rows), np.concatenate(window_offsets)
            # where the differentiator's support of every scored sample starts, as a flat index
            # into the part's windows
            self._window_first[name] = rows * seg.length + cols - self.pad
            self.scored[name] = original[name].starts[rows] + cols
            self.measured[name] = rec.velocity_rad_s[self.scored[name]]
        # each part runs on its own windows laid end to end (the screening part on an eighth to a
        # quarter of the samples): the model's per-sample work shrinks with the part (same values)
        self._runs = {}
        for name, seg in self.parts.items():
            if len(seg) * seg.length < len(self.signals):
                ends = np.arange(len(seg), dtype=np.int64) * seg.length
                self._runs[name] = (
                    self.signals.subset(seg.window_indices().ravel()),
                    Segments(ends, seg.length, seg.score_begin, seg.score_end, seg.is_fit),
                )

    def simulate(
        self, structure: ModelStructure, values: dict[str, float], part: str = "fit"
    ) -> np.ndarray:
        """Simulated arm velocity (by the tool's velocity definition) at the part's scored samples."""
        signals, seg = (structure.per_sample and self._runs.get(part)) or (
            self.signals,
            self.parts[part],
        )
        # a delayed sensor: the machine's state and torques are those the log shows later
        machine = structure.true_signals(values, signals)
        drive = structure.drive(values, machine)
        motor = structure.baseline.motor(values)
        w0 = machine.velocity_rad_s[seg.starts]
        w0 = np.where(np.abs(w0) < REST_SPEED_RAD_S, 0.0, w0)
        w = simulate(drive, motor, seg, w0, self.dt)
        if not np.all(np.isfinite(w)) or np.max(np.abs(w), initial=0.0) > DIVERGED_RAD_S:
            return np.full(len(self.measured[part]), 1e3)
        # integrate to an angle from the measured start angle (trapezoids), pass it through the
        # sensor model, and differentiate it like the measurement (the same Savitzky-Golay
        # weights, evaluated only where they are needed)
        angle = angle_from_velocity(w, self.dt, machine.arm_angle_rad[seg.starts])
        angle = structure.measured_angle(values, signals, angle)
        return windowed_dot(angle, self._window_first[part], self.coefficients)

    def residual(
        self, structure: ModelStructure, values: dict[str, float], part: str = "fit"
    ) -> np.ndarray:
        return self.measured[part] - self.simulate(structure, values, part)

    def rmse(self, structure: ModelStructure, values: dict[str, float], part: str = "val") -> float:
        r = self.residual(structure, values, part)
        return float(np.sqrt(np.mean(r * r)))

    def full_prediction(self, structure: ModelStructure, values: dict[str, float]) -> np.ndarray:
        """Simulated velocity over the whole recording (NaN at the few unscored samples at its ends)."""
        out = np.full(len(self.recording), np.nan)
        out[self.scored["all"]] = self.simulate(structure, values, "all")
        return out


# the screening part: every k-th fit segment, k the sparsest of 2..4 that keeps this many. On 60 s
# bench recordings (30 fit segments, so 8 of them in place of 15) 35 diagnoses named the same or
# fewer effects in 0.77x the time; at 30 s with 4 of 15, two mixes with a delay lost three names
MIN_SCREEN_SEGMENTS = 8


def _screen_stride(n_fit: int) -> int:
    return max(k for k in (2, 3, 4) if k == 2 or -(-n_fit // k) >= MIN_SCREEN_SEGMENTS)


def _parts(segments: Segments) -> dict[str, Segments]:
    fit_part = segments.subset(segments.is_fit)
    screen = np.zeros(len(fit_part), bool)
    screen[:: _screen_stride(len(fit_part))] = True
    return {
        "fit": fit_part,
        "val": segments.subset(~segments.is_fit),
        "all": segments,
        "screen": fit_part.subset(screen) if len(fit_part) > 3 else fit_part,
    }


def _spread(segments: Segments, most: int) -> Segments:
    """At most ``most`` segments, in whole fit/validation groups of four spread evenly over
    the recording: beyond some minutes more segments add time, not information, and the
    time a fit takes stops growing with the recording's length."""
    if len(segments) <= most:
        return segments
    groups = len(segments) // 4
    chosen = np.unique(np.linspace(0, groups - 1, most // 4).round().astype(int))
    keep = np.zeros(len(segments), bool)
    for g in chosen:
        keep[4 * g : 4 * g + 4] = True
    return segments.subset(keep)


@dataclass
class FitResult:
    structure: ModelStructure
    values: dict[str, float]
    uncertainties: dict[str, float]
    rmse_fit: float
    rmse_val: float
    n_evaluations: int = 0
    success: bool = True
    message: str = ""

    @property
    def effect_names(self) -> list[str]:
        return self.structure.names


@dataclass
class Objective:
    """What a fit minimises at an internal parameter vector ``x``: the residual of ``part``, and
    the prior rows of the parameters that have one. A plain object (no closure), so that a
    worker process that holds the problem can evaluate it too (:mod:`mechanism.sysid.fit_runner`)."""

    structure: ModelStructure
    part: str
    fixed: dict[str, float]
    params: list[Parameter]
    prior_index: np.ndarray
    prior_centre: np.ndarray
    prior_sd: np.ndarray
    prior_weight: float = 0.0  # set from the residual at the first start (see fit)

    def values(self, x: np.ndarray) -> dict[str, float]:
        return {**self.fixed, **values_from_internal(self.params, x)}

    def data(self, problem: Problem, x: np.ndarray) -> np.ndarray:
        # a trial point may overflow (the fit then steps back); numpy's error state is per thread,
        # where the warnings filters are one list for the whole process (a caller may fit on threads)
        with np.errstate(all="ignore"):
            return problem.residual(self.structure, self.values(x), self.part)

    def __call__(self, problem: Problem, x: np.ndarray) -> np.ndarray:
        r = self.data(problem, x)
        if not self.prior_index.size:
            return r
        prior = self.prior_weight * (x[self.prior_index] - self.prior_centre) / self.prior_sd
        return np.concatenate([r, prior])


# evaluates an objective at several points, in order (a pool of processes that hold the problem)
ColumnMap = Callable[[Objective, list], list]


def fit(
    problem: Problem,
    structure: ModelStructure,
    starts: Sequence[dict[str, float]],
    free: Sequence[str] | None = None,
    max_nfev: int = 40,
    scout_nfev: int = 3,
    progress: Callable[[], None] | None = None,
    part: str = "fit",
    tolerance: float = 1e-5,
    columns: ColumnMap | None = None,
) -> FitResult:
    """Least-squares fit of the parameters of ``structure`` on the fit segments.

    ``starts`` are initial guesses (missing names take the nominal value). With several,
    each gets a few iterations (``scout_nfev``; 0: one evaluation) and only the best is refined. ``free``
    names the parameters to fit (default: all); the others stay at the first start's values.
    ``tolerance``: the relative change of the cost (and of the scaled parameters) at which
    the optimiser stops. ``columns``: where the finite-difference Jacobian's points are
    evaluated (default: here, one after another); the numbers are the same either way.
    """
    every = structure.parameters
    params = [p for p in every if free is None or p.name in free]
    fixed = {p.name: p.nominal for p in every}
    # only this structure's parameters: a start built from a larger model's values (an effect since
    # dropped) would otherwise carry that effect's numbers into the result, and into the report
    fixed.update({k: v for k, v in (starts[0] if starts else {}).items() if k in fixed})
    lo, hi = internal_bounds(params)
    n_eval = 0
    objective = Objective(structure, part, fixed, params, *prior_weights(params))

    def counted(points: int) -> None:
        nonlocal n_eval
        n_eval += points
        if progress is not None:
            for _ in range(points):
                progress()

    def fun(x):
        counted(1)
        return objective(problem, x)

    def jacobian_points(_fun, points):  # scipy's ``workers``: it passes its wrapper of fun
        points = list(points)
        counted(len(points))
        assert columns is not None
        return columns(objective, points)

    if objective.prior_index.size:
        # a prior row weighs as sigma sqrt(correlation length) of the data residual (MAP with
        # the residual's own scale, as the uncertainties below): the model's knowledge counts as
        # much as one independent stretch of data disagreeing by its stated tolerance
        x0 = np.clip(internal_vector(params, starts[0] if starts else {}), lo, hi)
        counted(1)
        r0 = objective.data(problem, x0)
        objective.prior_weight = float(np.sqrt(np.mean(r0 * r0) * correlation_length(r0)))

    def run(x0, nfev):
        x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        # scipy >= 1.16 evaluates the Jacobian's points through ``workers``
        spread = {"workers": jacobian_points} if columns is not None else {}
        with np.errstate(all="ignore"):
            return least_squares(
                fun,
                x0,
                bounds=(lo, hi),
                x_scale="jac",
                diff_step=DIFF_STEP,
                method="trf",
                max_nfev=nfev,
                xtol=tolerance,
                ftol=tolerance,
                gtol=1e-8,
                **spread,
            )

    candidates = [internal_vector(params, s) for s in starts] or [internal_vector(params, {})]
    scouts = []
    if len(candidates) > 1 and scout_nfev <= 0:
        # the start with the lowest cost, one evaluation each
        x_start = min(candidates, key=lambda x0: float(np.sum(fun(np.clip(x0, lo, hi)) ** 2)))
    elif len(candidates) > 1:
        scouts = [run(x0, scout_nfev) for x0 in candidates]
        x_start = min(scouts, key=lambda r: r.cost).x
    else:
        x_start = candidates[0]
    # never worse than a start
    result = min([run(x_start, max_nfev), *scouts], key=lambda r: r.cost)
    values = objective.values(result.x)
    n_data = len(result.fun) - objective.prior_index.size
    r_fit = result.fun[:n_data] if part == "fit" else problem.residual(structure, values, "fit")
    rmse_fit = float(np.sqrt(np.mean(r_fit**2)))
    rmse_val = problem.rmse(structure, values, "val")
    unc = {p.name: math.nan for p in every}
    unc.update(_uncertainties(params, result, result.fun[:n_data]))
    return FitResult(
        structure,
        values,
        unc,
        rmse_fit,
        rmse_val,
        n_eval,
        bool(result.success),
        str(result.message),
    )


def _uncertainties(params: Sequence[Parameter], result, r: np.ndarray) -> dict[str, float]:
    jac = np.asarray(result.jac, dtype=float)
    n, p = len(r), jac.shape[1]
    if n <= p:
        return {q.name: math.inf for q in params}
    s2 = float(r @ r) / (n - p) * correlation_length(r)
    # prior rows (after the data's) are weighted by the data residual's own scale, so the whole
    # Jacobian gives the posterior covariance
    with np.errstate(all="ignore"):
        cov = s2 * np.linalg.pinv(jac.T @ jac)
    sd_internal = np.sqrt(np.clip(np.diag(cov), 0, None))
    sd = sd_internal * internal_derivative(params, result.x)
    # a parameter resting on a bound is not determined by the data there
    lo, hi = internal_bounds(params)
    at_bound = (result.x - lo < 1e-6 * (hi - lo)) | (hi - result.x < 1e-6 * (hi - lo))
    return {q.name: (math.nan if b else float(s)) for q, s, b in zip(params, sd, at_bound)}


def torque_balance(
    drive: Drive, motor: MotorConstants, w: np.ndarray, acc: np.ndarray
) -> np.ndarray:
    """The torque a model leaves unexplained at a measured velocity and acceleration
    (inverse dynamics of the rigid drive equation): drive minus losses minus J w'."""
    friction = drive.coulomb_Nm
    if np.any(drive.static_excess_Nm):
        friction = friction + drive.static_excess_Nm * np.exp(
            -np.power(np.abs(w) / drive.stribeck_velocity_rad_s, drive.stribeck_exponent)
        )
    return (
        motor.gain_arm * drive.voltage_V
        - (motor.emf_damping_arm + drive.viscous_Nm_s) * w
        - drive.tau_motor_Nm
        - drive.tau_arm_Nm
        - drive.quadratic_Nm_s2 * w * w
        - friction * np.sign(w)
        - drive.inertia_kgm2 * acc
    )


# the equation-error regression's rows: the moving samples, evenly thinned to at most this many.
# It gives a start for a few amplitudes: its cost grows with the rows, its noise falls only as
# their square root (a 60 s recording at 1 kHz kept 30 000 rows: a fifth of a diagnosis's time)
EQUATION_ERROR_ROWS = 8000


def equation_error_rows(velocity_rad_s: np.ndarray) -> np.ndarray:
    """The samples the equation-error regression reads: every other moving one (over 1 rad/s),
    thinned evenly to at most :data:`EQUATION_ERROR_ROWS`."""
    moving = np.flatnonzero(np.abs(velocity_rad_s) > 1.0)
    return moving[:: max(2, -(-len(moving) // EQUATION_ERROR_ROWS))]


def equation_error_start(
    problem: Problem,
    structure: ModelStructure,
    values: dict[str, float],
    effect: Effect,
    grid: Sequence[dict[str, float]],
) -> tuple[dict[str, float], float]:
    """A starting point for ``effect`` (the last one in ``structure``) from inverse dynamics.

    For each point of ``grid`` (the effect's non-linear parameters) the missing torque at
    the measured velocity and acceleration is regressed, by bounded linear least squares,
    on the effect's amplitude parameters and the baseline's linear ones (the baseline gives
    back what it had absorbed). No simulation: a few milliseconds per grid point. Returns
    the best values and their torque rms.
    """
    from scipy.optimize import lsq_linear

    amplitudes = effect.linear
    if amplitudes is None:
        raise ValueError(
            f"effect {effect.name} has no torque form (linear is None): it has no equation-error start"
        )
    s = structure.true_signals(values, problem.signals)
    if "eq_error" not in s._cache:
        w = s.velocity_rad_s
        acc = smoothed_velocity(w, s.dt)
        moving = equation_error_rows(w)
        s._cache["eq_error"] = (w[moving], acc[moving], moving, s.subset(moving))
    w, acc, sel, at_sel = s._cache["eq_error"]
    if len(sel) < 100:
        return dict(values), math.inf
    motor = structure.baseline.motor(values)
    by_name = {p.name: p for p in structure.parameters}

    if structure.per_sample:  # the drive at the chosen samples alone (the same values)

        def missing(v):
            return torque_balance(structure.drive(v, at_sel), motor, w, acc)
    else:
        acc_full = s._cache.setdefault("acc_full", smoothed_velocity(s.velocity_rad_s, s.dt))

        def missing(v):
            return torque_balance(structure.drive(v, s), motor, s.velocity_rad_s, acc_full)[sel]

    def column(v0, b0, name):
        step = by_name[name].typical
        return (b0 - missing({**v0, name: v0[name] + step})) / step  # torque explained per unit

    # the baseline's columns do not depend on the effect's shape: compute them once
    baseline_names = list(getattr(structure.baseline, "linear", ()))
    v_ref = {**values, **{n: 0.0 for n in amplitudes}}
    b_ref = missing(v_ref)
    baseline_columns = [column(v_ref, b_ref, n) for n in baseline_names]
    names = [*amplitudes, *baseline_names]
    best, best_cost = dict(values), math.inf
    for shape in grid:
        v0 = {**v_ref, **shape}
        b0 = missing(v0) if shape else b_ref
        A = np.column_stack([column(v0, b0, n) for n in amplitudes] + baseline_columns)
        lo = np.array([by_name[n].lower - v0[n] for n in names])
        hi = np.array([by_name[n].upper - v0[n] for n in names])
        scale = np.maximum(np.abs(A).max(axis=0), 1e-30)
        scaled = A / scale
        sol = lsq_linear(*_on_few_rows(scaled, b0), bounds=(lo * scale, hi * scale), method="bvls")
        cost = float(np.sqrt(np.mean((b0 - scaled @ sol.x) ** 2)))
        if cost < best_cost:
            best_cost = cost
            best = {**v0, **{n: v0[n] + x / sc for n, x, sc in zip(names, sol.x, scale)}}
    return best, best_cost


def _on_few_rows(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """min |A x - b| (with any bounds) as the same problem on as many rows as unknowns:
    |A x - b|^2 = |R x - d|^2 + |b|^2 - |d|^2 with R^T R = A^T A and R^T d = A^T b. Each of the
    solver's steps then costs microseconds, where on tens of thousands of rows they cost more than
    building the columns. ``A, b`` themselves where the columns are (nearly) dependent: A^T A squares
    the condition number, so its factor is used only where the smallest pivot stays above
    1e-6 of the largest."""
    from scipy.linalg import solve_triangular

    try:
        lower = np.linalg.cholesky(A.T @ A)
    except np.linalg.LinAlgError:
        return A, b
    pivots = np.abs(np.diag(lower))
    if not pivots.min() > 1e-6 * pivots.max():
        return A, b
    return lower.T, solve_triangular(lower, A.T @ b, lower=True)


def baseline_model(
    nominal: DriveNominal,
    baseline: str = "lumped",
    free: Sequence[str] = (),
    model_path=None,
    recording: Recording | None = None,
):
    """The baseline model object by name: ``lumped`` or ``multibody`` (the reduced model of
    the machine of ``nominal``, or of the MJCF at ``model_path``), around the described drive.
    With ``recording``, the terms every machine of the kind may need are chosen from it (see
    :func:`baseline_terms`)."""
    free = tuple(free)
    unknown = [f for f in free if f not in ("R", "Kt", "Ke")]
    if unknown:
        raise UserError(
            f"--free: unknown motor constant(s) {', '.join(unknown)}; choose from R, Kt, Ke"
        )
    offset, gravity, notes = (
        baseline_terms(nominal, recording) if recording is not None else (False, False, ())
    )
    if baseline == "lumped":
        return LumpedBaseline(nominal, free, offset=offset, gravity=gravity, notes=notes)
    if baseline == "multibody":
        from mechanism.sysid.multibody_baseline import MultibodyBaseline

        return MultibodyBaseline(nominal, free, model_path, offset=offset, notes=notes)
    raise UserError(f"unknown baseline {baseline!r}; choose lumped or multibody")


def baseline_terms(nominal: DriveNominal, rec: Recording) -> tuple[bool, bool, tuple[str, ...]]:
    """Whether the baseline carries a constant offset torque and the model's gravity torque
    for this recording, and why in words.

    - offset: when the shaft turns both ways (one way only, a constant torque is the Coulomb level);
    - gravity: when the machine's model has a gravity torque whose rms over the recorded angles
      is at least :data:`~mechanism.tolerances.GRAVITY_SIGNIFICANT` of the rms drive torque."""
    from mechanism.sysid.identifiability import turns_both_ways
    from mechanism.tolerances import GRAVITY_SIGNIFICANT

    notes = []
    offset = turns_both_ways(rec.velocity_rad_s)
    notes.append(
        "a constant offset torque is fitted: the shaft turns both ways, so it is separable from Coulomb friction"
        if offset
        else "no constant offset torque: the shaft turns one way, where a constant torque is the Coulomb level"
    )
    gravity = False
    if nominal.linkage is not None:
        g = nominal.linkage.at("gravity_torque_Nm", rec.arm_angle_rad)
        drive = nominal.motor.gain_arm * rec.voltage_V
        ratio = float(np.sqrt(np.mean(g * g)) / max(np.sqrt(np.mean(drive * drive)), 1e-12))
        gravity = ratio >= GRAVITY_SIGNIFICANT
        notes.append(
            f"the model's gravity torque G(theta) is carried (a prior, scale 1 within the CAD's tolerance): its rms "
            f"over the recorded angles is {100 * ratio:.3g} % of the rms drive torque"
            if gravity
            else f"the model's gravity torque is left out: its rms over the recorded angles is "
            f"{100 * ratio:.2g} % of the rms drive torque"
        )
    else:
        notes.append(
            "no gravity torque: the drive is described by its lumped numbers alone (no machine model)"
        )
    return offset, gravity, tuple(notes)


def fit_baseline(
    problem: Problem,
    baseline: str = "lumped",
    free: Sequence[str] = (),
    model_path=None,
    progress: Callable[[], None] | None = None,
) -> FitResult:
    """The baseline fitted from its equation-error start (and from the nominal values)."""
    model = baseline_model(problem.nominal, baseline, free, model_path, problem.recording)
    start = initial_baseline_values(problem, model)
    return fit(
        problem,
        ModelStructure(model),
        [start, {p.name: p.nominal for p in model.parameters}],
        progress=progress,
    )


def damping_below_datasheet(result: FitResult) -> bool:
    """The fitted viscous friction sits at zero: the recording has less speed-proportional
    damping than the datasheet's back-emf alone gives (Ke n^2 Kt / R), so the datasheet's
    back-emf constant is too large for this motor. (The thesis prints Kt 0.017 and Ke
    0.021; in SI units a DC motor has Kt = Ke, and speed data sees only Ke relative to
    Kt/R.)"""
    viscous = result.values.get("viscous_motor_side_Nm_s_per_rad")
    return (
        viscous is not None and "motor_back_emf_V_s_per_rad" not in result.values and viscous < 1e-7
    )


def initial_baseline_values(problem: Problem, baseline) -> dict[str, float]:
    """Equation-error start for the baseline: regress the drive equation on the measured
    velocity and its derivative (moving samples only) for J, viscous and Coulomb friction.
    Cheap, linear, and within a few percent of the simulation-error optimum, so the
    nonlinear fit starts in the right basin even when the machine differs from the thesis."""
    s = problem.signals
    values = {p.name: p.nominal for p in baseline.parameters}
    motor = baseline.motor(values)
    n = s.ratio
    w = s.velocity_rad_s
    acc = smoothed_velocity(w, s.dt)  # the same differentiator, applied to the velocity
    moving = np.abs(w) > 1.0
    if moving.sum() < 200:
        return values
    offset = "offset_torque_arm_Nm" in values
    if offset:
        values["offset_torque_arm_Nm"] = 0.0
    drive = baseline.drive(values, s)
    # the model's known torques (gravity at its nominal scale) stay on the measured side
    y = motor.gain_arm * drive.voltage_V - motor.emf_damping_arm * w - drive.tau_arm_Nm
    X = np.column_stack([acc, w, np.sign(w), *([np.ones(len(w))] if offset else [])])[moving]
    try:
        coef, *_ = np.linalg.lstsq(X, y[moving], rcond=None)
    except np.linalg.LinAlgError:
        return values
    j_arm, c_arm, fc = coef[:3]
    if offset:
        values["offset_torque_arm_Nm"] = float(coef[3])
    by_name = {q.name: q for q in baseline.parameters}
    ke = by_name.get("motor_back_emf_V_s_per_rad")
    if ke is not None and c_arm < 0:
        # less damping than the datasheet back-emf gives: the back-emf constant is smaller
        # start off the bound
        keep = 0.25 * by_name["viscous_motor_side_Nm_s_per_rad"].nominal * n * n
        k = ke.nominal + (c_arm - keep) * motor.resistance_ohm / (
            n * n * motor.torque_constant_Nm_per_A
        )
        values[ke.name] = float(min(max(k, ke.lower), ke.upper))
        c_arm = keep
    if (
        "inertia_correction_motor_side_kgm2" in by_name
    ):  # the multibody baseline: a correction to the model's mean
        j_arm = j_arm - baseline.tables.mean_inertia_kgm2
    for p, value in (
        ("inertia_motor_side_kgm2", j_arm / n**2),
        ("inertia_correction_motor_side_kgm2", j_arm / n**2),
        ("viscous_motor_side_Nm_s_per_rad", c_arm / n**2),
        ("coulomb_arm_Nm", fc),
    ):
        par = by_name.get(p)
        if par is not None and np.isfinite(value) and par.lower < value < par.upper:
            values[p] = float(value)
    return values


@dataclass
class IdentificationResult:
    """What ``identify`` found: the fitted baseline with uncertainties and rmse."""

    recording: Recording
    baseline: str
    fit: FitResult
    problem: Problem = field(repr=False)

    @property
    def params(self) -> dict[str, float]:
        return self.fit.values

    @property
    def traces(self):
        from mechanism.sysid.report import Traces

        rec = self.recording
        prediction = self.problem.full_prediction(self.fit.structure, self.fit.values)
        nominal = self.problem.nominal
        return Traces(
            rec.time_s,
            rec.arm_angle_rad,
            rec.voltage_V,
            rec.velocity_rad_s,
            {self.baseline: prediction},
            ratio=nominal.ratio,
            zero_meaning=nominal.zero_meaning,
        )

    @property
    def rmse(self) -> float:
        return self.fit.rmse_val

    def to_json(self) -> dict:
        return {
            "recording": self.recording.source,
            "baseline": self.baseline,
            "baseline_terms": self.fit.structure.baseline.terms,
            "params": self.fit.values,
            "uncertainty_1sigma": self.fit.uncertainties,
            "rmse": self.fit.rmse_val,
            "rmse_fit": self.fit.rmse_fit,
            "rmse_definition": "RMS of measured minus simulated arm velocity [rad/s] on the validation segments; both by the same Savitzky-Golay differentiator (21 ms, degree 4) of an angle; each 1 s segment restarts from the measured velocity after a 0.25 s burn-in",
            "split": {
                "segments_fit": int(self.problem.parts["fit"].starts.size),
                "segments_validation": int(self.problem.parts["val"].starts.size),
            },
            "reading": self.recording.reading,
        }


def blas_single_threaded():
    """BLAS limited to one thread: the fits use small matrices (10^4 x 10) where OpenBLAS's
    threads cost far more than they save (an SVD: 2 ms single-threaded, 45 ms with two
    threads on a busy two-core machine), and the diagnosis runs its own fits in parallel."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, "blas")


def require_identifiable(rec: Recording, nominal: DriveNominal) -> Identifiability:
    """The recording's information on the baseline's parameters (refused, naming the
    parameter and why, when one is not determined; :mod:`mechanism.sysid.identifiability`)."""
    from mechanism.sysid.identifiability import check_information

    info = check_information(rec, nominal)
    if not info.identifiable:
        raise NotIdentifiable(info.reason)
    return info


class NotIdentifiable(UserError):
    """The recording does not excite the machine enough to identify anything."""


def identify(
    recording: Recording,
    baseline: str = "lumped",
    free: Sequence[str] = (),
    progress: Callable[[], None] | None = None,
    model_path=None,
    *,
    nominal: DriveNominal,
) -> IdentificationResult:
    """Fit the baseline (inertia, viscous and Coulomb friction; the motor constants named in
    ``free``) by simulation-error minimisation; rmse on the validation segments. ``nominal``:
    the described drive (starting values and bounds scale from it)."""
    recording = at_fitting_rate(recording)
    require_identifiable(recording, nominal)
    with blas_single_threaded():
        problem = Problem(recording, nominal)
        result = fit_baseline(problem, baseline, free, model_path, progress)
    return IdentificationResult(recording, baseline, result, problem)
