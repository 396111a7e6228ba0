"""Generic fallback models: what the diagnosis fits when the library leaves a residual well
above the noise floor. They name no mechanism (``generic = True``, the family in the name);
their shapes come from the residual's signature (:mod:`mechanism.sysid.residual`):

- ``generic_shaft_torque``: a Fourier torque of the detected orders of the detected shaft;
- ``generic_speed_friction``: a friction level that is a smooth (piecewise-linear) function
  of speed;
- ``generic_change``: Coulomb and viscous friction and the torque gain change at one
  instant (a smooth step);
- ``generic_saturation``: the motor's torque stops following the voltage beyond a level (the
  motor current clipped), in hard accelerations and braking;
- ``generic_dead_zone``: the winding loses a constant voltage in the direction of the current
  (a brush drop, a driver's dead time);
- ``generic_voltage_limit``: the voltage reaching the motor clipped at a level;
- ``generic_input_delay``: the voltage acting a fixed time late;
- ``generic_drive_loss``: the voltage lost in short intervals located from the residual (a
  supply dropping out);
- ``generic_mode``: the angle sensor on a part that rocks against a spring (a housing on soft
  feet), set ringing by the drive's acceleration;
- ``generic_shaft_torque`` of a shaft the description does not name, at the ratio the
  residual's order spectrum shows (:func:`mechanism.sysid.residual.unnamed_shaft_ratio`).

Accepted by the same validation rule as library effects.
"""

from __future__ import annotations

from typing import Sequence


import numpy as np

from mechanism.dynamics.lumped import DriveNominal, Signals
from mechanism.files.tables import true_runs
from mechanism.sysid.effects import WHOLE_BASELINE, Effect, _amplitude
from mechanism.sysid.parameters import Parameter
from mechanism.sysid.residual import UNNAMED_SHAFT, Signature


class GenericEffect(Effect):
    """A fallback family: no mechanism named, so its evidence describes the fitted shape in words."""

    generic = True

    def words(self, v: dict[str, float]) -> str:
        raise NotImplementedError


class GenericShaftTorque(GenericEffect):
    name = "generic_shaft_torque"
    physics = (
        "an unbalanced or eccentric part on that shaft, a cam or a mechanism it drives, a damaged gear tooth or "
        "bearing race: a torque that repeats with the shaft's angle"
    )
    enters = "torque"
    all_linear = True
    feature = "residual"

    def __init__(self, nominal: DriveNominal, shaft: str, ratio: float, orders: list[int]):
        self.shaft, self.ratio, self.orders = (
            shaft,
            float(ratio),
            sorted(set(int(k) for k in orders)),
        )
        super().__init__(nominal)
        self.meaning = (
            f"a torque periodic in the {shaft.replace('_', ' ')} angle ({ratio:g} turns per shaft turn), "
            f"orders {', '.join(map(str, self.orders))}, constant in speed: a Fourier series with free phases"
        )

    def make_parameters(self, nominal):
        # up to ~3x the Coulomb level at the shaft
        bound = 25 / 9 * nominal.torque_scale_Nm / self.ratio
        return tuple(
            p
            for k in self.orders
            for p in (
                Parameter(
                    f"generic_{self.shaft}_order{k}_cos_Nm",
                    0.0,
                    -bound,
                    bound,
                    f"{self.shaft}-side torque {k}x per turn, cosine",
                    scale=bound / 25,
                ),
                Parameter(
                    f"generic_{self.shaft}_order{k}_sin_Nm",
                    0.0,
                    -bound,
                    bound,
                    f"{self.shaft}-side torque {k}x per turn, sine",
                    scale=bound / 25,
                ),
            )
        )

    def apply(self, v, s, drive):
        torque = s.harmonic_sum(
            [k * self.ratio for k in self.orders],
            [v[f"generic_{self.shaft}_order{k}_cos_Nm"] for k in self.orders],
            [v[f"generic_{self.shaft}_order{k}_sin_Nm"] for k in self.orders],
        )
        # virtual work: a torque on a shaft turning ``ratio`` times faster acts ``ratio`` times on the described shaft
        if self.shaft == "motor":
            drive.tau_motor_Nm += self.ratio * torque
        else:
            drive.tau_arm_Nm += self.ratio * torque

    def words(self, v) -> str:
        amps = {
            k: _amplitude(
                v, f"generic_{self.shaft}_order{k}_cos_Nm", f"generic_{self.shaft}_order{k}_sin_Nm"
            )[0]
            for k in self.orders
        }
        main = max(amps, key=amps.__getitem__)
        if self.shaft == UNNAMED_SHAFT:
            return (
                f"a generic torque periodic in the angle of a shaft turning {self.ratio:.4g} times per turn "
                f"of the described shaft, which the description does not name ({amps[main]:.2g} N m at order {main})"
            )
        return (
            f"a generic {self.shaft.replace('_', ' ')}-angle torque of order{'s' if len(self.orders) > 1 else ''} "
            f"{', '.join(map(str, self.orders))} ({amps[main]:.2g} N m at order {main})"
        )


