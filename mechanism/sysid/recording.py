"""Bench recordings: read and validate the recording contract, and the one velocity definition.

The contract (issue 6, checked by an independent benchmark): a UTF-8 CSV with optional
leading ``#`` comment lines, a header, then rows. Required columns ``time`` [s, strictly
increasing, nominally 1 kHz], ``voltage`` [V, motor terminal voltage as logged] and
``arm_angle`` [rad, unwrapped arm-shaft encoder angle, 0 = needle top dead centre];
optional ``current`` [A]. Columns named with units (``time_s``, ``voltage_V``,
``arm_angle_rad``, ``current_A``) are accepted as aliases, as are ``shaft_angle`` (the described
shaft's angle, from its zero) and, for a described machine, its main motor's input column
``JOINT_V`` (a recording with one input column per motor); unknown columns (other motors' inputs,
``JOINT_angle`` of other measured joints) are ignored.

Other formats (compressed CSV, MATLAB, Parquet, TDMS, JSON; :mod:`mechanism.files.formats`)
and other column names and units (a ``[recording]`` map; :mod:`mechanism.sysid.recording_map`)
are read into the same contract; ``shaft_angle`` is the generic name of ``arm_angle``.

Every problem a user can fix is a :class:`~mechanism.errors.UserError` (exit 2): a missing
column, non-numeric/NaN/inf values, time that is not strictly increasing (duplicated or
decreasing), fewer than :data:`MIN_DURATION_S` of data, a gap in the sampling. Slightly
irregular sampling (logger jitter) is resampled onto a uniform grid at the mean step.

Velocity: the encoder angle is quantised to 2*pi/20000 rad; differencing it at 1 kHz gives
0.31 rad/s steps. :func:`smoothed_velocity` is a Savitzky-Golay differentiator (a local
degree-4 polynomial over a 21 ms window: flat to about 40 Hz, -3 dB near 60 Hz, a
quantisation noise floor of about 0.008 rad/s). Every velocity residual and every rmse the
tool reports applies this same differentiator to the measured angle and to the simulated
angle, so the filter cancels out of the comparison.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.signal import savgol_coeffs

from mechanism.errors import UserError
from mechanism.files.tables import check_increasing

MIN_DURATION_S = 2.0
VELOCITY_WINDOW_S = 0.021
VELOCITY_POLYORDER = 4
MAX_GAP_S = 0.05
ENCODER_STEP_RAD = 2 * np.pi / 20000


@dataclass
class Recording:
    """A validated bench recording on a uniform time grid (SI units)."""

    time_s: np.ndarray
    voltage_V: np.ndarray
    arm_angle_rad: np.ndarray
    current_A: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    source: str = "<recording>"
    # what was read and done (format, columns, units, resampling)
    reading: dict = field(default_factory=dict)

    @property
    def dt(self) -> float:
        return float(self.time_s[1] - self.time_s[0])

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def velocity_rad_s(self) -> np.ndarray:
        """Measured arm velocity by the tool's one velocity definition (cached)."""
        cached = self.__dict__.get("_velocity")
        if cached is None:
            cached = smoothed_velocity(self.arm_angle_rad, self.dt)
            self.__dict__["_velocity"] = cached
        return cached


def velocity_coefficients(dt: float) -> np.ndarray:
    """The Savitzky-Golay first-derivative weights for sample step ``dt`` (odd length)."""
    window = max(VELOCITY_POLYORDER + 3, int(round(VELOCITY_WINDOW_S / dt)) | 1)
    return savgol_coeffs(window, VELOCITY_POLYORDER, deriv=1, delta=dt, use="dot")


def smoothed_velocity(angle: np.ndarray, dt: float, axis: int = -1) -> np.ndarray:
    """d(angle)/dt by the Savitzky-Golay differentiator (same length; ends fitted by the
    end polynomials). Works on stacked segments along ``axis``."""
    from scipy.signal import savgol_filter

    window = len(velocity_coefficients(dt))
    angle = np.asarray(angle, dtype=float)
    if angle.shape[axis] < window:
        return np.gradient(angle, dt, axis=axis)
    return savgol_filter(
        angle, window, VELOCITY_POLYORDER, deriv=1, delta=dt, axis=axis, mode="interp"
    )


