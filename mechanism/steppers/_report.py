"""What a run is and what it says: :class:`StepperRun`, slips, the summary and the plots."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from mechanism.steppers._drive import DriveMode, StepperKind
from mechanism.steppers._motor import StepperParams
from mechanism.steppers.step_profiles import StepProfile


@dataclass
class StepperRun:
    """One simulated sequence at the simulation's full time resolution. Angles are
    relative to the start (the rest position of step 0), unwrapped."""

    kind: StepperKind
    mode: DriveMode
    params: StepperParams
    profile: StepProfile
    time_s: np.ndarray
    command_deg: np.ndarray  # the driver's rounded command
    rotor_deg: np.ndarray
    speed_rad_s: np.ndarray
    current_a_A: np.ndarray
    current_b_A: np.ndarray
    torque_Nm: np.ndarray
    backend: Literal["native", "python"] = "native"  # the callbacks that ran
    wall_s: float = 0.0
    summary: dict = field(default_factory=dict)

    @property
    def step_deg(self) -> float:
        return self.params.step_angle_deg

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return (
            float(self.time_s[-1] + (self.time_s[1] - self.time_s[0])) / self.wall_s
            if self.wall_s
            else math.inf
        )

    def columns(self, sample_period_s: float | None = None) -> dict[str, np.ndarray]:
        """The CSV columns, every ``sample_period_s`` (all steps when None)."""
        dt = self.time_s[1] - self.time_s[0]
        every = max(1, int(round(sample_period_s / dt))) if sample_period_s else 1
        pick = slice(None, None, every)
        return {
            "time_s": self.time_s[pick],
            "commanded_position_deg": self.command_deg[pick],
            "rotor_position_deg": self.rotor_deg[pick],
            "rotor_speed_rad_s": self.speed_rad_s[pick],
            "phase_a_current_A": self.current_a_A[pick],
            "phase_b_current_A": self.current_b_A[pick],
            "torque_Nm": self.torque_Nm[pick],
            "commanded_rate_steps_s": self.profile.rate_steps_s(self.time_s[pick]),
        }


def slip_events(run: StepperRun) -> list[tuple[float, int]]:
    """(time, full steps) each time the rotor slips a whole electrical period (4 full
    steps) against the field: negative = it fell behind the command. A slip is counted
    when the load angle passes 1.25 half-periods, so an oscillation at the edge does not
    chatter."""
    p = run.params.pole_pairs
    load = np.radians(run.command_deg - run.rotor_deg) * p  # electrical radians, + = rotor behind
    steps_per_period = 4
    events: list[tuple[float, int]] = []
    centre, start = 0, 0
    while True:
        beyond = np.flatnonzero(np.abs(load[start:] - 2 * np.pi * centre) > 1.25 * np.pi)
        if beyond.size == 0:
            return events
        k = start + int(beyond[0])
        new_centre = int(np.round(load[k] / (2 * np.pi)))
        events.append((float(run.time_s[k]), -(new_centre - centre) * steps_per_period))
        centre, start = new_centre, k


def analyse(
    run: StepperRun, settle_window_s: float = 0.005, reversal_window_s: float = 0.05
) -> dict:
    """Peak position, final error, lost steps (rotor more than half a step from the
    command after settling) with slip times, and at each reversal, within
    ``reversal_window_s`` either side: the overshoot (how far the rotor passes the
    commanded turning point), the peak speed error against the commanded speed and the
    peak speed (the spike of the thesis's figure 20)."""
    step = run.step_deg
    tail = run.time_s >= run.time_s[-1] - settle_window_s
    final_error = float(np.mean(run.rotor_deg[tail] - run.command_deg[tail]))
    lost = int(round(abs(final_error) / step)) if abs(final_error) > step / 2 else 0
    summary = {
        "model": run.kind,
        "mode": run.mode.name,
        "sequence": run.profile.name,
        "duration_s": float(run.time_s[-1]),
        "peak_command_deg": float(np.max(run.command_deg)),
        "peak_position_deg": float(np.max(run.rotor_deg)),
        "final_command_deg": float(np.mean(run.command_deg[tail])),
        "final_position_deg": float(np.mean(run.rotor_deg[tail])),
        "final_error_deg": final_error,
        "lost_steps": lost,
        "slips": slip_events(run),
    }
    reversals = []
    for t_rev in run.profile.reversal_times_s():
        before = run.profile.rate_steps_s(np.array([max(t_rev - 1e-6, 0.0)]))[0]
        direction = 1.0 if before > 0 else -1.0
        window = (run.time_s >= t_rev - reversal_window_s) & (
            run.time_s <= t_rev + reversal_window_s
        )
        turn = float(np.max(direction * run.command_deg[window]))
        overshoot = float(np.max(direction * run.rotor_deg[window]) - turn)
        commanded_speed = run.profile.rate_steps_s(run.time_s[window]) * run.params.step_rad
        speed_error = float(np.max(np.abs(run.speed_rad_s[window] - commanded_speed)))
        reversals.append(
            {
                "time_s": t_rev,
                "overshoot_deg": overshoot,
                "peak_speed_error_rad_s": speed_error,
                "peak_speed_rad_s": float(np.max(np.abs(run.speed_rad_s[window]))),
            }
        )
    summary["reversals"] = reversals
    return summary


def plot_run(run: StepperRun, path) -> None:
    """Position, speed (the thesis's figures 19 and 20), phase currents and torque."""
    from mechanism.files.plotting import plt, save_figure

    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    t = run.time_s
    axes[0].plot(t, run.command_deg, "--", color="0.4", lw=1, label="commanded")
    axes[0].plot(t, run.rotor_deg, lw=1.2, label="rotor")
    axes[0].set_ylabel("position [deg]")
    axes[1].plot(
        t,
        run.profile.rate_steps_s(t) * run.params.step_rad,
        "--",
        color="0.4",
        lw=1,
        label="commanded",
    )
    axes[1].plot(t, run.speed_rad_s, lw=0.8, label="rotor")
    axes[1].set_ylabel("speed [rad/s]")
    axes[2].plot(t, run.current_a_A, lw=0.6, label="phase A")
    axes[2].plot(t, run.current_b_A, lw=0.6, label="phase B")
    axes[2].set_ylabel("current [A]")
    axes[3].plot(t, run.torque_Nm * 1e3, lw=0.6)
    axes[3].set_ylabel("torque [mN m]")
    axes[3].set_xlabel("time [s]")
    for reversal in run.summary.get("reversals", []):
        for ax in axes[:2]:
            ax.axvline(reversal["time_s"], color="r", lw=0.6, alpha=0.5)
    for ax in axes[:3]:
        ax.legend(loc="best", fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    s = run.summary
    fig.suptitle(
        f"{run.profile.name}: {run.kind} model, {run.mode.name} step; lost steps {s['lost_steps']}, "
        f"final error {s['final_error_deg']:.2f} deg",
        fontsize=10,
    )
    save_figure(fig, path)


def plot_sweep(results: dict[StepperKind, list[dict]], path) -> None:
    """Lost steps against the step rate, one line per model."""
    from mechanism.files.plotting import plt, save_figure

    fig, ax = plt.subplots(figsize=(7, 4))
    for kind, rows in results.items():
        ax.plot(
            [r["rate_steps_s"] for r in rows], [r["lost_steps"] for r in rows], "o-", label=kind
        )
    ax.set_xlabel("step rate [full steps/s]")
    ax.set_ylabel("lost steps after a ramped move")
    ax.grid(alpha=0.3)
    ax.legend()
    save_figure(fig, path)