class GenericSpeedFriction(GenericEffect):
    name = "generic_speed_friction"
    physics = (
        "a friction of another speed dependence than the library's: a lubricant film (a Stribeck curve of another "
        "shape), a fan, pump or air drag growing with speed, eddy-current drag, a seal"
    )
    enters = "friction"
    all_linear = True
    feature = "residual"
    meaning = (
        "a friction level that varies smoothly with speed (piecewise linear between speed knots)"
    )
    KNOTS = (0.0, 0.05, 0.15, 0.35, 0.65, 1.0)  # fractions of the top speed

    def __init__(self, nominal: DriveNominal, top_speed_rad_s: float):
        self.top = max(float(top_speed_rad_s), 1e-3)
        super().__init__(nominal)

    def make_parameters(self, nominal):
        t = nominal.torque_scale_Nm
        return tuple(
            Parameter(
                f"friction_at_speed{i}_Nm",
                0.0,
                -t,
                25 / 9 * t,
                f"change of the friction level at {100 * f:.0f}% of top speed",
                scale=t / 9,
            )
            for i, f in enumerate(self.KNOTS)
        )

    def basis(self, s: Signals) -> np.ndarray:
        def compute():
            x = np.clip(np.abs(s.velocity_rad_s) / self.top, 0.0, 1.0)
            knots = np.array(self.KNOTS)
            return np.stack([np.interp(x, knots, np.eye(len(knots))[i]) for i in range(len(knots))])

        return s.memo("speed_basis", self.top, compute)

    def apply(self, v, s, drive):
        b = self.basis(s)
        drive.coulomb_Nm += sum(
            v[f"friction_at_speed{i}_Nm"] * b[i] for i in range(len(self.KNOTS))
        )
        np.maximum(drive.coulomb_Nm, 0.0, out=drive.coulomb_Nm)

    def words(self, v) -> str:
        values = [v[f"friction_at_speed{i}_Nm"] for i in range(len(self.KNOTS))]
        return (
            f"a generic speed-dependent friction ({values[0]:+.2g} N m at rest, {values[2]:+.2g} N m at "
            f"{100 * self.KNOTS[2]:.0f}% and {values[-1]:+.2g} N m at top speed)"
        )