def read_recording(
    path: str | os.PathLike, recording_map=None, motor_joint: str | None = None
) -> Recording:
    """Read and validate a recording (see the module docstring for the contract) in any
    format :mod:`mechanism.files.formats` reads, its columns taken by ``recording_map`` (a
    :class:`~mechanism.sysid.recording_map.RecordingMap`, a path to a ``--recording-map``
    TOML, or None for the default column names). What was read and done is
    ``Recording.reading`` (written into the identify and diagnose JSON). With ``motor_joint``
    (the described main motor's), its input column ``JOINT_V`` is also a default voltage
    column, for recordings that name one input column per motor."""
    from mechanism.files.formats import read_columns
    from mechanism.sysid.recording_map import RecordingMap, apply_map, read_recording_map

    path = Path(path)
    if recording_map is not None and not isinstance(recording_map, RecordingMap):
        recording_map = read_recording_map(recording_map)
    columns = read_columns(
        path, "recording", records=recording_map.get("records") if recording_map else None
    )
    signals = apply_map(columns, recording_map, motor_joint)
    return make_recording(
        signals.time_s,
        signals.voltage_V,
        signals.shaft_angle_rad,
        signals.current_A,
        metadata=signals.metadata,
        source=str(path),
        label=f"recording {path}",
        unwrap=signals.unwrap,
        reading=signals.reading,
    )


def sampling_gaps(time: np.ndarray) -> tuple[float, list[tuple[float, float]]]:
    """The median step [s] and the gaps: (time before the gap [s], gap length [s]) for every
    step longer than max(:data:`MAX_GAP_S`, 3 steps)."""
    steps = np.diff(time)
    dt = float(np.median(steps)) if len(steps) else 0.0
    big = np.flatnonzero(steps > max(MAX_GAP_S, 3 * dt))
    return dt, [(float(time[i]), float(steps[i])) for i in big]


def make_recording(
    time,
    voltage,
    arm_angle,
    current=None,
    metadata=None,
    source="<recording>",
    label=None,
    unwrap: bool | None = None,
    reading: dict | None = None,
) -> Recording:
    """Validate arrays as a recording (the same checks as for a file). ``unwrap``: True
    unwraps, False never does, None unwraps only an angle found wrapped (with a warning)."""
    label = label or f"recording {source}"
    reading = dict(reading or {})
    time = np.asarray(time, dtype=float)
    voltage = np.asarray(voltage, dtype=float)
    arm_angle = np.asarray(arm_angle, dtype=float)
    columns = {"time": time, "voltage": voltage, "shaft_angle": arm_angle}
    if current is not None:
        current = np.asarray(current, dtype=float)
        columns["current"] = current
    for name, values in columns.items():
        if values.ndim != 1 or len(values) != len(time):
            raise UserError(
                f"{label}: column {name} has {values.size} values, time has {len(time)}"
            )
        if not np.all(np.isfinite(values)):
            raise UserError(
                f"{label}: column {name}: NaN/inf not allowed, found at data row {int(np.flatnonzero(~np.isfinite(values))[0]) + 1}"
            )
    if len(time) < 2:
        raise UserError(
            f"{label}: {len(time)} data row(s); at least {MIN_DURATION_S:g} s of data needed"
        )
    check_increasing(time, label)
    duration = time[-1] - time[0]
    if duration < MIN_DURATION_S:
        raise UserError(
            f"{label}: only {duration:.3g} s of data; at least {MIN_DURATION_S:g} s needed"
        )
    steps = np.diff(time)
    dt, gaps = sampling_gaps(time)
    if gaps:
        at, length = max(gaps, key=lambda g: g[1])
        raise UserError(
            f"{label}: {len(gaps)} gap(s) in the sampling, the longest {length:.3g} s after t = {at:.6g} s "
            f"(sampling is every {dt:.3g} s); a gap is not interpolated over: mechanism inspect-recording --split DIR "
            "cuts it into gap-free pieces (a fleet for diagnose --out)"
        )
    if dt > 0.01:
        raise UserError(
            f"{label}: sampled every {dt:.3g} s; at least 100 Hz needed to see the machine's dynamics (nominally 1 kHz)"
        )
    jumps = np.abs(np.diff(arm_angle))
    if unwrap is None and jumps.max() > np.pi:
        # A wrapped angle (0..2pi) instead of the unwrapped one of the contract: unwrap it.
        warnings.warn(
            f"{label}: shaft_angle jumps by more than pi between samples; treating it as wrapped and unwrapping it"
        )
        arm_angle = np.unwrap(arm_angle)
        reading.setdefault("shaft_angle_rad", {})["unwrapped"] = (
            "yes: found wrapped (jumps of more than pi)"
        )
    deviation = float(np.max(np.abs(steps - dt)) / dt)
    # the grid's step: float rounding of large time stamps (epoch seconds or ms) moves the median
    # step by a whole rounding quantum (2.4e-7 s at 1.7e9 s: half a sample over a minute at
    # 190 Hz) and the mean step (duration / intervals) by 1e-16 of the duration. Uneven stamps
    # use the mean; even ones keep the median unless the two differ by more than 1e-9 of a step
    # (a recording written with exact stamps reads bit for bit as before).
    mean = duration / (len(time) - 1)
    if deviation > 0.01 or abs(mean - dt) > 1e-9 * dt:
        dt = mean
    if deviation > 0.01:
        grid = time[0] + dt * np.arange(int(np.floor(duration / dt + 1e-9)) + 1)
        # a grid point within a millionth of a step of a sample is at it (rounding decides nothing)
        hold = np.clip(np.searchsorted(time, grid + 1e-6 * dt, side="right") - 1, 0, len(time) - 1)
        voltage = voltage[hold]  # the logged voltage is held between samples
        arm_angle = np.interp(grid, time, arm_angle)
        current = np.interp(grid, time, current) if current is not None else None
        reading["resampling"] = {
            "method": "onto a uniform grid at the mean step: voltage held from the last sample (zero-order hold), "
            "shaft angle and current interpolated linearly",
            "rate_Hz": 1.0 / dt,
            "samples_in": int(len(time)),
            "samples_out": int(len(grid)),
            "largest_step_deviation_percent": 100 * deviation,
        }
        time = grid
    else:
        reading["resampling"] = {"method": "none: steps uniform within 1 %", "rate_Hz": 1.0 / dt}
        time = time[0] + dt * np.arange(len(time))
    return Recording(time, voltage, arm_angle, current, dict(metadata or {}), source, reading)


