"""Needle zigzag: the stepper swings the needle bar sideways, timed against the arm shaft.

The zigzag stepper (a PM25S-048, :mod:`mechanism.steppers`) moves the needle sideways
through a linkage; the needle may only move sideways while its point is above the fabric
(needle-plate top plus a clearance). At a sewing speed of N stitches per minute (arm rpm)
the needle is above the plate for a fixed share of each revolution; a zigzag move that is
still under way when the needle comes back down into the fabric bends the needle or
breaks it on the plate. :func:`check_move` flags such moves; :func:`sew` simulates a run
of zigzag stitches and reports where the needle moved sideways inside the fabric.

The needle height over arm angle is an input (:class:`NeedleProfile`): a function or a
table of ``needle_z_mm`` against arm angle (0 = needle TDC, z from the needle-plate top,
positive up). :meth:`NeedleProfile.slider_crank` gives an analytic stand-in;
:func:`machine_needle_profile` is the one place where the shipped sewing machine's table
plugs in.

Linkage (assumed, the thesis gives none): the needle bar swings linearly with the motor
angle, full width 7 mm in 40 full steps (0.175 mm per 7.5 degree step, about 0.1 mm per
half step, a typical zigzag resolution). The needle bar and its swing frame are reflected
to the motor as an equivalent mass at the needle point (30 g, assumed).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from mechanism.steppers import step_profiles
from mechanism.steppers._drive import StepperKind
from mechanism.steppers._motor import StepperParams, described_step_rate, pm25s048
from mechanism.steppers._simulation import simulate
from mechanism.errors import UserError


@dataclass(frozen=True)
class ZigzagLinkage:
    """Motor angle to needle sideways position: linear, ``width_mm`` over
    ``steps_full_width`` full steps."""

    width_mm: float = 7.0
    steps_full_width: int = 40
    equivalent_mass_kg: float = 0.03  # needle bar and swing frame, at the needle point

    def __post_init__(self):
        if not (self.width_mm > 0 and self.steps_full_width > 0 and self.equivalent_mass_kg >= 0):
            raise UserError("zigzag linkage: width and steps must be positive, mass not negative")

    @property
    def mm_per_step(self) -> float:
        return self.width_mm / self.steps_full_width

    def mm_per_rad(self, params: StepperParams) -> float:
        return self.mm_per_step / params.step_rad

    def reflected_inertia_kg_m2(self, params: StepperParams) -> float:
        lever_m = self.mm_per_rad(params) / 1000.0
        return self.equivalent_mass_kg * lever_m**2

    def steps_for(self, width_mm: float) -> int:
        """Full steps for a sideways move of ``width_mm`` (rounded to the nearest step)."""
        return int(round(width_mm / self.mm_per_step))

    def motor(self, params: StepperParams | None = None) -> StepperParams:
        """The zigzag motor with the linkage's inertia on its shaft."""
        params = params or pm25s048()
        return params.replace(load_inertia_kg_m2=self.reflected_inertia_kg_m2(params))