class GenericChange(GenericEffect):
    name = "generic_change"
    physics = (
        "something that changed at one instant: a supply dropout or a current limit engaging, a belt or clutch "
        "starting to slip, a part working loose, a load added or removed"
    )
    enters = "voltage"
    linear = ("coulomb_change_fraction", "viscous_change_fraction", "gain_change_fraction")
    feature = "residual"
    meaning = "Coulomb and viscous friction and the motor's torque gain change at one instant (a 50 ms step)"
    WIDTH_S = 0.05

    def __init__(self, nominal: DriveNominal, t_change_s: float, duration_s: float):
        self.t0, self.duration = float(t_change_s), float(duration_s)
        super().__init__(nominal)

    def make_parameters(self, nominal):
        return (
            Parameter(
                "change_time_s", self.t0, 0.0, self.duration, "when the change happens", scale=1.0
            ),
            Parameter(
                "coulomb_change_fraction",
                0.0,
                -0.9,
                3.0,
                "relative change of the Coulomb level",
                scale=0.2,
            ),
            Parameter(
                "viscous_change_fraction",
                0.0,
                -0.9,
                3.0,
                "relative change of the viscous friction",
                scale=0.5,
            ),
            Parameter(
                "gain_change_fraction",
                0.0,
                -0.5,
                0.5,
                "relative change of the torque per volt",
                scale=0.05,
            ),
        )

    def step(self, v, s):
        t0 = v["change_time_s"]
        return s.memo(
            "change_step", t0, lambda: 0.5 * (1 + np.tanh((s.time_s - t0) / self.WIDTH_S))
        )

    def voltage(self, v, s, u):
        return u * (1.0 + v["gain_change_fraction"] * self.step(v, s))

    def apply(self, v, s, drive):
        h = self.step(v, s)
        drive.coulomb_Nm *= 1.0 + v["coulomb_change_fraction"] * h
        drive.viscous_Nm_s *= 1.0 + v["viscous_change_fraction"] * h
        np.maximum(drive.coulomb_Nm, 0.0, out=drive.coulomb_Nm)
        np.maximum(drive.viscous_Nm_s, 0.0, out=drive.viscous_Nm_s)

    def grid(self, s, located):
        return [
            {"change_time_s": min(max(self.t0 + dt, 0.0), self.duration)} for dt in (-0.5, 0.0, 0.5)
        ]

    def words(self, v) -> str:
        return (
            f"a generic change at t = {v['change_time_s']:.1f} s (Coulomb {100 * v['coulomb_change_fraction']:+.0f}%, viscous "
            f"{100 * v['viscous_change_fraction']:+.0f}%, torque per volt {100 * v['gain_change_fraction']:+.0f}%)"
        )


class GenericSaturation(GenericEffect):
    name = "generic_saturation"
    physics = (
        "a drive that limits the motor current (a current-limited amplifier, a supply that folds back under "
        "load, a driver's protection), or a transmission that slips beyond a torque (a pulley loose on its shaft, "
        "a slipping belt or clutch): the torque stops following the voltage in hard accelerations and braking"
    )
    enters = "torque"
    feature = "residual"
    restarts_baseline = WHOLE_BASELINE
    meaning = (
        "the motor's torque clipped at a level (its current at the logged voltage and measured speed, "
        "(U - Ke n w) / R, limited to +/- a maximum current)"
    )

    def __init__(self, nominal: DriveNominal, peak_current_A: float):
        # no clipping at or above the largest current the recording can draw: the null
        self.peak = max(float(peak_current_A), 1e-6)
        super().__init__(nominal)

    def make_parameters(self, nominal):
        return (
            Parameter(
                "current_limit_A",
                self.peak,
                0.02 * self.peak,
                self.peak,
                "the largest current the drive lets through",
                log=True,
            ),
        )

    def null(self):
        return {"current_limit_A": self.peak}

    def starts(self, s, located):
        return [{"current_limit_A": f * self.peak} for f in (0.1, 0.2, 0.35, 0.5, 0.7)]

    def apply(self, v, s, drive):
        if v["current_limit_A"] >= self.peak:
            return  # the null: the model it extends, exactly
        m = self.nominal.motor
        # the motor's torque at the measured speed (arm side), n Kt i: what the limit cuts off is
        # resisting torque at the motor (the kernel still applies the unclipped one)
        torque = m.gain_arm * drive.voltage_V - m.emf_damping_arm * s.velocity_rad_s
        limit = m.ratio * m.torque_constant_Nm_per_A * v["current_limit_A"]
        drive.tau_motor_Nm += torque - np.clip(torque, -limit, limit)

    def words(self, v) -> str:
        return (
            f"a generic saturation of the motor's torque at a current of {v['current_limit_A']:.3g} A "
            f"({100 * v['current_limit_A'] / self.peak:.0f}% of the largest the recording could draw)"
        )