FIT_RATE_HZ = 1000.0


def at_fitting_rate(rec: Recording) -> Recording:
    """A recording sampled at 2 kHz or faster, brought to about 1 kHz for fitting: the
    velocity differentiator passes nothing above ~60 Hz, so faster samples only cost time
    (a 5 kHz minute fits in the time of a 1 kHz one). The angle is kept at every m-th sample
    (it is exact there), the voltage averaged over each block of m (the drive holds a
    sample's voltage over its step)."""
    m = int((1.0 / rec.dt) // FIT_RATE_HZ)
    if m < 2:
        return rec
    n = len(rec) // m * m
    current = rec.current_A[:n:m] if rec.current_A is not None else None
    return Recording(
        rec.time_s[:n:m].copy(),
        rec.voltage_V[:n].reshape(-1, m).mean(axis=1),
        rec.arm_angle_rad[:n:m].copy(),
        current,
        dict(rec.metadata),
        rec.source,
        dict(rec.reading),
    )


@dataclass
class Excitation:
    """Whether a recording excites the machine enough to identify anything."""

    identifiable: bool
    reason: str
    voltage_levels_V: list[float]


def check_excitation(rec: Recording) -> Excitation:
    """A recording at one constant voltage cannot separate viscous from Coulomb friction
    (one steady-state point), has no step response for the inertia, and no speed range to
    tell a torque from a sensor error: such a recording is *not identifiable*. (What the
    motion determines is judged by :mod:`mechanism.sysid.identifiability`.)"""
    u = rec.voltage_V
    lo, hi = np.percentile(u, [1, 99])
    spread = hi - lo
    levels = _voltage_levels(u)
    if spread < max(0.5, 0.05 * abs(np.median(u))):
        return Excitation(
            False,
            f"the voltage is constant ({np.median(u):.3g} V, spread {spread:.2g} V): one operating point cannot separate inertia, viscous and Coulomb friction, nor tell any missing effect from another",
            levels,
        )
    # how much the motion determines is judged by the fit's information (mechanism.sysid.identifiability)
    return Excitation(True, "voltage varies between %.3g and %.3g V" % (lo, hi), levels)


def _voltage_levels(u: np.ndarray, resolution: float = 0.25) -> list[float]:
    """Distinct voltage plateaus (rounded), longest first."""
    rounded = np.round(u / resolution) * resolution
    values, counts = np.unique(rounded, return_counts=True)
    order = np.argsort(-counts)
    keep = counts[order] > 0.02 * len(u)
    return [float(v) for v in values[order][keep]]