class NeedleProfile:
    """``needle_z_mm(arm_angle_rad)``: needle point height over the needle-plate top,
    periodic in the arm angle (0 = needle TDC)."""

    def __init__(self, function: Callable[[np.ndarray], np.ndarray], name: str):
        self._function = function
        self.name = name

    def __call__(self, arm_angle_rad) -> np.ndarray:
        return np.asarray(self._function(np.asarray(arm_angle_rad, dtype=float)), dtype=float)

    @classmethod
    def slider_crank(
        cls, crank_mm: float = 16.5, rod_mm: float = 50.0, tdc_height_mm: float = 21.0
    ) -> "NeedleProfile":
        """A needle bar driven by a plain slider-crank (an analytic stand-in for the
        machine): height ``tdc_height_mm`` at TDC, stroke 2 x crank."""
        if not (0 < crank_mm < rod_mm):
            raise UserError(f"slider-crank needs 0 < crank ({crank_mm} mm) < rod ({rod_mm} mm)")

        def height(angle):
            drop = (
                crank_mm
                + rod_mm
                - (crank_mm * np.cos(angle) + np.sqrt(rod_mm**2 - (crank_mm * np.sin(angle)) ** 2))
            )
            return tdc_height_mm - drop

        return cls(
            height,
            f"slider-crank (crank {crank_mm:g} mm, rod {rod_mm:g} mm, TDC {tdc_height_mm:g} mm above the plate)",
        )

    @classmethod
    def from_table(cls, arm_angle_rad, needle_z_mm, name: str = "table") -> "NeedleProfile":
        """Periodic linear interpolation of a table over one revolution."""
        angle = np.asarray(arm_angle_rad, dtype=float)
        z = np.asarray(needle_z_mm, dtype=float)
        if angle.ndim != 1 or angle.shape != z.shape or angle.size < 8:
            raise UserError(
                f"needle table {name}: needs at least 8 rows of arm angle and needle height"
            )
        order = np.argsort(np.mod(angle, 2 * np.pi))
        wrapped, z = np.mod(angle, 2 * np.pi)[order], z[order]
        if np.any(np.diff(wrapped) <= 0):
            raise UserError(f"needle table {name}: arm angles repeat within one revolution")
        return cls(lambda a: np.interp(np.mod(a, 2 * np.pi), wrapped, z, period=2 * np.pi), name)

    @classmethod
    def from_csv(cls, path: str | os.PathLike) -> "NeedleProfile":
        """A CSV with ``arm_angle_deg`` (or ``arm_angle_rad``) and ``needle_z_mm``."""
        from mechanism.files.tables import read_table

        table = read_table(
            path,
            required=["needle_z_mm"],
            optional=["arm_angle_deg", "arm_angle_rad"],
            what="needle table",
        )
        if "arm_angle_deg" in table:
            angle = np.radians(table["arm_angle_deg"])
        elif "arm_angle_rad" in table:
            angle = table["arm_angle_rad"]
        else:
            raise UserError(
                f"{table.source}: needs a column arm_angle_deg or arm_angle_rad next to needle_z_mm"
            )
        return cls.from_table(angle, table["needle_z_mm"], Path(path).name)

    def window(self, clearance_mm: float = 0.0, samples: int = 7200) -> tuple[float, float]:
        """Arm angles [rad] where the needle point leaves the fabric (rising, before TDC:
        negative) and comes back into it (falling, after TDC): it is above
        ``clearance_mm`` in between. Crossings are found on a fine grid and refined."""
        from scipy.optimize import brentq

        angle = np.linspace(-np.pi, np.pi, samples + 1)
        above = self(angle) > clearance_mm
        if not above[samples // 2]:
            raise UserError(f"needle ({self.name}) is not above {clearance_mm:g} mm at TDC")
        if above.all():
            raise UserError(
                f"needle ({self.name}) never goes below {clearance_mm:g} mm: nothing to time against"
            )
        centre = samples // 2
        # first index above, going back from TDC
        first = centre - np.flatnonzero(~above[:centre][::-1])[0]
        last = centre + np.flatnonzero(~above[centre:])[0] - 1  # last index above, going forward

        def f(a):
            return float(self(a)) - clearance_mm

        exit_angle = brentq(f, angle[first - 1], angle[first])
        entry_angle = brentq(f, angle[last], angle[last + 1])
        return exit_angle, entry_angle


def machine_needle_profile(description=None, model_path=None) -> NeedleProfile:
    """The tool (needle) height over shaft angle of a described machine (default: the shipped
    one; ``model_path`` replaces its MJCF), from its kinematics (``mechanism.inspection.tool``)."""
    from dataclasses import replace
    from pathlib import Path

    from mechanism.inspection.tool import tool_motion
    from mechanism.machine.machine import Machine, resolve_description

    description = resolve_description(description)
    if model_path is not None:
        description = replace(description, model=Path(model_path))
    motion = tool_motion(Machine(description), samples=720)
    return NeedleProfile.from_table(
        np.deg2rad(motion.shaft_angle_deg),
        motion.tool_z_mm,
        f"machine {description.name}" if model_path is None else str(model_path),
    )


def arm_period_s(stitches_per_minute: float) -> float:
    if not (np.isfinite(stitches_per_minute) and stitches_per_minute > 0):
        raise UserError(
            f"sewing speed must be a positive number of stitches per minute, got {stitches_per_minute:g}"
        )
    return 60.0 / stitches_per_minute


@dataclass
class MoveCheck:
    """One sideways move timed against the needle's time above the fabric."""

    stitches_per_minute: float
    steps: int
    width_mm: float
    rate_steps_s: float
    exit_angle_deg: float  # needle leaves the fabric (the move starts)
    entry_angle_deg: float  # needle comes back into the fabric
    window_s: float  # time between the two
    move_time_s: float  # from the start until the needle stays within tolerance of its target
    tolerance_mm: float
    finish_angle_deg: float  # arm angle when the move is done
    needle_z_at_finish_mm: float
    lost_steps: int

    @property
    def flagged(self) -> bool:
        """The move is still under way when the needle is back in the fabric."""
        return self.move_time_s > self.window_s

    @property
    def margin_s(self) -> float:
        return self.window_s - self.move_time_s

    def as_dict(self) -> dict:
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out.update(flagged=self.flagged, margin_s=self.margin_s)
        return out


def settle_time(time_s: np.ndarray, error: np.ndarray, tolerance: float) -> float:
    """The first time after which ``|error|`` stays within ``tolerance`` (inf if never)."""
    outside = np.flatnonzero(np.abs(error) > tolerance)
    if outside.size == 0:
        return float(time_s[0])
    if outside[-1] == time_s.size - 1:
        return math.inf
    return float(time_s[outside[-1] + 1])


def check_move(
    stitches_per_minute: float,
    needle: NeedleProfile,
    width_mm: float | None = None,
    rate: float | None = None,
    linkage: ZigzagLinkage | None = None,
    params: StepperParams | None = None,
    kind: StepperKind = "circuit",
    mode: str = "full",
    ramp_steps: float = 0.0,
    clearance_mm: float = 0.0,
    tolerance_mm: float | None = None,
) -> MoveCheck:
    """Simulate one sideways move of ``width_mm`` (default: the full width) starting when
    the needle leaves the fabric, and time it against the needle's time above it.
    ``tolerance_mm`` (default half a step at the needle) says when the move is done."""
    linkage = linkage or ZigzagLinkage()
    motor = linkage.motor(params)
    width_mm = linkage.width_mm if width_mm is None else float(width_mm)
    steps = linkage.steps_for(width_mm)
    if steps <= 0:
        raise UserError(
            f"a zigzag move of {width_mm:g} mm is less than one step ({linkage.mm_per_step:g} mm)"
        )
    rate = float(rate) if rate is not None else described_step_rate()
    tolerance_mm = 0.5 * linkage.mm_per_step if tolerance_mm is None else float(tolerance_mm)
    period = arm_period_s(stitches_per_minute)
    exit_angle, entry_angle = needle.window(clearance_mm)
    window_s = (entry_angle - exit_angle) / (2 * np.pi) * period
    profile = step_profiles.move(steps, rate, ramp_steps, name=f"zigzag {steps} steps")
    run = simulate(profile, kind, mode, motor, settle_s=max(window_s, 0.05))
    error_mm = (
        (run.rotor_deg - steps * motor.step_angle_deg) / motor.step_angle_deg * linkage.mm_per_step
    )
    move_time = settle_time(run.time_s, error_mm, tolerance_mm)
    finish_angle = (
        exit_angle + 2 * np.pi * move_time / period if math.isfinite(move_time) else math.nan
    )
    return MoveCheck(
        stitches_per_minute=float(stitches_per_minute),
        steps=steps,
        width_mm=steps * linkage.mm_per_step,
        rate_steps_s=rate,
        exit_angle_deg=math.degrees(exit_angle),
        entry_angle_deg=math.degrees(entry_angle),
        window_s=window_s,
        move_time_s=move_time,
        tolerance_mm=tolerance_mm,
        finish_angle_deg=math.degrees(finish_angle),
        needle_z_at_finish_mm=float(needle(finish_angle))
        if math.isfinite(finish_angle)
        else math.nan,
        lost_steps=run.summary["lost_steps"],
    )


@dataclass
class SewingRun:
    """A run of zigzag stitches: the needle's path and where it moved inside the fabric."""

    columns: dict[str, np.ndarray]
    summary: dict


def sew(
    stitches_per_minute: float,
    needle: NeedleProfile,
    stitches: int = 6,
    width_mm: float | None = None,
    rate: float | None = None,
    linkage: ZigzagLinkage | None = None,
    params: StepperParams | None = None,
    kind: StepperKind = "circuit",
    mode: str = "full",
    clearance_mm: float = 0.0,
    tolerance_mm: float | None = None,
    sample_period_s: float = 1e-4,
) -> SewingRun:
    """Zigzag stitches at a steady arm speed: each time the needle leaves the fabric the
    driver heads for the other side at ``rate``. Time 0 is the first exit. Reports, per
    stitch, the largest sideways error of the needle while it is in the fabric."""
    linkage = linkage or ZigzagLinkage()
    motor = linkage.motor(params)
    width_mm = linkage.width_mm if width_mm is None else float(width_mm)
    steps = linkage.steps_for(width_mm)
    rate = float(rate) if rate is not None else described_step_rate()
    tolerance_mm = 0.5 * linkage.mm_per_step if tolerance_mm is None else float(tolerance_mm)
    if not (1 <= int(stitches) <= 1000):
        raise UserError(f"stitches must be 1..1000, got {stitches}")
    period = arm_period_s(stitches_per_minute)
    exit_angle, entry_angle = needle.window(clearance_mm)
    starts = np.arange(int(stitches)) * period
    targets = np.where(np.arange(int(stitches)) % 2 == 0, steps, 0)
    profile = step_profiles.from_targets("zigzag", starts, targets, rate)
    duration = int(stitches) * period
    run = simulate(
        profile, kind, mode, motor, settle_s=max(duration - profile.duration_s, 0.0) + 1e-9
    )
    dt = run.time_s[1] - run.time_s[0]
    every = max(1, int(round(sample_period_s / dt)))
    keep = run.time_s < duration
    time_s = run.time_s[keep]
    arm = exit_angle + 2 * np.pi * time_s / period
    z = needle(arm)
    in_fabric = np.mod(arm - exit_angle, 2 * np.pi) > entry_angle - exit_angle
    mm_per_deg = linkage.mm_per_step / motor.step_angle_deg
    x_cmd = run.command_deg[keep] * mm_per_deg - linkage.width_mm / 2
    x = run.rotor_deg[keep] * mm_per_deg - linkage.width_mm / 2
    # the needle's target in each stitch: the side it was sent to at the last exit
    stitch = np.minimum((time_s // period).astype(int), int(stitches) - 1)
    x_target = targets[stitch] * linkage.mm_per_step - linkage.width_mm / 2
    error = np.where(in_fabric, np.abs(x - x_target), 0.0)
    per_stitch = [float(error[stitch == k].max(initial=0.0)) for k in range(int(stitches))]
    bad = [k + 1 for k, e in enumerate(per_stitch) if e > tolerance_mm]
    columns = {
        "time_s": time_s[::every],
        "arm_angle_deg": np.degrees(arm[::every]),
        "needle_z_mm": z[::every],
        "needle_x_command_mm": x_cmd[::every],
        "needle_x_mm": x[::every],
        "needle_in_fabric": in_fabric[::every].astype(float),
        "sideways_error_in_fabric_mm": error[::every],
    }
    summary = {
        "stitches_per_minute": float(stitches_per_minute),
        "stitches": int(stitches),
        "steps_per_move": steps,
        "width_mm": steps * linkage.mm_per_step,
        "rate_steps_s": rate,
        "tolerance_mm": tolerance_mm,
        "worst_error_in_fabric_mm": max(per_stitch),
        "stitches_moving_in_fabric": bad,
        "lost_steps": run.summary["lost_steps"],
    }
    return SewingRun(columns, summary)


def plot_sewing(run: SewingRun, path) -> None:
    """Needle height and sideways position over time, the in-fabric phases shaded."""
    from mechanism.files.plotting import plt, save_figure

    c = run.columns
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    t = c["time_s"]
    axes[0].plot(t, c["needle_z_mm"], lw=1)
    axes[0].axhline(0, color="0.5", lw=0.8)
    axes[0].set_ylabel("needle height [mm]")
    axes[1].plot(t, c["needle_x_command_mm"], "--", color="0.4", lw=1, label="commanded")
    axes[1].plot(t, c["needle_x_mm"], lw=1.2, label="needle")
    axes[1].set_ylabel("needle sideways [mm]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.fill_between(
            t,
            0,
            1,
            where=c["needle_in_fabric"] > 0,
            transform=ax.get_xaxis_transform(),
            color="tab:red",
            alpha=0.12,
            lw=0,
        )
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8)
    s = run.summary
    fig.suptitle(
        f"zigzag {s['width_mm']:.2f} mm at {s['stitches_per_minute']:g} stitches/min, "
        f"{s['rate_steps_s']:g} steps/s: worst sideways error in the fabric {s['worst_error_in_fabric_mm']:.3f} mm "
        f"(shaded: needle in the fabric)",
        fontsize=9,
    )
    save_figure(fig, path)