class GenericDeadZone(GenericEffect):
    name = "generic_dead_zone"
    physics = (
        "brushes, a diode or a driver's output stage that take a constant voltage whichever way the current "
        "flows (a brush drop), a driver's dead time: no current until the voltage across the winding passes a level"
    )
    enters = "voltage"
    feature = "residual"
    meaning = (
        "the voltage reaching the winding loses a constant level in the direction of the current (the logged "
        "voltage against the back-emf at the measured speed): a dead zone of the current, braking included"
    )

    def __init__(self, nominal: DriveNominal, top_voltage_V: float):
        # the levels the recording drives at bound the zone: its evidence quotes no other
        self.top = max(float(top_voltage_V), 1e-3)
        super().__init__(nominal)

    def make_parameters(self, nominal):
        return (
            Parameter(
                "dead_zone_V",
                0.0,
                0.0,
                0.3 * self.top,
                "voltage lost in the direction of the current",
                scale=0.02 * self.top,
            ),
        )

    def starts(self, s, located):
        return [{"dead_zone_V": f * self.top} for f in (0.02, 0.05, 0.1)]

    def voltage(self, v, s, u):
        zone = v["dead_zone_V"]
        if zone <= 0.0:
            return u  # the null: the model it extends, exactly
        m = self.nominal.motor
        across = u - m.back_emf_V_s_per_rad * m.ratio * s.velocity_rad_s
        return u - np.clip(across, -zone, zone)

    def words(self, v) -> str:
        return (
            f"a generic dead zone of {v['dead_zone_V']:.2g} V in the direction of the current "
            f"({100 * v['dead_zone_V'] / self.top:.0f}% of the {self.top:.3g} V the recording drives at most)"
        )


class GenericVoltageLimit(GenericEffect):
    name = "generic_voltage_limit"
    physics = (
        "a supply or driver that cannot give more than a voltage (a supply at its limit, a PWM at its largest "
        "duty, a battery that sags): above it the motor no longer follows the command"
    )
    enters = "voltage"
    feature = "residual"
    meaning = "the voltage reaching the motor clipped at a level (the logged one up to it)"
    # a baseline without it lowers its torque per volt and friction to mimic it
    restarts_baseline = WHOLE_BASELINE

    def __init__(self, nominal: DriveNominal, top_voltage_V: float):
        # no clipping at or above the largest voltage the recording drives at: the null
        self.top = max(float(top_voltage_V), 1e-3)
        super().__init__(nominal)

    def make_parameters(self, nominal):
        return (
            Parameter(
                "voltage_limit_V",
                self.top,
                0.2 * self.top,
                self.top,
                "the largest voltage that reaches the motor",
                scale=0.05 * self.top,
            ),
        )

    def null(self):
        return {"voltage_limit_V": self.top}

    def starts(self, s, located):
        return [{"voltage_limit_V": f * self.top} for f in (0.5, 0.7, 0.85)]

    def voltage(self, v, s, u):
        limit = v["voltage_limit_V"]
        return u if limit >= self.top else np.clip(u, -limit, limit)

    def words(self, v) -> str:
        return (
            f"a generic limit of the voltage reaching the motor at {v['voltage_limit_V']:.3g} V "
            f"(the recording commands up to {self.top:.3g} V)"
        )


