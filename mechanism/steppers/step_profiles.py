"""Step sequences for the stepper models: what the driver is told to do over time.

A profile is a piecewise-linear step *rate* (full steps per second, negative = reverse;
rate jumps are allowed); the commanded shaft position is its exact integral, in full
steps (7.5 degrees for the PM25S-048) from the start. The driver rounds that position to
its resolution (full, half or 1/N step, see :mod:`mechanism.steppers`).

Where profiles come from:

* built-ins: ``thread-cut`` (thesis 3.4.1: forward then back to the start at the step
  rate, from the machine description's ``[thread_cut]`` and ``[stepper]``) and
  ``thread-cut-ramped`` (the same stroke with a linear ramp down to rest before the
  reversal and back up after it);
* :func:`move` (a constant-rate or trapezoidal move) and :func:`from_rates`;
* CSV files, told apart by their header (``#`` comment lines are allowed):

  ``time_s,rate_steps_s``
      step rate at each time, linear in between (a ramp; equal rows = constant rate).
      The rate is 0 before the first row; the sequence ends at the last row.
  ``time_s,target_steps``
      at each time the driver heads for the target position (full steps from the start)
      at the slew rate (``--rate``), abandoning an unfinished move when the next row
      comes; the sequence ends when the last target is reached.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mechanism.errors import UserError, close_matches
from mechanism.steppers._motor import described_section, described_step_rate

BUILTINS = ("thread-cut", "thread-cut-ramped")
DEFAULT_RAMP_STEPS = 25


@dataclass(frozen=True)
class StepProfile:
    """Piecewise-linear step rate: ``rate(t)`` is linear between knots; equal knot times
    make a jump. The profile ends at the last knot (the rate is 0 outside the knots)."""

    name: str
    knot_time_s: np.ndarray
    knot_rate_steps_s: np.ndarray
    # full steps from the start at each knot, from the rates (set by __post_init__)
    _knot_position: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        t = np.asarray(self.knot_time_s, dtype=float)
        r = np.asarray(self.knot_rate_steps_s, dtype=float)
        if t.ndim != 1 or t.shape != r.shape or t.size < 2:
            raise ValueError("a profile needs at least two knots of time and rate")
        if np.any(np.diff(t) < 0) or t[0] < 0:
            raise ValueError("profile knot times must start at >= 0 and not decrease")
        object.__setattr__(self, "knot_time_s", t)
        object.__setattr__(self, "knot_rate_steps_s", r)
        # position at each knot: trapezoids of the piecewise-linear rate
        dt = np.diff(t)
        pos = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * dt)])
        object.__setattr__(self, "_knot_position", pos)

    @property
    def duration_s(self) -> float:
        return float(self.knot_time_s[-1])

    def _segment(self, t: np.ndarray):
        t = np.asarray(t, dtype=float)
        knots = self.knot_time_s
        i = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, knots.size - 2)
        t0, t1 = knots[i], knots[i + 1]
        r0, r1 = self.knot_rate_steps_s[i], self.knot_rate_steps_s[i + 1]
        slope = np.divide(r1 - r0, t1 - t0, out=np.zeros_like(r0), where=t1 > t0)
        tau = np.clip(t, knots[0], knots[-1]) - t0
        return i, tau, r0, slope

    def rate_steps_s(self, t) -> np.ndarray:
        """Commanded step rate [full steps/s] at times ``t`` (0 outside the profile)."""
        t = np.asarray(t, dtype=float)
        _, tau, r0, slope = self._segment(t)
        inside = (t >= self.knot_time_s[0]) & (t < self.knot_time_s[-1])
        return np.where(inside, r0 + slope * tau, 0.0)

    def position_steps(self, t) -> np.ndarray:
        """Commanded position [full steps from the start] at times ``t``, before rounding."""
        i, tau, r0, slope = self._segment(t)
        return self._knot_position[i] + r0 * tau + 0.5 * slope * tau**2

    def _motion_pieces(self) -> list[tuple[float, float, float]]:
        """(start, end, direction) of the stretches where the rate keeps one nonzero sign."""
        pieces = []
        t, r = self.knot_time_s, self.knot_rate_steps_s
        for k in range(t.size - 1):
            t0, t1, r0, r1 = t[k], t[k + 1], r[k], r[k + 1]
            if t1 == t0:
                continue
            if r0 * r1 < 0:
                crossing = t0 + (t1 - t0) * r0 / (r0 - r1)
                pieces += [(t0, crossing, np.sign(r0)), (crossing, t1, np.sign(r1))]
            elif r0 or r1:
                pieces.append((t0, t1, np.sign(r0 + r1)))
        return pieces

    def peak_steps(self) -> float:
        """Largest commanded position (it is reached where a forward stretch ends)."""
        ends = [end for _, end, direction in self._motion_pieces() if direction > 0]
        return float(max([0.0, *self.position_steps(np.array(ends))])) if ends else 0.0

    def reversal_times_s(self) -> list[float]:
        """Times where the commanded motion turns round (the end of the stretch before)."""
        pieces = self._motion_pieces()
        return [float(prev[1]) for prev, cur in zip(pieces, pieces[1:]) if cur[2] != prev[2]]


def _check_rate(rate: float, what: str = "step rate") -> float:
    rate = float(rate)
    if not np.isfinite(rate) or rate <= 0:
        raise UserError(f"{what} must be a positive number of full steps per second, got {rate:g}")
    return rate


def from_rates(name: str, times_s, rates_steps_s) -> StepProfile:
    return StepProfile(
        name, np.asarray(times_s, dtype=float), np.asarray(rates_steps_s, dtype=float)
    )


def move(
    steps: float, rate: float, ramp_steps: float = 0.0, start_s: float = 0.0, name: str = "move"
) -> StepProfile:
    """A move of ``steps`` full steps (sign = direction) at ``rate`` steps/s from rest at
    ``start_s``: abrupt start and stop (``ramp_steps=0``) or linear ramps of
    ``ramp_steps`` steps at both ends."""
    rate = _check_rate(rate)
    speed = (1.0 if steps >= 0 else -1.0) * rate
    distance = abs(float(steps))
    ramp = min(max(float(ramp_steps), 0.0), distance / 2)
    t_ramp, t_cruise = 2 * ramp / rate, (distance - 2 * ramp) / rate
    if ramp:
        times = [
            start_s,
            start_s + t_ramp,
            start_s + t_ramp + t_cruise,
            start_s + 2 * t_ramp + t_cruise,
        ]
        rates = [0.0, speed, speed, 0.0]
    else:
        times = [start_s, start_s + t_cruise, start_s + t_cruise]
        rates = [speed, speed, 0.0]
    if start_s > 0:  # at rest until the start
        times, rates = [0.0, start_s, *times], [0.0, 0.0, *rates]
    return from_rates(name, times, rates)


def thread_cut_timing(machine=None) -> tuple[float, float, float]:
    """(forward time [s], back time [s], step rate [steps/s]) of a described machine's thread
    cut (``[thread_cut]`` and ``[stepper] step_rate_steps_s``; default: the shipped machine,
    the thesis's 0.35 s + 0.35 s at 1000 steps/s)."""
    cut, where = described_section(machine, "thread_cut")
    if not cut:
        raise UserError(f"{where}: the machine description has no thread cut")
    return float(cut["forward_s"]), float(cut["back_s"]), described_step_rate(machine)


def thread_cut_stroke_steps(machine=None) -> int:
    """The cutter stroke: the thesis runs forward for its forward time at its step rate."""
    forward_s, _, rate = thread_cut_timing(machine)
    return int(round(forward_s * rate))


def thread_cut(rate: float | None = None, ramp_steps: float = 0.0, machine=None) -> StepProfile:
    """The thesis's thread-cut stroke out and straight back at ``rate`` (default: the
    thesis's 1000 steps/s). With ``ramp_steps`` > 0 the motor ramps linearly down to rest
    over that many steps before the reversal and back up over as many after it; start
    and end stay abrupt as in the thesis, so only the reversal differs."""
    rate = _check_rate(rate if rate is not None else described_step_rate(machine))
    stroke = thread_cut_stroke_steps(machine)
    n = min(float(ramp_steps), stroke / 2)
    if n <= 0:
        t1 = stroke / rate
        return from_rates("thread-cut", [0, t1, t1, 2 * t1, 2 * t1], [rate, rate, -rate, -rate, 0])
    t1 = (stroke - n) / rate
    t2 = t1 + 2 * n / rate
    t3 = t2 + 2 * n / rate
    t4 = t3 + (stroke - n) / rate
    return from_rates(
        "thread-cut-ramped", [0, t1, t2, t3, t4, t4], [rate, rate, 0, -rate, -rate, 0]
    )


def builtin(
    name: str, rate: float | None = None, ramp_steps: float = DEFAULT_RAMP_STEPS, machine=None
) -> StepProfile:
    if name == "thread-cut":
        return thread_cut(rate, machine=machine)
    if name == "thread-cut-ramped":
        return thread_cut(rate, ramp_steps=ramp_steps, machine=machine)
    raise UserError(f"unknown sequence '{name}' (built-ins: {close_matches(name, BUILTINS)})")


def from_targets(name: str, times_s, targets_steps, rate: float) -> StepProfile:
    """Head for each target at ``rate`` from its row time; a later row interrupts."""
    rate = _check_rate(rate, "slew rate")
    knots_t, knots_r = [0.0], [0.0]
    position, now = 0.0, 0.0
    rows = list(zip(map(float, times_s), map(float, targets_steps)))
    for k, (start, target) in enumerate(rows):
        if start > now:  # at rest until this row
            knots_t += [now, start]
            knots_r += [0.0, 0.0]
        now = max(now, start)
        distance = target - position
        arrive = now + abs(distance) / rate
        deadline = rows[k + 1][0] if k + 1 < len(rows) else np.inf
        end = min(arrive, max(deadline, now))
        if distance:
            speed = np.sign(distance) * rate
            knots_t += [now, end]
            knots_r += [speed, speed]
            position += speed * (end - now)
        knots_t.append(end)
        knots_r.append(0.0)
        now = end
    return StepProfile(name, np.array(knots_t), np.array(knots_r))


def from_file(path: str | os.PathLike, rate: float | None = None, machine=None) -> StepProfile:
    """Read a ``time_s,rate_steps_s`` or ``time_s,target_steps`` CSV (see module doc)."""
    from mechanism.files.tables import check_increasing, read_table

    path = Path(path)
    table = read_table(
        path, required=["time_s"], optional=["rate_steps_s", "target_steps"], what="sequence"
    )
    has_rate, has_target = "rate_steps_s" in table, "target_steps" in table
    if has_rate == has_target:
        raise UserError(
            f"{table.source}: needs exactly one of the columns rate_steps_s (a step-rate profile) "
            f"or target_steps (position targets), next to time_s"
        )
    t = table["time_s"]
    check_increasing(t, table.source, "time_s")
    if t[0] < 0:
        raise UserError(f"{table.source}: time_s starts at {t[0]:g}; times must be >= 0")
    if has_rate:
        if rate is not None:
            raise UserError(
                f"{table.source}: a rate profile sets its own rates; --rate applies to thread-cut and target files"
            )
        if t.size < 2:
            raise UserError(f"{table.source}: a rate profile needs at least two rows")
        times, rates = t, table["rate_steps_s"]
        if times[0] > 0:  # at rest until the first row
            times, rates = (
                np.concatenate([[0.0, times[0]], times]),
                np.concatenate([[0.0, 0.0], rates]),
            )
        return from_rates(path.name, times, rates)
    if rate is None:
        rate = described_step_rate(machine)
    return from_targets(path.name, t, table["target_steps"], rate)


def resolve(
    sequence: str, rate: float | None = None, ramp_steps: float = DEFAULT_RAMP_STEPS, machine=None
) -> StepProfile:
    """A built-in name or a CSV file path (the CLI's ``--sequence``); defaults (step rate,
    thread cut) from ``machine``'s description (default: the shipped machine)."""
    if rate is not None:
        _check_rate(rate, "--rate")
    if sequence in BUILTINS:
        return builtin(sequence, rate, ramp_steps, machine)
    path = Path(sequence)
    if path.suffix.lower() == ".csv" or path.exists():
        return from_file(path, rate, machine)
    raise UserError(
        f"unknown sequence '{sequence}': not a built-in (did you mean {close_matches(sequence, BUILTINS)}?) "
        f"and no such CSV file"
    )
