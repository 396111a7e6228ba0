"""What a model leaves unexplained: the recording's own noise floor, and the signature of a
residual against the whole machine.

- **noise floor** (:func:`noise_floor`): the velocity error a perfect model still shows,
  from the recording itself: the encoder's quantisation (counts per turn from a
  ``# counts_per_rev:`` metadata line, else inferred from the angle's steps) and the
  angle's scatter around a local polynomial while the shaft moves, both passed through
  the tool's one velocity differentiator.
- **signature** (:func:`signature`): where a residual lives. Periodic in which shaft (every
  shaft the drive's ratios name) and at which integer orders; how its periodic part scales
  with speed (a torque's velocity ripple falls with speed, a sensor error's grows); a drift
  or a change at one instant; concentration after voltage rises or falls (load reversals,
  where a dead zone in a transmission shows); a share proportional to the acceleration (an
  angle logged late: a delay, a phase lag that grows with frequency).

The numbers describe; they seed the generic fallback models and the report's sentence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter

from mechanism.errors import UserError
from mechanism.sysid.recording import (
    VELOCITY_POLYORDER,
    Recording,
    smoothed_velocity,
    velocity_coefficients,
)

# A residual counts as unexplained above this multiple of the noise floor. Clean virtual-bench
# recordings (1 kHz, 250 Hz-5 kHz, 2500-20000 counts) end at 0.9-1.7x; a missed effect or
# physics outside the library sits at 3-100x.
UNEXPLAINED_FACTOR = 2.5
PASSBAND_HZ = 40.0  # the velocity differentiator is flat to about here
MAX_ORDER = 48


@dataclass(frozen=True)
class NoiseFloor:
    counts_per_rev: int | None
    quantisation_rad_s: float
    scatter_rad_s: float

    @property
    def rmse(self) -> float:
        return math.hypot(self.quantisation_rad_s, self.scatter_rad_s)

    def to_json(self) -> dict:
        return {
            "rmse_rad_s": self.rmse,
            "encoder_counts_per_rev": self.counts_per_rev,
            "quantisation_rad_s": self.quantisation_rad_s,
            "angle_scatter_rad_s": self.scatter_rad_s,
        }


def encoder_counts(rec: Recording) -> int | None:
    """Counts per turn: the ``counts_per_rev`` metadata line, else the angle's quantisation
    step when every step is a whole number of it; None for an unquantised angle."""
    text = rec.metadata.get("counts_per_rev")
    if text is not None:
        try:
            counts = int(float(text))
        except ValueError:
            raise UserError(
                f"recording {rec.source}: counts_per_rev {text!r} is not a number"
            ) from None
        if counts < 16:
            raise UserError(f"recording {rec.source}: counts_per_rev {counts} is below 16")
        return counts
    return counts_from_steps(rec.arm_angle_rad)


def counts_from_steps(angle: np.ndarray) -> int | None:
    """Counts per turn from an angle's quantisation step [rad] when every step is a whole
    number of it; None for an unquantised angle (or fewer than 100 moving samples)."""
    steps = np.abs(np.diff(angle))
    steps = steps[steps > 1e-6]
    if len(steps) < 100:
        return None
    smallest = float(np.min(steps))
    # the smallest step may be several counts (a shaft that never moves by one count per sample)
    for parts in range(1, 33):
        q = smallest / parts
        multiple = steps / q
        if np.mean(np.abs(multiple - np.round(multiple)) < 0.02) >= 0.95:
            counts = 2 * math.pi / q
            return int(round(counts)) if abs(counts - round(counts)) < 0.02 * counts else None
    return None


def noise_floor(rec: Recording) -> NoiseFloor:
    """The velocity rmse a perfect model would show on ``rec``: the smoothed angle quantised
    again by the encoder and differentiated like the measurement (that keeps the
    quantisation error's correlation at low speed and its absence at rest), plus the
    angle's scatter beyond quantisation, as white noise through the differentiator."""
    c = velocity_coefficients(rec.dt)
    window = len(c)
    angle = rec.arm_angle_rad
    counts = encoder_counts(rec)
    if len(angle) < 4 * window:
        return NoiseFloor(counts, 0.0, 0.0)
    smooth = savgol_filter(angle, window, VELOCITY_POLYORDER)
    requantised = (
        np.floor(smooth / (2 * math.pi / counts)) * (2 * math.pi / counts) if counts else smooth
    )
    error = smoothed_velocity(requantised, rec.dt) - smoothed_velocity(smooth, rec.dt)
    quantisation = float(np.sqrt(np.mean(error[window:-window] ** 2)))
    speed = np.abs(rec.velocity_rad_s)
    moving = speed > 0.2 * np.percentile(speed, 90)
    scatter = 0.0
    if moving.sum() > 100:
        centre = savgol_coeffs(window, VELOCITY_POLYORDER, use="dot")[window // 2]
        measured = float(np.var((angle - smooth)[moving]))
        quantised = float(np.var((requantised - smooth)[moving]))
        # white noise through the smoother leaves variance sigma^2 (1 - h0)
        sigma = math.sqrt(max(measured - quantised, 0.0) / max(1e-9, 1 - centre))
        scatter = sigma * float(np.sqrt(np.sum(c * c)))
    return NoiseFloor(counts, quantisation, scatter)


# ----------------------------------------------------------------------------- signature


@dataclass
class Periodic:
    shaft: str
    ratio: float  # shaft turns per described-shaft turn
    orders: list[int]  # significant orders, strongest first
    amplitudes_rad_s: list[float]
    share: float  # share of the residual variance the orders explain
    speed_exponent: float  # d log(velocity amplitude) / d log(speed), strongest order
    kind: str  # "torque-like", "sensor-like", "mixed"

    def to_json(self) -> dict:
        return {
            "shaft": self.shaft,
            "turns_per_shaft_turn": self.ratio,
            "orders": self.orders,
            "amplitudes_rad_s": self.amplitudes_rad_s,
            "variance_share": self.share,
            "speed_exponent": self.speed_exponent,
            "scales_like": self.kind,
        }


@dataclass
class Signature:
    periodic: Periodic | None
    delay_s: float
    delay_share: float  # residual variance explained by -delay x acceleration
    step_time_s: float | None
    step_rad_s: float
    step_share: float
    drift_share: float
    after_rise_rms: float
    after_fall_rms: float
    steady_rms: float
    low_speed_rms: float

    def to_json(self) -> dict:
        return {
            "periodic": self.periodic.to_json() if self.periodic else None,
            "acceleration_share": self.delay_share,
            "change_at_s": self.step_time_s,
            "change_rad_s": self.step_rad_s,
            "change_share": self.step_share,
            "drift_share": self.drift_share,
            "after_voltage_rise_rms_rad_s": self.after_rise_rms,
            "after_voltage_fall_rms_rad_s": self.after_fall_rms,
            "steady_rms_rad_s": self.steady_rms,
            "low_speed_rms_rad_s": self.low_speed_rms,
        }


def _order_amplitudes(r, phase, speed, ratio, dt, max_order=MAX_ORDER):
    """Velocity amplitude of each order 1..max_order of ``phase`` in ``r`` (samples where the
    order's frequency lies in the differentiator's pass band), and the sample count used."""
    z = np.exp(1j * phase)
    zk = np.ones_like(z)
    out = np.zeros(max_order + 1)
    counts = np.zeros(max_order + 1, dtype=int)
    power = np.zeros(max_order + 1)
    for k in range(1, max_order + 1):
        zk *= z
        ok = k * ratio * speed < 2 * math.pi * PASSBAND_HZ
        n = int(ok.sum())
        if n < 200:
            break
        out[k] = 2 * abs(np.mean(r[ok] * np.conj(zk[ok])))
        counts[k] = n
        power[k] = float(np.mean(r[ok] ** 2))
    return out, counts, power


def _correlation_length(r: np.ndarray) -> float:
    from mechanism.sysid.identifiability import correlation_length

    return correlation_length(r[: min(len(r), 200000)])


def periodic_part(r, angle, speed, shafts: dict[str, float], dt) -> Periodic | None:
    """The strongest periodic structure of ``r`` over every shaft's angle, with its orders."""
    moving = speed > 0.05 * max(float(np.percentile(speed, 99)), 1e-9)
    if moving.sum() < 1000:
        return None
    sel = np.flatnonzero(moving)
    sel = sel[:: max(1, len(sel) // 120000)]  # a long recording: every few samples are enough
    rr, th, sp = r[sel], angle[sel], speed[sel]
    rr = rr - rr.mean()
    total = float(np.mean(rr * rr))
    if total <= 0:
        return None
    corr = _correlation_length(rr)
    found = []
    for name, ratio in shafts.items():
        orders, share, amps = _significant_orders(rr, th, sp, ratio, dt, corr, total)
        if orders:
            found.append((name, orders, share, ratio, amps))
    if not found or max(f[2] for f in found) < 0.05:
        # in none of the described shafts: perhaps in one the description does not name
        unnamed = unnamed_shaft_ratio(rr, th, shafts)
        if unnamed is None:
            return None
        orders, share, amps = _significant_orders(rr, th, sp, unnamed, dt, corr, total, 4)
        if not orders or share < 0.05:
            return None
        found = [(UNNAMED_SHAFT, orders, share, unnamed, amps)]
    # integer ratios make one structure periodic in several shafts: among those that explain
    # about as much, say the motor (its orders are the drive's), then the described shaft
    strongest = max(f[2] for f in found)
    preference = {"motor": 0, "shaft": 1}
    name, orders, share, ratio, amps = min(
        (f for f in found if f[2] > 0.8 * strongest),
        key=lambda f: (preference.get(f[0], 2), min(f[1])),
    )
    exponent = _speed_exponent(rr, ratio * th, sp, orders[0])
    kind = "sensor-like" if exponent > 0.5 else ("torque-like" if exponent < -0.4 else "mixed")
    return Periodic(
        name,
        float(ratio),
        orders,
        [float(amps[k]) for k in orders],
        min(share, 1.0),
        exponent,
        kind,
    )


def _significant_orders(rr, th, sp, ratio, dt, corr, total, max_order=MAX_ORDER):
    """The orders of a shaft turning ``ratio`` times per shaft turn that stand out of ``rr``
    (strongest first, at most four), the variance share they explain, every order's amplitude.
    An order counts when it stands out of what noise of the residual it was measured on gives
    (4 sigma), over at least a fifth of the moving samples."""
    amps, counts, power = _order_amplitudes(rr, ratio * th, sp, ratio, dt, max_order)
    noise = 4 * np.sqrt(power * corr / np.maximum(counts, 1)) * math.sqrt(2)
    sig = [k for k in np.argsort(-amps) if amps[k] > noise[k] and counts[k] > 0.2 * len(rr)][:4]
    share = float(sum(0.5 * amps[k] ** 2 * counts[k] for k in sig) / (total * len(rr)))
    return [int(k) for k in sig], share, amps


UNNAMED_SHAFT = "unnamed_shaft"
# the unnamed shaft's line must stand this far above the median of the order spectrum (noise
# bins are exponentially distributed in power, whose median is ln 2 of its mean: 8x the median
# amplitude is 44x the mean power, e^-44 for one bin)
UNNAMED_LINE_FACTOR = 8.0


def unnamed_shaft_ratio(r, angle, shafts: dict[str, float]) -> float | None:
    """The turns per described-shaft turn of a shaft the description does not name (an
    accessory, an idler, a pump on its own belt) in whose angle ``r`` repeats, or None. The
    residual is averaged into bins of the unwrapped shaft angle and Fourier-transformed there
    (an order spectrum: a line at every ratio, integer or not); lines at the described
    shafts' orders are left out. Needs 20 turns or more."""
    turns = float(np.ptp(angle)) / (2 * math.pi)
    if turns < 20:
        return None
    per_turn = 64
    index = np.floor((angle - angle.min()) * (per_turn / (2 * math.pi))).astype(np.int64)
    n = int(index.max()) + 1
    count = np.bincount(index, minlength=n)
    binned = np.bincount(index, weights=r, minlength=n) / np.maximum(count, 1)
    spectrum = np.abs(np.fft.rfft(binned))
    ratios = np.fft.rfftfreq(n, d=1.0 / per_turn)
    resolution = per_turn / n
    valid = (ratios > 0.2) & (ratios < 0.4 * per_turn)
    for ratio in shafts.values():
        orders = np.arange(1, MAX_ORDER + 1) * ratio
        nearest = np.min(np.abs(ratios[:, None] - orders[None, :]), axis=1)
        valid &= nearest > 3 * resolution
    if valid.sum() < 100:
        return None
    level = spectrum[valid]
    peak = int(np.flatnonzero(valid)[np.argmax(level)])
    if spectrum[peak] < UNNAMED_LINE_FACTOR * float(np.median(level)):
        return None
    # the bin's centre can be half a bin off, which over the whole recording cancels half the
    # line: refine on the samples themselves
    fine = ratios[peak] + np.linspace(-resolution, resolution, 21)
    sel = slice(None, None, max(1, len(r) // 30000))
    rs, th = r[sel], angle[sel]
    strength = [abs(np.mean(rs * np.exp(-1j * q * th))) for q in fine]
    return float(fine[int(np.argmax(strength))])


def _speed_exponent(r, phase, speed, order) -> float:
    bands = np.quantile(speed, [0, 0.25, 0.5, 0.75, 1.0])
    xs, ys = [], []
    for lo, hi in zip(bands[:-1], bands[1:]):
        sel = (speed >= lo) & (speed <= hi)
        if sel.sum() < 300:
            continue
        z = np.exp(1j * order * phase[sel])
        xs.append(math.log(max(float(np.median(speed[sel])), 1e-6)))
        ys.append(math.log(max(2 * abs(np.mean(r[sel] * np.conj(z))), 1e-12)))
    if len(xs) < 2 or np.ptp(xs) < 0.2:
        return math.nan
    return float(np.polyfit(xs, ys, 1)[0])


def _explained(r, x) -> tuple[float, float]:
    """Least-squares coefficient of r on x and the variance share it explains."""
    xx = float(np.dot(x, x))
    if xx <= 0:
        return 0.0, 0.0
    b = float(np.dot(r, x)) / xx
    rr = float(np.dot(r, r))
    return b, (b * b * xx / rr) if rr > 0 else 0.0


def _step_change(t, r, steady) -> tuple[float | None, float, float, float]:
    """The best single change of the mean residual over time (steady samples): its time,
    size, variance share; and the share a linear drift explains instead."""
    idx = np.flatnonzero(steady)
    if len(idx) < 1000:
        return None, 0.0, 0.0, 0.0
    rr = r[idx] - r[idx].mean()
    n = len(rr)
    cs = np.cumsum(rr)[:-1]
    k = np.arange(1, n)
    # between-group sum of squares of a split at k
    gain = cs * cs * n / (k * (n - k))
    margin = max(n // 20, 1)
    gain[:margin] = 0
    gain[-margin:] = 0
    i = int(np.argmax(gain))
    total = float(np.dot(rr, rr))
    share = float(gain[i] / total) if total > 0 else 0.0
    size = float(rr[i + 1 :].mean() - rr[: i + 1].mean())
    _, drift = _explained(rr, t[idx] - t[idx].mean())
    return float(t[idx[i + 1]]), size, share, drift


def signature(rec: Recording, r: np.ndarray, shafts: dict[str, float]) -> Signature:
    """The signature of residual ``r`` (over the whole recording) against the machine."""
    t, u, dt = rec.time_s, rec.voltage_V, rec.dt
    w = rec.velocity_rad_s
    speed = np.abs(w)
    periodic = periodic_part(r, rec.arm_angle_rad, speed, shafts, dt)
    acc = smoothed_velocity(w, dt)
    # an angle logged late by d reads w(t - d) = w - d w' + d^2/2 w'': the residual is the
    # acceleration and its rate of change, in whatever share the baseline's winding lag left
    timing = np.column_stack([acc, smoothed_velocity(acc, dt)])
    coef, *_ = np.linalg.lstsq(timing, r, rcond=None)
    rr = float(np.dot(r, r))
    delay_share = float(1 - np.sum((r - timing @ coef) ** 2) / rr) if rr > 0 else 0.0
    b = float(coef[0])
    jumps = np.diff(u)
    rise, fall = np.zeros(len(r), bool), np.zeros(len(r), bool)
    span = max(int(0.15 / dt), 1)
    for k in np.flatnonzero(np.abs(jumps) > 0.5):
        (rise if jumps[k] > 0 else fall)[k + 1 : k + 1 + span] = True
    steady = ~(rise | fall) & (np.abs(u) > 0.5)
    # plateau means removed: a change or drift shows within each voltage level
    level = np.round(u / 0.5)
    if steady.any():
        keys, inv = np.unique(level[steady], return_inverse=True)
        centred = r.copy()
        centred[steady] = r[steady] - (np.bincount(inv, weights=r[steady]) / np.bincount(inv))[inv]
    else:
        centred = r
    step_t, step, step_share, drift = _step_change(t, centred, steady)
    top = max(float(np.percentile(speed, 99)), 1e-9)
    low = (speed < 0.1 * top) & ((speed > 0.01) | (np.abs(u) > 0.1))

    def rms(mask):
        return float(np.sqrt(np.mean(r[mask] ** 2))) if mask.any() else 0.0

    return Signature(
        periodic,
        -b,
        delay_share,
        step_t,
        step,
        step_share,
        drift,
        rms(rise),
        rms(fall),
        rms(steady),
        rms(low),
    )


def _shaft_words(p: Periodic, shafts: dict[str, float]) -> str:
    main = p.orders[0]
    if p.shaft == UNNAMED_SHAFT:
        name = (
            f"turn of a shaft the description does not name ({p.ratio:.4g} turns per turn of the "
            f"described shaft: an accessory, an idler, a shaft on a belt of its own)"
        )
        return f"a residual {main} times per {name}; " + _amplitude_words(p.kind)
    name = "shaft" if p.shaft == "shaft" else p.shaft.replace("_", " ")
    equivalent = main * p.ratio
    also = (
        f" ({equivalent:g} per turn of the described shaft)"
        if p.shaft != "shaft" and abs(equivalent - round(equivalent)) < 1e-6
        else ""
    )
    others = [o for o in p.orders[1:]]
    extra = f", with orders {', '.join(map(str, others))} of the same shaft" if others else ""
    return f"a residual {main} times per {name} turn{also}{extra}; {_amplitude_words(p.kind)}"


def _amplitude_words(kind: str) -> str:
    return {
        "torque-like": "its velocity ripple falls with speed as an inertia filters a torque of constant amplitude",
        "sensor-like": "it grows with speed, as an error of the angle sensor does",
        "mixed": "its size changes little with speed",
    }[kind]


def describe(sig: Signature, shafts: dict[str, float]) -> str:
    """One sentence for a mechanism engineer: what the residual looks like."""
    parts = []
    if sig.periodic is not None:
        parts.append(
            f"{_shaft_words(sig.periodic, shafts)} ({100 * sig.periodic.share:.0f}% of the residual)"
        )
    if sig.delay_share > 0.3:
        parts.append(
            f"an error shaped like the acceleration and its rate of change ({100 * sig.delay_share:.0f}% of the "
            f"residual): a timing error, a phase lag that grows with frequency (a delay in the log, a lag in the drive)"
        )
    if (
        sig.step_share > 0.3
        and sig.step_share > 1.5 * sig.drift_share
        and sig.step_time_s is not None
    ):
        parts.append(
            f"a change at t = {sig.step_time_s:.1f} s: the speed error steps by {sig.step_rad_s:+.2g} rad/s "
            f"at the same voltages ({100 * sig.step_share:.0f}% of the steady residual)"
        )
    elif sig.drift_share > 0.3:
        parts.append(
            f"a drift over the recording ({100 * sig.drift_share:.0f}% of the steady residual)"
        )
    if max(sig.after_rise_rms, sig.after_fall_rms) > 2.5 * max(sig.steady_rms, 1e-12):
        falls = sig.after_fall_rms > 1.5 * sig.after_rise_rms
        which = (
            "falls"
            if falls
            else ("rises" if sig.after_rise_rms > 1.5 * sig.after_fall_rms else "changes")
        )
        where = (
            ", where the load on the transmission reverses (the motor brakes the shaft)"
            if falls
            else ""
        )
        parts.append(
            f"concentrated after the voltage {which} ({max(sig.after_rise_rms, sig.after_fall_rms):.2g} rad/s rms against "
            f"{sig.steady_rms:.2g} in steady running){where}"
        )
    if sig.low_speed_rms > 2.5 * max(sig.steady_rms, 1e-12):
        parts.append(f"largest at low speed ({sig.low_speed_rms:.2g} rad/s rms)")
    if not parts:
        parts.append(
            "no structure the signature recognises: broadband, in no shaft's angle, time or speed"
        )
    return "; ".join(parts)