class GenericInputDelay(GenericEffect):
    name = "generic_input_delay"
    physics = (
        "a driver or controller that applies the command late (a transport delay in its loop, a PWM updated "
        "once per period, a bus that buffers the command), or a log whose voltage is stamped early"
    )
    enters = "voltage"
    feature = "residual"
    meaning = "the logged voltage reaches the motor a fixed time later (a pure delay, beside the winding's lag)"
    LONGEST_S = 0.05

    def make_parameters(self, nominal):
        return (
            Parameter(
                "input_delay_s",
                0.0,
                0.0,
                self.LONGEST_S,
                "how late the voltage acts",
                scale=0.002,
            ),
        )

    def starts(self, s, located):
        return [{"input_delay_s": d} for d in (0.002, 0.005, 0.015)]

    def voltage(self, v, s, u):
        delay = v["input_delay_s"]
        if delay <= 0.0:
            return u
        # the voltage as logged before the recording's start: its first sample
        return np.interp(s.time_s - delay, s.time_s, u, left=u[0])

    def words(self, v) -> str:
        return f"a generic delay of {1e3 * v['input_delay_s']:.3g} ms before the voltage acts"


class GenericDriveLoss(GenericEffect):
    name = "generic_drive_loss"
    physics = (
        "supply dropouts, a loose connector or a brush lifting off the commutator, a driver's protection "
        "tripping for a moment: the motor loses its voltage briefly while the log keeps the commanded one"
    )
    enters = "voltage"
    feature = "residual"
    meaning = (
        "the voltage reaching the motor falls by a fraction in short intervals where the shaft decelerated as if "
        "its drive were gone (located from the residual)"
    )

    def __init__(self, nominal: DriveNominal, intervals_s: list[tuple[float, float]]):
        self.intervals = [(float(a), float(b)) for a, b in intervals_s]
        super().__init__(nominal)

    def make_parameters(self, nominal):
        return (
            Parameter(
                "drive_lost_fraction",
                0.0,
                0.0,
                1.0,
                "share of the logged voltage that does not reach the motor in the intervals",
                scale=0.1,
            ),
        )

    def starts(self, s, located):
        return [{"drive_lost_fraction": f} for f in (0.5, 1.0)]

    def mask(self, s: Signals) -> np.ndarray:
        def compute():
            begins = np.array([a for a, _ in self.intervals])
            ends = np.array([b for _, b in self.intervals])
            i = np.searchsorted(begins, s.time_s, side="right") - 1
            return (i >= 0) & (s.time_s < ends[np.maximum(i, 0)])

        return s.memo("drive_loss_mask", tuple(self.intervals), compute)

    def voltage(self, v, s, u):
        lost = v["drive_lost_fraction"]
        if lost <= 0.0 or not self.intervals:
            return u
        return u * (1.0 - lost * self.mask(s))

    def words(self, v) -> str:
        lengths = [1e3 * (b - a) for a, b in self.intervals]
        return (
            f"a generic loss of {100 * v['drive_lost_fraction']:.0f}% of the drive in {len(lengths)} short "
            f"interval{'s' if len(lengths) != 1 else ''} ({sum(lengths):.0f} ms in all, the longest "
            f"{max(lengths):.0f} ms, the first at t = {self.intervals[0][0]:.2f} s)"
        )


