"""The lumped drive model of the thesis (eq. 15-16), simulated fast over many segments.

Equation (arm side: the encoder is on the arm shaft, so every state and torque here is
expressed on the arm shaft; n = 8 is the motor-to-arm belt ratio)::

    J w' = n Kt/R (U - Ke n w) - n^2 d w - Fc sgn(w) - (loads)

with the thesis's motor-side numbers mapped as J = n^2 J_motor, viscous n^2 d_motor, and
Fc the arm-side Coulomb friction (0.18 Nm in the thesis). The baseline reports its
parameters in the thesis's own conventions (``inertia_motor_side_kgm2``,
``viscous_motor_side_Nm_s_per_rad``, ``coulomb_arm_Nm``) so that they compare directly
with Table 3. Motor constants (R, Kt, Ke) are the datasheet values unless freed.

Stick-slip: a shaft at rest stays at rest while the driving torque is within the static
friction level (Coulomb, plus a Stribeck excess when that effect is present); a velocity
that would cross zero inside a step stops at zero (Karnopp). Linear damping (back-emf and
viscous) is integrated exactly over each step.

Position-dependent torques are driven by the *measured* arm angle inside short segments
that restart from the measured velocity (multiple shooting): a free 60 s simulation would
drift in phase against the recording, and every periodic residual would then be a phase
error rather than missing physics.

The hot loop is a small C kernel (``mechanism/native/lumped.c``, through
:mod:`mechanism.native`); :func:`simulate_numpy` is the same equations vectorised over
segments, used where no C compiler exists and to check the kernel.
"""

from __future__ import annotations

import ctypes
import functools
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Hashable

import numpy as np

from mechanism.tolerances import LAG_MEMORY_TIME_CONSTANTS

if TYPE_CHECKING:  # the tables need mujoco; the lumped drive does not
    from mechanism.kinematics.linkage import LinkageTables


@dataclass(frozen=True)
class MotorConstants:
    resistance_ohm: float
    torque_constant_Nm_per_A: float
    back_emf_V_s_per_rad: float
    ratio: float  # motor turns per shaft turn

    @property
    def gain_arm(self) -> float:
        """Arm-side stall torque per volt, n Kt / R [Nm/V]."""
        return self.ratio * self.torque_constant_Nm_per_A / self.resistance_ohm

    @property
    def emf_damping_arm(self) -> float:
        """Arm-side back-emf damping n^2 Kt Ke / R [Nm s/rad]."""
        return (
            self.ratio**2
            * self.torque_constant_Nm_per_A
            * self.back_emf_V_s_per_rad
            / self.resistance_ohm
        )


