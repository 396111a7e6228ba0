"""Bench recordings: read and validate the recording contract, and the one velocity definition.

The contract (issue 6, checked by an independent benchmark): a UTF-8 CSV with optional
leading ``#`` comment lines, a header, then rows. Required columns ``time`` [s, strictly
increasing, nominally 1 kHz], ``voltage`` [V, motor terminal voltage as logged] and
``arm_angle`` [rad, unwrapped arm-shaft encoder angle, 0 = needle top dead centre];
optional ``current`` [A]. Columns named with units (``time_s``, ``voltage_V``,
``arm_angle_rad``, ``current_A``) are accepted as aliases; unknown columns are ignored.

Every problem a user can fix is a :class:`~mechanism.errors.UserError` (exit 2): a missing
column, non-numeric/NaN/inf values, time that is not strictly increasing (duplicated or
decreasing), fewer than :data:`MIN_DURATION_S` of data, a gap in the sampling. Slightly
irregular sampling (logger jitter) is resampled onto a uniform grid at the median rate.

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
from mechanism.files.tables import check_increasing, read_table

MIN_DURATION_S = 2.0
VELOCITY_WINDOW_S = 0.021
VELOCITY_POLYORDER = 4
MAX_GAP_S = 0.05
ENCODER_STEP_RAD = 2 * np.pi / 20000

COLUMN_ALIASES = {
    "time": ["time_s", "t", "t_s"],
    "voltage": ["voltage_V", "voltage_v", "U_V", "u_V"],
    "arm_angle": ["arm_angle_rad", "angle_rad", "arm_position_rad"],
    "current": ["current_A", "current_a", "I_A"],
}


@dataclass
class Recording:
    """A validated bench recording on a uniform time grid (SI units)."""

    time_s: np.ndarray
    voltage_V: np.ndarray
    arm_angle_rad: np.ndarray
    current_A: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    source: str = "<recording>"

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
    return savgol_filter(angle, window, VELOCITY_POLYORDER, deriv=1, delta=dt, axis=axis, mode="interp")


def read_recording(path: str | os.PathLike) -> Recording:
    """Read and validate a recording CSV (see the module docstring for the contract)."""
    path = Path(path)
    label = f"recording {path}"
    table = read_table(
        path,
        required=["time", "voltage", "arm_angle"],
        optional=["current"],
        aliases=COLUMN_ALIASES,
        min_rows=2,
        what="recording",
    )
    return make_recording(
        table["time"], table["voltage"], table["arm_angle"],
        table["current"] if "current" in table else None,
        metadata=table.metadata, source=str(path), label=label,
    )


def make_recording(time, voltage, arm_angle, current=None, metadata=None, source="<recording>", label=None) -> Recording:
    """Validate arrays as a recording (the same checks as for a file)."""
    label = label or f"recording {source}"
    time = np.asarray(time, dtype=float)
    voltage = np.asarray(voltage, dtype=float)
    arm_angle = np.asarray(arm_angle, dtype=float)
    columns = {"time": time, "voltage": voltage, "arm_angle": arm_angle}
    if current is not None:
        current = np.asarray(current, dtype=float)
        columns["current"] = current
    for name, values in columns.items():
        if values.ndim != 1 or len(values) != len(time):
            raise UserError(f"{label}: column {name} has {values.size} values, time has {len(time)}")
        if not np.all(np.isfinite(values)):
            raise UserError(f"{label}: column {name} contains NaN or inf at data row {int(np.flatnonzero(~np.isfinite(values))[0]) + 1}")
    if len(time) < 2:
        raise UserError(f"{label}: {len(time)} data row(s); at least {MIN_DURATION_S:g} s of data needed")
    check_increasing(time, label)
    duration = time[-1] - time[0]
    if duration < MIN_DURATION_S:
        raise UserError(f"{label}: only {duration:.3g} s of data; at least {MIN_DURATION_S:g} s needed")
    steps = np.diff(time)
    dt = float(np.median(steps))
    if steps.max() > max(MAX_GAP_S, 3 * dt):
        i = int(np.argmax(steps))
        raise UserError(f"{label}: gap of {steps[i]:.3g} s in the sampling after t = {time[i]:.6g} s (sampling is every {dt:.3g} s)")
    if dt > 0.01:
        raise UserError(f"{label}: sampled every {dt:.3g} s; at least 100 Hz needed to see the machine's dynamics (nominally 1 kHz)")
    jumps = np.abs(np.diff(arm_angle))
    if jumps.max() > np.pi:
        # A wrapped angle (0..2pi) instead of the unwrapped one of the contract: unwrap it.
        warnings.warn(f"{label}: arm_angle jumps by more than pi between samples; treating it as wrapped and unwrapping it")
        arm_angle = np.unwrap(arm_angle)
    if np.max(np.abs(steps - dt)) > 0.01 * dt:
        grid = time[0] + dt * np.arange(int(np.floor(duration / dt + 1e-9)) + 1)
        hold = np.clip(np.searchsorted(time, grid, side="right") - 1, 0, len(time) - 1)
        voltage = voltage[hold]  # the logged voltage is held between samples
        arm_angle = np.interp(grid, time, arm_angle)
        current = np.interp(grid, time, current) if current is not None else None
        time = grid
    else:
        time = time[0] + dt * np.arange(len(time))
    return Recording(time, voltage, arm_angle, current, dict(metadata or {}), source)


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
    return Recording(rec.time_s[:n:m].copy(), rec.voltage_V[:n].reshape(-1, m).mean(axis=1), rec.arm_angle_rad[:n:m].copy(),
                     current, dict(rec.metadata), rec.source)


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
        return Excitation(False, f"the voltage is constant ({np.median(u):.3g} V, spread {spread:.2g} V): one operating point cannot separate inertia, viscous and Coulomb friction, nor tell any missing effect from another", levels)
    # how much the motion determines is judged by the fit's information (mechanism.sysid.identifiability)
    return Excitation(True, "voltage varies between %.3g and %.3g V" % (lo, hi), levels)


def _voltage_levels(u: np.ndarray, resolution: float = 0.25) -> list[float]:
    """Distinct voltage plateaus (rounded), longest first."""
    rounded = np.round(u / resolution) * resolution
    values, counts = np.unique(rounded, return_counts=True)
    order = np.argsort(-counts)
    keep = counts[order] > 0.02 * len(u)
    return [float(v) for v in values[order][keep]]