class GenericMode(GenericEffect):
    name = "generic_mode"
    physics = (
        "a housing or base that rocks on soft feet, a flexible mount of the motor or of the angle sensor: "
        "something compliant between the sensor and the ground, which the drive's own torque sets ringing"
    )
    enters = "measurement"
    feature = "residual"
    meaning = (
        "the angle sensor sits on a part that rocks against a spring (a second-order mode of its own frequency "
        "and damping), driven by the reaction of the drive's acceleration: measured = simulated + r L[theta''], "
        "L = 1 / (s^2 + 2 zeta w s + w^2), r the drive's inertia over the rocking part's"
    )
    # a stiff mode (or none) is the null: the ratio at zero
    LOW_HZ, HIGH_HZ = 1.0, 100.0

    def make_parameters(self, nominal):
        return (
            Parameter(
                "mode_frequency_Hz",
                10.0,
                self.LOW_HZ,
                self.HIGH_HZ,
                "the mode's frequency",
                log=True,
            ),
            Parameter("mode_damping_ratio", 0.1, 0.01, 1.0, "the mode's damping ratio", log=True),
            Parameter(
                "mode_inertia_ratio",
                0.0,
                0.0,
                2.0,
                "the drive's inertia over that of the part that rocks",
                scale=0.05,
            ),
        )

    def starts(self, s, located):
        top = min(self.HIGH_HZ, 0.45 / s.dt)
        peaks = [f for f in located.resonance_hz if self.LOW_HZ < f < top][:2]
        # the residual's peaks, and an octave grid: away from its frequency the mode's fit has
        # no slope to follow (a start at a wrong peak stayed there, the error unchanged)
        grid = [
            f
            for f in (3.0, 6.0, 12.0, 24.0)
            if f < top and all(abs(f / p - 1) > 0.3 for p in peaks)
        ]
        return [
            {"mode_frequency_Hz": f, "mode_damping_ratio": z, "mode_inertia_ratio": 0.1}
            for f in [*peaks, *grid]
            for z in (0.05, 0.2)
        ]

    def measure(self, v, s, angle):
        ratio = v["mode_inertia_ratio"]
        if ratio <= 0.0:
            return angle
        from scipy.signal import lfilter

        dt = s.dt
        w = 2 * np.pi * v["mode_frequency_Hz"]
        # r / (s^2 + 2 zeta w s + w^2) by the bilinear transform, s = k (1 - 1/z) / (1 + 1/z)
        k, zw = 2.0 / dt, 2 * v["mode_damping_ratio"] * w
        a = np.array([k * k + zw * k + w * w, 2 * (w * w - k * k), k * k - zw * k + w * w])
        b = ratio * np.array([1.0, 2.0, 1.0])
        rows = np.atleast_2d(angle)
        # the acceleration of each window's simulated angle (its ends repeat their neighbours);
        # each window starts the mode at rest, which its burn-in lets ring out
        acc = np.empty_like(rows)
        acc[:, 1:-1] = (rows[:, 2:] - 2 * rows[:, 1:-1] + rows[:, :-2]) / (dt * dt)
        acc[:, 0], acc[:, -1] = acc[:, 1], acc[:, -2]
        return (rows + lfilter(b, a, acc, axis=1)).reshape(np.shape(angle))

    def words(self, v) -> str:
        return (
            f"a generic mode at {v['mode_frequency_Hz']:.3g} Hz (damping ratio {v['mode_damping_ratio']:.2g}) that "
            f"the drive's acceleration excites and the angle sensor sees, as if a part {1 / max(v['mode_inertia_ratio'], 1e-9):.3g} "
            f"times the drive's inertia rocked under the sensor"
        )


# a loss of drive: the shaft decelerates by at least this share of what the logged voltage's
# torque would accelerate it by, for at least this long, where the voltage is at least this share
# of the recording's top
LOSS_SHARE, LOSS_MIN_S, LOSS_MIN_VOLTAGE_SHARE = 0.5, 0.01, 0.2