@dataclass(frozen=True)
class DriveNominal:
    """The described machine's drive, as identification, diagnosis and the test bench need
    it: the one seam through which a machine's numbers enter them (bounds, starting values
    and truth ranges all scale from these, never from a particular machine's).

    ``inertia_kgm2`` is the total inertia seen at the described shaft (the motor's, reflected
    through ``ratio``, included); friction is the shaft-side Coulomb level and viscous
    coefficient. ``joint_ratios`` names the other shafts (turns per shaft turn) whose
    periodic residuals the diagnosis looks for; the motor and the shaft are always there.
    """

    motor: MotorConstants
    inertia_kgm2: float
    coulomb_shaft_Nm: float
    viscous_shaft_Nm_s_per_rad: float
    joint_ratios: tuple[tuple[str, float], ...] = ()
    supply_V: float | None = None
    # the machine has a tool that works in fabric (a needle-penetration load can exist)
    tool_in_fabric: bool = True
    zero_meaning: str = "needle top"  # what shaft angle 0 is, for reports
    # The shaft's travel when it rocks between stops (shaft angles [rad], lower first); None
    # for a shaft that turns whole revolutions.
    travel_rad: tuple[float, float] | None = None
    # What the machine's model knows beyond the lumped numbers (None for a drive given by its
    # lumped numbers alone): the linkage tables over a shaft turn (J(theta), J'(theta), the
    # gravity torque G(theta), arm side; mechanism.kinematics.linkage.LinkageTables) and the
    # described roles (shaft joint, zero site) that name the shaft in its MJCF.
    linkage: LinkageTables | None = field(default=None, compare=False, repr=False)
    roles: tuple[str, str] | None = field(default=None, compare=False)
    # the MJCF that the roles name: a drive given by its lumped numbers (no linkage here) still
    # has its machine's model for the multibody baseline
    model_path: str | None = field(default=None, compare=False)

    def __post_init__(self):
        if isinstance(self.joint_ratios, dict):
            object.__setattr__(self, "joint_ratios", tuple(self.joint_ratios.items()))
        if not (self.motor.ratio > 0 and self.inertia_kgm2 > 0):
            raise ValueError("a drive needs a positive motor ratio and a positive inertia")

    @property
    def ratio(self) -> float:
        return self.motor.ratio

    @property
    def inertia_motor_side_kgm2(self) -> float:
        return self.inertia_kgm2 / self.ratio**2

    @property
    def viscous_motor_side(self) -> float:
        """Viscous friction on the motor side; when the description gives none, a tenth of the
        back-emf damping sets its scale."""
        if self.viscous_shaft_Nm_s_per_rad > 0:
            return self.viscous_shaft_Nm_s_per_rad / self.ratio**2
        m = self.motor
        return 0.1 * m.torque_constant_Nm_per_A * m.back_emf_V_s_per_rad / m.resistance_ohm

    @property
    def torque_scale_Nm(self) -> float:
        """The shaft-side torque every torque bound scales with: the Coulomb level, or (when
        the description gives none) the motor's stall torque at 1.5 V."""
        if self.coulomb_shaft_Nm > 0:
            return self.coulomb_shaft_Nm
        return 1.5 * self.motor.gain_arm

    def shafts(self) -> dict[str, float]:
        """Every shaft whose angle a periodic residual can follow: turns per described-shaft turn."""
        out = {"motor": self.ratio, "shaft": 1.0}
        for name, r in self.joint_ratios:
            if abs(r) > 1e-9 and all(abs(abs(r) - abs(v)) > 1e-6 * abs(v) for v in out.values()):
                out[name] = abs(float(r))
        return out

    def scaled(
        self, inertia: float = 1.0, ratio: float | None = None, torque: float = 1.0, **motor
    ) -> "DriveNominal":
        """Another machine of the same kind (tests, benches): inertia and friction scaled,
        another ratio, other motor constants."""
        from dataclasses import replace

        m = replace(self.motor, ratio=ratio or self.motor.ratio, **motor)
        return replace(
            self,
            motor=m,
            inertia_kgm2=self.inertia_kgm2 * inertia,
            linkage=None,
            coulomb_shaft_Nm=self.coulomb_shaft_Nm * torque,
            viscous_shaft_Nm_s_per_rad=self.viscous_shaft_Nm_s_per_rad * torque,
        )


# a lag over stretches of the recording (Signals.lag_filtered) where they add up to less than this
# share of it; beyond it the whole once, shared by every part, costs less
STRETCH_SHARE = 0.6