def drive_loss_intervals(
    nominal: DriveNominal,
    time_s: np.ndarray,
    voltage_V: np.ndarray,
    residual: np.ndarray,
    dt: float,
) -> list[tuple[float, float]]:
    """Where the measured shaft decelerated against the model as if the motor had lost its
    voltage. With a share ``l`` of the voltage lost, the measured acceleration falls behind the
    model's by (l G U + c r) / J, ``r`` the velocity residual (measured minus model: the slower
    shaft's back-emf and viscous friction brake it less), G the torque per volt, c the damping:
    ``l`` from the residual and its rate of change, with the described inertia and damping (the
    fitted ones differ by less than the factor-2 margin of the test here)."""
    from mechanism.sysid.recording import smoothed_velocity

    if len(residual) < 100:
        return []
    m = nominal.motor
    inertia = nominal.inertia_motor_side_kgm2 * m.ratio**2
    damping = m.emf_damping_arm + nominal.viscous_motor_side * m.ratio**2
    slope = smoothed_velocity(residual, dt)
    driven = np.abs(voltage_V) >= LOSS_MIN_VOLTAGE_SHARE * max(top_voltage_V(voltage_V), 1e-9)
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(
            driven, -(inertia * slope + damping * residual) / (m.gain_arm * voltage_V), 0.0
        )
    pad = max(int(round(0.002 / dt)), 1)
    return [
        (float(time_s[max(first - pad, 0)]), float(time_s[min(last + 1 + pad, len(time_s) - 1)]))
        for first, last in true_runs(share > LOSS_SHARE)
        if (last + 1 - first) * dt >= LOSS_MIN_S
    ]


def top_voltage_V(voltage_V: np.ndarray) -> float:
    """The largest voltage a recording drives at (its 99th percentile of |U|)."""
    return float(np.percentile(np.abs(voltage_V), 99)) if len(voltage_V) else 0.0


def peak_current_A(nominal: DriveNominal, signals: Signals) -> float:
    """The largest current the described motor draws over the recording (the logged voltage
    against the back-emf at the measured speed)."""
    m = nominal.motor
    emf = m.back_emf_V_s_per_rad * m.ratio * signals.velocity_rad_s
    return float(np.max(np.abs(signals.voltage_V - emf), initial=0.0)) / m.resistance_ohm


def candidates(
    nominal: DriveNominal,
    sig: Signature,
    signals: Signals,
    losses: Sequence[tuple[float, float]] = (),
) -> list[Effect]:
    """The generic families the signature points to (the speed friction, the saturation, the
    dead zone, the voltage limit and the mode always; the input delay where the residual reads
    as a timing error; a loss of drive where ``losses`` located one)."""
    out: list[Effect] = []
    if sig.periodic is not None:
        p = sig.periodic
        out.append(GenericShaftTorque(nominal, p.shaft, p.ratio, p.orders))
    if sig.step_time_s is not None and sig.step_share > 0.3:
        out.append(GenericChange(nominal, sig.step_time_s, float(signals.time_s[-1])))
    out.append(
        GenericSpeedFriction(nominal, float(np.percentile(np.abs(signals.velocity_rad_s), 99)))
    )
    if peak_current_A(nominal, signals) > 0.0:
        out.append(GenericSaturation(nominal, peak_current_A(nominal, signals)))
    if top_voltage_V(signals.voltage_V) > 0.0:
        out.append(GenericDeadZone(nominal, top_voltage_V(signals.voltage_V)))
        out.append(GenericVoltageLimit(nominal, top_voltage_V(signals.voltage_V)))
    if sig.delay_share > 0.3:
        # only where the residual reads as a timing error: beside a library model whose own
        # discretisation is a fraction of a sample off (a free play's contact), a delay of a
        # fraction of a sample also cuts the error, and names nothing real
        out.append(GenericInputDelay(nominal))
    out.append(GenericMode(nominal))
    if losses:
        out.append(GenericDriveLoss(nominal, list(losses)))
    return out


def evidence(
    effect: GenericEffect, values: dict, description: str, before: float, after: float
) -> str:
    gain = 100 * (1 - after / before) if before > 0 else 0.0
    what = effect.words(values)
    return (
        f"Not in the library: {description}; {what} cuts the validation velocity error from {before:.3g} to "
        f"{after:.3g} rad/s ({gain:.0f}% lower). It names no mechanism; possible physics: {effect.physics}."
    )