@dataclass
class Signals:
    """The measured signals that drive the model, plus cached angle functions."""

    time_s: np.ndarray
    voltage_V: np.ndarray
    arm_angle_rad: np.ndarray
    velocity_rad_s: np.ndarray
    dt: float
    ratio: float
    source_index: np.ndarray | None = None  # windows of a long recording: their samples in it
    whole: "Signals | None" = None  # ... and the whole recording's signals
    # a subset (see :meth:`subset`): the signals it was taken from ...
    parent: "Signals | None" = None
    parent_index: np.ndarray | None = None  # ... and its samples there
    # signals advanced by a sensor's delay (see :meth:`advanced`): the logged ones, whose voltage they share
    logged: "Signals | None" = field(default=None, repr=False)
    _cache: dict = field(default_factory=dict, repr=False)
    _memos: dict = field(default_factory=dict, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def memo(self, kind: Hashable, key, compute, keep: int = 16):
        """A small per-kind LRU of derived arrays (lagged voltages, warmth curves), safe for
        the diagnosis's parallel fits; fewer kept for a long recording (memory)."""
        keep = max(2, min(keep, int(4e6 // max(len(self), 1))))
        with self._lock:
            store = self._memos.setdefault(kind, OrderedDict())
            if key in store:
                store.move_to_end(key)
                return store[key]
        value = compute()
        with self._lock:
            store[key] = value
            while len(store) > keep:
                store.popitem(last=False)
        return value

    def __len__(self) -> int:
        return len(self.time_s)

    def subset(self, index: np.ndarray) -> "Signals":
        """These signals at ``index`` only (the windows one part of the segments simulates, laid
        end to end): per-sample work on them shrinks with the part. Everything read from them is
        what these signals give at the same samples: the mid-sample angle, the quantities that
        integrate over the past (:meth:`history`) and the lagged voltage (:meth:`lagged`) come
        from the parent."""
        index = np.asarray(index, dtype=np.int64)
        whole = self.whole if self.whole is not None else self
        source = self.source_index[index] if self.source_index is not None else index
        sub = Signals(
            self.time_s[index],
            self.voltage_V[index],
            self.arm_angle_rad[index],
            self.velocity_rad_s[index],
            self.dt,
            ratio=self.ratio,
            source_index=source,
            whole=whole,
            parent=self,
            parent_index=index,
        )
        sub._cache["mid"] = self.drive_angle_rad[index]
        return sub

    def advanced(self, delay_s: float) -> "Signals":
        """These signals as a sensor that logs ``delay_s`` late hides them: the angle and the
        velocity read ``delay_s`` later (linear interpolation; past the recording's end the
        angle goes on at the last velocity), the voltage as logged. A model with a sensor delay
        drives its position-dependent torques by this angle: with the logged one, a ripple at
        the motor angle would be out of phase by speed times delay (a motor turn at 8 ms and
        800 rad/s). Subsets are the same subset of the advanced whole recording."""
        if not delay_s > 0.0:
            return self
        whole, source = self.whole, self.source_index
        if whole is not None and source is not None:
            return self.memo(
                "advanced", delay_s, lambda: whole.advanced(delay_s).subset(source), keep=4
            )
        return self.memo("advanced", delay_s, lambda: self._advanced_whole(delay_s), keep=4)

    def _advanced_whole(self, delay_s: float) -> "Signals":
        n = len(self)
        if n == 0:
            return self
        shift = delay_s / self.dt
        at = np.arange(n) + shift
        inside = np.minimum(at, n - 1)
        i = np.minimum(inside.astype(np.int64), max(n - 2, 0))
        frac = inside - i
        j = np.minimum(i + 1, n - 1)

        def read(x):
            return x[i] + frac * (x[j] - x[i])

        velocity = read(self.velocity_rad_s)
        angle = read(self.arm_angle_rad) + (at - inside) * self.dt * self.velocity_rad_s[-1]
        return Signals(
            self.time_s, self.voltage_V, angle, velocity, self.dt, ratio=self.ratio, logged=self
        )

    def lagged(self, tau_s: float) -> np.ndarray:
        """The logged voltage behind the winding lag ``tau_s`` (:func:`lagged_voltage`), remembered per time constant."""
        if self.source_index is None:
            if self.logged is not None:
                # the same voltage: its lag is remembered there, for every delay
                return self.logged.lagged(tau_s)
            return self.memo(
                "lagged", tau_s, lambda: lagged_voltage(self.voltage_V, tau_s, self.dt)
            )
        whole = self._whole_of_part()
        return self._on_stretches(
            "lagged",
            tau_s,
            tau_s,
            # not lag_filtered: the whole's lag goes through lagged(), which a delayed sensor's
            # signals share with the logged ones for every delay
            lambda: whole.lagged(tau_s),
            lambda read: lagged_voltage(whole.voltage_V[read], tau_s, self.dt),
        )

    def lag_filtered(self, kind: str, key, tau_s: float, series, lag) -> np.ndarray:
        """``lag(series(whole))`` at these samples, remembered per ``key``: ``lag`` a causal filter
        whose memory is a first-order lag ``tau_s`` (:meth:`_on_stretches`), ``series`` the signal it
        filters, from the whole recording's signals."""
        if self.source_index is None:
            return self.memo(kind, key, lambda: lag(series(self)))
        whole = self._whole_of_part()
        return self._on_stretches(
            kind,
            key,
            tau_s,
            lambda: whole.lag_filtered(kind, key, tau_s, series, lag),
            lambda read: lag(series(whole)[read]),
        )

    def _whole_of_part(self) -> "Signals":
        """The whole recording's signals these (a part of it: ``source_index`` set) were read from."""
        if self.whole is None or self.source_index is None:
            raise ValueError("these signals are the whole recording, not a part of it")
        return self.whole

    def _on_stretches(self, kind: str, key, tau_s: float, on_whole, on_read) -> np.ndarray:
        """A lag filter ``tau_s`` at these samples (a part of the whole recording): ``on_read(read)``
        filters the whole recording's samples ``read``. A first-order lag forgets where it started
        after :data:`~mechanism.tolerances.LAG_MEMORY_TIME_CONSTANTS` time constants, so where these
        samples are a small part of the recording (the windows of a part of the segments) it runs
        only over stretches around them, each started that many time constants early: the same
        values to a double's rounding, for a fraction of the work (a fit changes the time constant
        at every step). Otherwise ``on_whole()`` (the whole recording, shared by every part)."""
        lead = int(math.ceil(LAG_MEMORY_TIME_CONSTANTS * max(tau_s, 0.0) / self.dt)) + 1
        stretches = self._stretches(lead)
        if stretches is None:
            return self.memo(kind, key, lambda: on_whole()[self.source_index])
        read, at = stretches
        return self.memo(kind, key, lambda: on_read(read)[at])

    def _stretches(self, lead: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The whole recording's samples to filter for these signals' samples: each contiguous run
        of them with the ``lead`` samples before it, laid end to end (before the recording's start,
        its first sample again: the filters start at rest there); and where these samples are
        among them. None where that is most of the recording."""
        whole = self._whole_of_part()
        if "runs" not in self._cache:
            index = self.source_index
            assert index is not None
            breaks = np.flatnonzero(np.diff(index) != 1) + 1
            first = index[np.r_[0, breaks]] if len(index) else index
            count = np.diff(np.r_[0, breaks, len(index)]) if len(index) else first
            self._cache["runs"] = (first, count)
        first, count = self._cache["runs"]
        if not len(first) or len(first) * lead + len(self) > STRETCH_SHARE * len(whole):
            return None

        def lay_out():
            length = count + lead
            ends = np.cumsum(length)
            read = np.repeat(first - lead - (ends - length), length) + np.arange(ends[-1])
            # each run's own samples are the last ``count`` of its stretch
            at = np.repeat(ends - count - (np.cumsum(count) - count), count) + np.arange(len(self))
            return np.maximum(read, 0), at

        return self.memo("stretches", lead, lay_out, keep=4)

    def history(self, kind: str, key, compute):
        """A quantity that integrates over the recording's past (warmth, copper temperature, a
        changed voltage behind the winding lag): ``compute(signals)`` on the whole recording,
        remembered per ``key``, read at these samples."""
        if self.parent is not None:
            return self.memo(
                kind, key, lambda: self.parent.history(kind, key, compute)[self.parent_index]
            )
        if self.whole is None:
            return self.memo(kind, key, lambda: compute(self))
        return self.memo(kind, key, lambda: compute(self.whole)[self.source_index])

    @property
    def drive_angle_rad(self) -> np.ndarray:
        """The arm angle in the middle of each sample interval: position-dependent torques
        held over a step are evaluated there, which makes the step second-order accurate."""
        if "mid" not in self._cache:
            a = self.arm_angle_rad
            mid = np.empty_like(a)
            mid[:-1] = 0.5 * (a[1:] + a[:-1])
            mid[-1] = a[-1] + 0.5 * (a[-1] - a[-2]) if len(a) > 1 else a[-1]
            self._cache["mid"] = mid
        return self._cache["mid"]

    PERIODIC_GRID = 2048

    def periodic(self, values_on_grid: np.ndarray) -> np.ndarray:
        """A function of the arm angle given on ``periodic_grid()``, at every drive angle
        (linear interpolation; much cheaper than evaluating trigonometry per sample)."""
        if "phase_index" not in self._cache:
            x = np.mod(self.drive_angle_rad, 2 * np.pi) * (self.PERIODIC_GRID / (2 * np.pi))
            i = np.minimum(x.astype(np.int64), self.PERIODIC_GRID - 1)
            self._cache["phase_index"] = (i, x - i)
        i, frac = self._cache["phase_index"]
        table = np.append(values_on_grid, values_on_grid[0])
        return table[i] + frac * (table[i + 1] - table[i])

    @classmethod
    def periodic_grid(cls) -> np.ndarray:
        return np.arange(cls.PERIODIC_GRID) * (2 * np.pi / cls.PERIODIC_GRID)

    # whole orders up to this are powers of exp(i angle) (below); beyond, or fractional, trigonometry
    MAX_POWER_ORDER = 4096

    def harmonic(self, order: float, kind: str) -> np.ndarray:
        """cos/sin(order * drive angle), cached (orders 8k are motor-angle harmonics).

        A whole order is a power of exp(i angle), by squaring: a few complex products per sample
        instead of trigonometry of order * angle, which over a long run is a large argument
        (1e6 rad at the 192nd order) that numpy reduces slowly and that rounding has already
        moved by 1e-10 rad; the power's phase error is order * 1e-16."""
        key = (order, kind)
        if key not in self._cache:
            whole = float(order).is_integer() and 0 < abs(order) <= self.MAX_POWER_ORDER
            if whole:
                z = self._power(abs(int(order)))
                self._cache[(order, "cos")] = z.real.copy()
                self._cache[(order, "sin")] = np.copysign(1.0, order) * z.imag
            else:
                fn = np.cos if kind == "cos" else np.sin
                self._cache[key] = fn(order * self.drive_angle_rad)
        return self._cache[key]

    def _power(self, n: int) -> np.ndarray:
        """exp(i n angle) at the drive angles, by squaring the cached exp(i angle) (the squares
        are not kept: a dozen complex products cost less than the memory of a long recording)."""
        if "unit" not in self._cache:
            angle = self.drive_angle_rad
            self._cache["unit"] = np.cos(angle) + 1j * np.sin(angle)
        square = self._cache["unit"]
        while not n & 1:  # up to the lowest set bit (n >= 1)
            square = square * square
            n >>= 1
        result = square
        n >>= 1
        while n:
            square = square * square
            if n & 1:
                result = result * square
            n >>= 1
        return result

    def harmonic_sum(self, orders, cos_amplitudes, sin_amplitudes) -> np.ndarray:
        """sum_k a_k cos(order_k angle) + b_k sin(order_k angle) at every drive angle: one
        product with the stacked harmonics (cached), not a pass over the samples per term."""
        orders = tuple(orders)
        key = ("stacked", orders)
        if key not in self._cache:
            self._cache[key] = np.stack(
                [self.harmonic(order, kind) for order in orders for kind in ("cos", "sin")]
            )
        amplitudes = np.empty(2 * len(orders))
        amplitudes[0::2] = cos_amplitudes
        amplitudes[1::2] = sin_amplitudes
        stacked = self._cache[key]
        # remembered per amplitudes: a finite-difference Jacobian moves one parameter at a time,
        # and its columns that leave these amplitudes alone read the sum again
        return self.memo(
            ("harmonic_sum", orders),
            amplitudes.tobytes(),
            lambda: read_only(amplitudes @ stacked),
        )


def read_only(array: np.ndarray) -> np.ndarray:
    """A remembered array that every reader shares: adding it to a drive's array is fine,
    changing it in place an error."""
    array.flags.writeable = False
    return array


@dataclass
class Drive:
    """Per-sample coefficients of the drive equation (arm side) and scalar options.

    The baseline fills it, each torque effect adds to it, the kernel integrates it.
    """

    voltage_V: np.ndarray  # applied motor voltage
    tau_motor_Nm: np.ndarray  # torque acting on the motor side (arm units), resisting
    tau_arm_Nm: np.ndarray  # position-dependent torque on the arm, resisting
    coulomb_Nm: np.ndarray  # kinetic friction level (>= 0)
    static_excess_Nm: np.ndarray  # static minus kinetic friction (Stribeck)
    # viscous friction (arm units; on the motor where a belt separates motor and arm)
    viscous_Nm_s: np.ndarray
    inertia_kgm2: np.ndarray  # arm-side inertia, may vary with angle
    quadratic_Nm_s2: np.ndarray  # coefficient of w^2 (1/2 dJ/dtheta)
    stribeck_velocity_rad_s: float = 1.0
    stribeck_exponent: float = 1.0
    belt_stiffness_Nm_rad: float = 0.0  # 0 = rigid belt
    belt_damping_Nm_s: float = 0.0
    motor_inertia_kgm2: float = 0.0  # motor-side share of the inertia (arm units), belt mode
    belt_gap_rad: float = 0.0  # half the belt's free play (backlash), belt mode

    def per_sample(self) -> tuple[np.ndarray, ...]:
        """The per-sample arrays in the kernel's argument order (lumped.c): voltage, motor-side
        and arm-side torques, Coulomb, static excess, viscous, inertia, quadratic."""
        return (
            self.voltage_V,
            self.tau_motor_Nm,
            self.tau_arm_Nm,
            self.coulomb_Nm,
            self.static_excess_Nm,
            self.viscous_Nm_s,
            self.inertia_kgm2,
            self.quadratic_Nm_s2,
        )

    @classmethod
    def constant(
        cls, signals: Signals, voltage: np.ndarray, inertia: float, viscous: float, coulomb: float
    ) -> "Drive":
        n = len(signals)
        return cls(
            voltage_V=np.asarray(voltage, dtype=float),  # shared, never modified in place
            tau_motor_Nm=np.zeros(n),
            tau_arm_Nm=np.zeros(n),
            coulomb_Nm=np.full(n, coulomb),
            static_excess_Nm=np.zeros(n),
            viscous_Nm_s=np.full(n, viscous),
            inertia_kgm2=np.full(n, inertia),
            quadratic_Nm_s2=np.zeros(n),
        )


@dataclass(frozen=True)
class Segments:
    """Simulation windows (multiple shooting): each starts from the measured velocity at
    ``starts`` and runs ``length`` samples; ``score`` is the slice of each window whose
    residual counts (the windows' scored parts tile the recording)."""

    starts: np.ndarray  # window start sample
    length: int
    score_begin: np.ndarray  # scored part, offsets inside the window
    score_end: np.ndarray
    is_fit: np.ndarray  # bool: fit (True) or validation (False) segment

    def __len__(self) -> int:
        return len(self.starts)

    def subset(self, mask: np.ndarray) -> "Segments":
        return Segments(
            self.starts[mask],
            self.length,
            self.score_begin[mask],
            self.score_end[mask],
            self.is_fit[mask],
        )

    def window_indices(self) -> np.ndarray:
        """(n_segments, length) recording sample indices of every window sample."""
        return self.starts[:, None] + np.arange(self.length)[None, :]


def make_segments(
    n_samples: int, dt: float, segment_s: float = 1.0, burn_in_s: float = 0.25, pad: int = 10
) -> Segments:
    """Tile the recording into scored segments of ``segment_s``; each window starts
    ``burn_in_s`` (plus the differentiator's half window ``pad``) earlier so that the
    restart from the measured velocity has died out before scoring begins. Segments
    alternate fit / validation in pairs (fit, val, val, fit, fit, val, ...) so that both
    parts see every voltage level, every transient and the whole warm-up."""
    duration = n_samples * dt
    segment_s = min(segment_s, duration / 4)
    score = max(int(round(segment_s / dt)), 2 * pad + 2)
    burn = int(round(burn_in_s / dt)) + pad
    length = min(n_samples, score + burn + pad)
    begins = np.arange(0, n_samples, score)
    if n_samples - begins[-1] < score // 2 and len(begins) > 1:
        begins = begins[:-1]
    ends = np.append(begins[1:], n_samples)
    length = min(n_samples, max(length, int((ends - begins).max()) + burn + pad))
    starts = np.clip(begins - burn, 0, n_samples - length)
    pattern = np.array([True, False, False, True])
    is_fit = pattern[np.arange(len(begins)) % 4]
    # every scored sample has the differentiator's full support inside its window (the
    # recording's first and last ``pad`` samples are not scored)
    score_begin = np.maximum(begins - starts, pad)
    score_end = np.minimum(ends - starts, length - pad)
    return Segments(
        starts.astype(np.int64),
        int(length),
        score_begin.astype(np.int64),
        score_end.astype(np.int64),
        is_fit,
    )


class _DriveParams(ctypes.Structure):
    _fields_ = [
        ("gain", ctypes.c_double),
        ("c_emf", ctypes.c_double),
        ("ws", ctypes.c_double),
        ("delta", ctypes.c_double),
        ("k_belt", ctypes.c_double),
        ("c_belt", ctypes.c_double),
        ("j_motor", ctypes.c_double),
        ("dt", ctypes.c_double),
        ("substeps", ctypes.c_int),
        ("gap", ctypes.c_double),
    ]


@functools.lru_cache(maxsize=None)
def _kernel():
    from mechanism import native

    lib = native.load("lumped")
    if lib is None:
        return None
    fn = lib.simulate_segments
    # arrays go by address (``ndarray.ctypes.data``): building a typed pointer per array
    # (``data_as``) cost a tenth of the kernel's own time on the diagnosis's short segments
    p = ctypes.c_void_p
    fn.argtypes = [ctypes.POINTER(_DriveParams)] + [p] * 8 + [ctypes.c_int, p, p, p, p, p]
    fn.restype = None
    return fn


@functools.lru_cache(maxsize=None)
def _signal_kernels():
    """The compiled trapezoid integral and windowed filter (lumped.c), or None."""
    from mechanism import native

    lib = native.load("lumped")
    if lib is None:
        return None
    p = ctypes.c_void_p  # by address, as the kernel's arrays
    integrate, dot = lib.angle_from_velocity, lib.windowed_dot
    integrate.argtypes = [p, ctypes.c_int, ctypes.c_int, ctypes.c_double, p, p]
    dot.argtypes = [p, ctypes.c_int, p, p, ctypes.c_int, p]
    integrate.restype = dot.restype = None
    return integrate, dot


def angle_from_velocity(w: np.ndarray, dt: float, start_angle: np.ndarray) -> np.ndarray:
    """Angle [rad] of each segment (rows of ``w``) by trapezoids from its start angle."""
    w = np.ascontiguousarray(w, dtype=np.float64)
    start = np.ascontiguousarray(start_angle, dtype=np.float64)
    angle = np.empty_like(w)
    kernels = _signal_kernels()
    if kernels is not None:
        kernels[0](w.ctypes.data, w.shape[0], w.shape[1], dt, start.ctypes.data, angle.ctypes.data)
        return angle
    # a0 + dt * cumsum(0.5 * (w[1:] + w[:-1])), in place
    angle[:, 0] = 0.0
    steps = angle[:, 1:]
    np.add(w[:, 1:], w[:, :-1], out=steps)
    steps *= 0.5
    np.cumsum(steps, axis=1, out=steps)
    angle *= dt
    angle += start[:, None]
    return angle


def windowed_dot(x: np.ndarray, first: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """``x.ravel()[first[j] + k] @ coefficients`` for every j: a filter (the velocity
    differentiator) evaluated only at the samples whose windows start at ``first``."""
    x = np.ascontiguousarray(x, dtype=np.float64).ravel()
    first = np.ascontiguousarray(first, dtype=np.int64)
    c = np.ascontiguousarray(coefficients, dtype=np.float64)
    if len(first) and (first.min() < 0 or first.max() + len(c) > len(x)):
        # the compiled loop reads without checking: a window beyond x is a caller's error
        raise ValueError("a filter window reaches beyond the signal")
    kernels = _signal_kernels()
    if kernels is None:
        return x[first[:, None] + np.arange(len(c))] @ c
    out = np.empty(len(first))
    kernels[1](x.ctypes.data, len(first), first.ctypes.data, c.ctypes.data, len(c), out.ctypes.data)
    return out


# the exponential step is exact for the linear part; more substeps change nothing measurable
SUBSTEPS = 1
# a shaft measured slower than this is at rest: a segment starting so starts stuck, and it does
# not turn for what heats with turning
REST_SPEED_RAD_S = 0.05


def simulate(
    drive: Drive,
    motor: MotorConstants,
    segments: Segments,
    w0: np.ndarray,
    dt: float,
    substeps: int = SUBSTEPS,
    use_native: bool = True,
) -> np.ndarray:
    """Arm velocity [rad/s] at every window sample, shape (n_segments, length)."""
    kernel = _kernel() if use_native else None
    if kernel is None:
        return simulate_numpy(drive, motor, segments, w0, dt, substeps)
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in drive.per_sample()]
    n_seg = len(segments)
    out = np.empty((n_seg, segments.length), dtype=np.float64)
    starts = np.ascontiguousarray(segments.starts, dtype=np.int32)
    lengths = np.full(n_seg, segments.length, dtype=np.int32)
    offsets = (np.arange(n_seg, dtype=np.int32) * segments.length).astype(np.int32)
    w0 = np.ascontiguousarray(w0, dtype=np.float64)
    params = _DriveParams(
        motor.gain_arm,
        motor.emf_damping_arm,
        drive.stribeck_velocity_rad_s,
        drive.stribeck_exponent,
        drive.belt_stiffness_Nm_rad,
        drive.belt_damping_Nm_s,
        drive.motor_inertia_kgm2,
        dt,
        int(substeps),
        drive.belt_gap_rad,
    )
    kernel(
        ctypes.byref(params),
        *[a.ctypes.data for a in arrays],
        n_seg,
        starts.ctypes.data,
        lengths.ctypes.data,
        offsets.ctypes.data,
        w0.ctypes.data,
        out.ctypes.data,
    )
    return out


def _friction(fk, fx, w, drive: Drive):
    if not np.any(fx):
        return fk
    return fk + fx * np.exp(
        -np.power(np.abs(w) / drive.stribeck_velocity_rad_s, drive.stribeck_exponent)
    )


def simulate_numpy(
    drive: Drive,
    motor: MotorConstants,
    segments: Segments,
    w0: np.ndarray,
    dt: float,
    substeps: int = SUBSTEPS,
) -> np.ndarray:
    """The kernel's equations in numpy, vectorised over segments (the fallback)."""
    idx = segments.window_indices()
    n_seg, length = idx.shape
    out = np.empty((n_seg, length))
    gain, c_emf = motor.gain_arm, motor.emf_damping_arm
    u, tm, ta, fk, fx, cv, jt, q = drive.per_sample()
    w = np.array(w0, dtype=float)
    if drive.belt_stiffness_Nm_rad > 0:
        return _simulate_belt_numpy(drive, motor, idx, w, dt, substeps)
    h = dt / substeps
    for i in range(length):
        k = idx[:, i]
        out[:, i] = w
        c = c_emf + cv[k]
        decay = np.exp(-c * h / jt[k])
        decay_half = np.exp(-0.5 * c * h / jt[k])
        drive_torque = gain * u[k] - tm[k] - ta[k]
        for _ in range(substeps):
            f = drive_torque - q[k] * w * w
            at_rest = w == 0.0
            stuck = at_rest & (np.abs(f) <= fk[k] + fx[k])
            direction = np.where(at_rest, np.sign(f), np.sign(w))
            wss = (f - _friction(fk[k], fx[k], w, drive) * direction) / c
            wh = wss + (w - wss) * decay_half
            wh = np.where(np.sign(wh) == -direction, 0.0, wh)
            wss = (
                drive_torque - q[k] * wh * wh - _friction(fk[k], fx[k], wh, drive) * direction
            ) / c
            wn = wss + (w - wss) * decay
            wn = np.where(np.sign(wn) == -direction, 0.0, wn)
            w = np.where(stuck, 0.0, wn)
    return out


def _simulate_belt_numpy(
    drive: Drive, motor: MotorConstants, idx: np.ndarray, w: np.ndarray, dt: float, substeps: int
) -> np.ndarray:
    n_seg, length = idx.shape
    out = np.empty((n_seg, length))
    gain, c_emf = motor.gain_arm, motor.emf_damping_arm
    jm, kb, cb = drive.motor_inertia_kgm2, drive.belt_stiffness_Nm_rad, drive.belt_damping_Nm_s
    u, tm, ta, fk, fx, cv, jt, q = drive.per_sample()
    k0 = idx[:, 0]
    wr = np.sqrt(kb * (1 / jm + 1 / (jt[k0] - jm)))
    nsub = int(max(substeps, np.ceil(np.max(wr) * dt / 0.25)))
    h = dt / nsub
    wm = w.copy()
    load = ta[k0] + q[k0] * w * w + np.where(w != 0, fk[k0] * np.sign(w), 0.0)
    lim = fk[k0] + fx[k0]
    load = np.where(w == 0, np.clip(gain * u[k0] - tm[k0], -lim, lim), load)
    gap = drive.belt_gap_rad
    x = load / kb + gap * np.sign(load)
    for i in range(length):
        k = idx[:, i]
        out[:, i] = w
        ja = jt[k] - jm
        for _ in range(nsub):
            fb = np.where(np.abs(x) > gap, kb * (x - gap * np.sign(x)) + cb * (wm - w), 0.0)
            wm = wm + h * (gain * u[k] - (c_emf + cv[k]) * wm - tm[k] - fb) / jm
            f = fb - ta[k] - q[k] * w * w
            at_rest = w == 0.0
            stuck = at_rest & (np.abs(f) <= fk[k] + fx[k])
            direction = np.where(at_rest, np.sign(f), np.sign(w))
            f = f - _friction(fk[k], fx[k], w, drive) * direction
            wn = w + h * f / ja
            wn = np.where(np.sign(wn) == -direction, 0.0, wn)
            w = np.where(stuck, 0.0, wn)
            x = x + h * (wm - w)
    return out


def lagged_voltage(voltage: np.ndarray, tau_s: float, dt: float) -> np.ndarray:
    """The voltage behind a first-order lag ``tau_s`` (the winding's L/R), averaged over
    each sample interval (the kernel holds it over the step). Exact for a voltage held
    between samples."""
    from scipy.signal import lfilter

    if tau_s <= 0.02 * dt:
        return voltage
    a = math.exp(-dt / tau_s)
    # state at the start of each interval: x[k+1] = a x[k] + (1 - a) u[k], x[0] = u[0]
    start = lfilter([0.0, 1.0 - a], [1.0, -a], voltage - voltage[0]) + voltage[0]
    weight = tau_s / dt * (1.0 - a)  # interval average = u + (x - u) * weight
    return voltage + (start - voltage) * weight
