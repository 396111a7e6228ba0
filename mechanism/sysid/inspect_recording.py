"""What a recording holds, before any fit (``mechanism inspect-recording``): the columns
found and chosen, units, rate, duration, each signal's range, the encoder step, gaps, and a
simple, stated check of whether the recording excites the machine enough to identify each
parameter of the lumped baseline.

The excitation check is deliberately plain (thresholds below, each named in the output):

- inertia: needs speed changes: at least two voltage levels (steps) and a speed range of at
  least :data:`MIN_SPEED_RANGE_RAD_S`;
- viscous friction: needs steady running at two or more clearly different speeds (the
  speeds at the voltage plateaus differ by at least a factor :data:`MIN_SPEED_RATIO`);
- Coulomb friction: needs the shaft to start and stop or to turn both ways (a constant
  friction torque is told from a viscous one by low speeds and by its sign);
- winding L/R: needs voltage steps (it shows only in the first milliseconds after each).

These are necessary conditions, not sufficient ones: identify's uncertainties say how well
each parameter was actually determined.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from mechanism.errors import UserError
from mechanism.files.formats import read_columns

MIN_SPEED_RANGE_RAD_S = 5.0
MIN_SPEED_RATIO = 1.5
MOVING_RAD_S = 0.5


def _range(values: np.ndarray) -> dict:
    return {"min": float(np.min(values)), "max": float(np.max(values))}


def inspect_recording(path: str | os.PathLike, recording_map=None) -> dict:
    """The inspection as a JSON-ready dict (units in every key)."""
    from mechanism.sysid.recording import (
        check_excitation,
        make_recording,
        sampling_gaps,
        smoothed_velocity,
    )
    from mechanism.sysid.recording_map import apply_map
    from mechanism.sysid.residual import counts_from_steps

    path = Path(path)
    columns = read_columns(
        path, "recording", records=recording_map.get("records") if recording_map else None
    )
    signals = apply_map(columns, recording_map)
    time = signals.time_s
    out: dict = {
        "recording": str(path),
        "format": signals.reading["file_format"],
        "map": signals.reading["map"],
        "columns_found": columns.names,
        "samples": int(len(time)),
    }
    out["chosen"] = {
        key: value
        for key, value in signals.reading.items()
        if key in ("time_s", "voltage_V", "shaft_angle_rad", "current_A", "signed_bits")
    }
    if len(time) < 2:
        raise UserError(f"recording {path}: {len(time)} sample(s)")
    steps = np.diff(time)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        out["problems"] = [
            f"time is not strictly increasing at sample {i + 2} ({time[i]:.6g} s then {time[i + 1]:.6g} s)"
        ]
        return out
    dt, gaps = sampling_gaps(time)
    out["duration_s"] = float(time[-1] - time[0])
    out["rate_Hz"] = 1.0 / dt
    out["step_jitter_percent"] = float(100 * np.max(np.abs(steps - dt)) / dt)
    out["gaps"] = [{"after_s": at, "length_s": length} for at, length in gaps]
    ranges = {
        "time_s": _range(time),
        "voltage_V": _range(signals.voltage_V),
        "shaft_angle_rad": _range(signals.shaft_angle_rad),
    }
    if signals.current_A is not None:
        ranges["current_A"] = _range(signals.current_A)
    out["ranges"] = ranges
    counts = counts_from_steps(signals.shaft_angle_rad)
    stated = signals.metadata.get("counts_per_rev")
    out["encoder"] = {
        "counts_per_rev_detected": counts,
        "step_rad_detected": 2 * math.pi / counts if counts else None,
        "counts_per_rev_stated": int(float(stated)) if stated not in (None, "") else None,
    }
    problems: list[str] = []
    try:
        rec = make_recording(
            time,
            signals.voltage_V,
            signals.shaft_angle_rad,
            signals.current_A,
            signals.metadata,
            str(path),
            unwrap=signals.unwrap,
            reading=signals.reading,
        )
    except UserError as exc:
        problems.append(str(exc))
        out["problems"] = problems
        out["usable"] = False
        return out
    out["usable"] = True
    out["resampling"] = rec.reading.get("resampling")
    speed = smoothed_velocity(rec.arm_angle_rad, rec.dt)
    out["ranges"]["shaft_speed_rad_s"] = _range(speed)
    top_turns_s = float(np.percentile(np.abs(speed), 99)) / (2 * math.pi)
    out["nyquist_Hz"] = 0.5 / rec.dt
    # a ripple of k per shaft turn is at k * turns/s: above the Nyquist frequency it cannot be seen
    out["orders_per_turn_visible_at_top_speed"] = (
        out["nyquist_Hz"] / top_turns_s if top_turns_s > 0 else None
    )
    out["excitation"] = _excitation(rec, speed)
    overall = check_excitation(rec)
    out["identifiable"] = overall.identifiable
    out["identifiable_reason"] = overall.reason
    out["problems"] = problems
    return out


def _excitation(rec, speed: np.ndarray) -> dict:
    from mechanism.sysid.recording import _voltage_levels

    u = rec.voltage_V
    levels = _voltage_levels(u)
    span = float(np.percentile(speed, 99) - np.percentile(speed, 1))
    forward, backward = bool(np.any(speed > MOVING_RAD_S)), bool(np.any(speed < -MOVING_RAD_S))
    still = np.abs(speed) < MOVING_RAD_S
    starts = int(np.count_nonzero(still[:-1] & ~still[1:]))
    plateau_speeds = []
    rounded = np.round(u / 0.25) * 0.25
    for level in levels:
        at = np.flatnonzero(rounded == level)
        if len(at) > 10:
            late = at[len(at) // 2 :]  # the settled half of the time at this level
            plateau_speeds.append(float(np.median(np.abs(speed[late]))))
    moving = [s for s in plateau_speeds if s > MOVING_RAD_S]
    ratio = max(moving) / min(moving) if len(moving) >= 2 else 1.0
    u_steps = int(np.count_nonzero(np.abs(np.diff(u)) > 0.5))

    def verdict(ok: bool, why: str) -> dict:
        return {"excited": ok, "why": why}

    return {
        "voltage_levels_V": levels[:12],
        "shaft_speed_range_rad_s": span,
        "turns_forward": forward,
        "turns_backward": backward,
        "starts_from_rest": starts,
        "plateau_speed_ratio": ratio,
        "inertia": verdict(
            len(levels) >= 2 and span >= MIN_SPEED_RANGE_RAD_S,
            f"{len(levels)} voltage level(s), speed range {span:.3g} rad/s (needs 2 levels and "
            f"{MIN_SPEED_RANGE_RAD_S:g} rad/s)",
        ),
        "viscous_friction": verdict(
            ratio >= MIN_SPEED_RATIO,
            f"steady speeds at the plateaus differ by a factor {ratio:.3g} (needs {MIN_SPEED_RATIO:g})",
        ),
        "coulomb_friction": verdict(
            starts >= 1 or (forward and backward),
            f"{starts} start(s) from rest, turns {'both ways' if forward and backward else 'one way'} "
            "(needs a start from rest or both directions)",
        ),
        "winding_L_over_R": verdict(
            u_steps >= 1, f"{u_steps} voltage step(s) of more than 0.5 V (needs one)"
        ),
    }


def format_inspection(data: dict) -> str:
    """The inspection as lines of text for the terminal."""
    lines = [
        f"recording {data['recording']} ({data['format']}; map: {data['map']})",
        f"columns found: {', '.join(data['columns_found'][:30])}"
        + (" ..." if len(data["columns_found"]) > 30 else ""),
    ]
    for key, item in data["chosen"].items():
        if key == "signed_bits":
            lines.append(
                f"  signed registers: {', '.join(f'{k} ({v} bits)' for k, v in item.items())}"
            )
            continue
        extra = ""
        if key == "shaft_angle_rad":
            extra = f"; {item.get('formula', '')}" + (
                f"; unwrapped: {item['unwrapped']}" if "unwrapped" in item else ""
            )
        elif key == "time_s" and "shifted_by_s" in item:
            extra = f"; shifted by {item['shifted_by_s']:.6g} s to start at 0"
        lines.append(f"  {key:16s} <- {item['from']} [{item['unit']}]{extra}")
    if "rate_Hz" in data:
        lines.append(
            f"samples {data['samples']}, duration {data['duration_s']:.4g} s, rate {data['rate_Hz']:.4g} Hz, "
            f"step jitter {data['step_jitter_percent']:.3g} %"
        )
        for gap in data["gaps"]:
            lines.append(f"gap: {gap['length_s']:.4g} s after t = {gap['after_s']:.6g} s")
        for key, r in data["ranges"].items():
            lines.append(f"  {key:18s} {r['min']:12.5g} .. {r['max']:.5g}")
        enc = data["encoder"]
        detected = (
            f"{enc['counts_per_rev_detected']} counts/rev (step {enc['step_rad_detected']:.3g} rad)"
            if enc["counts_per_rev_detected"]
            else "no quantisation step found"
        )
        lines.append(
            f"encoder: {detected}"
            + (
                f"; stated {enc['counts_per_rev_stated']} counts/rev"
                if enc["counts_per_rev_stated"]
                else ""
            )
        )
    if data.get("orders_per_turn_visible_at_top_speed"):
        lines.append(
            f"Nyquist {data['nyquist_Hz']:.4g} Hz: at the top speed, effects up to "
            f"{data['orders_per_turn_visible_at_top_speed']:.3g} per shaft turn can be seen"
        )
    if data.get("resampling"):
        lines.append(f"resampling: {data['resampling']['method']}")
    if "excitation" in data:
        for name in ("inertia", "viscous_friction", "coulomb_friction", "winding_L_over_R"):
            item = data["excitation"][name]
            lines.append(
                f"  {name:18s} {'excited' if item['excited'] else 'NOT excited'}: {item['why']}"
            )
        lines.append(
            f"identifiable: {'yes' if data['identifiable'] else 'no'} -- {data['identifiable_reason']}"
        )
    for problem in data.get("problems", []):
        lines.append(f"problem: {problem}")
    return "\n".join(lines)


def split_at_gaps(
    path: str | os.PathLike, out_dir: str | os.PathLike, recording_map=None
) -> list[Path]:
    """Cut a recording at its gaps into gap-free pieces of at least the shortest usable
    length, written as contract CSVs (``time_s``, ``voltage_V``, ``shaft_angle_rad``,
    ``current_A``: the map already applied) into ``out_dir`` as ``<name>_part<k>.csv``; a
    folder ``diagnose --out`` takes as a fleet. Pieces too short to use are left out (and
    said so in the returned list's absence). UserError when no piece is long enough."""
    from mechanism.files.outputs import atomic_dir
    from mechanism.files.tables import write_table
    from mechanism.sysid.recording import MIN_DURATION_S, sampling_gaps
    from mechanism.sysid.recording_map import apply_map

    path = Path(path)
    columns = read_columns(
        path, "recording", records=recording_map.get("records") if recording_map else None
    )
    signals = apply_map(columns, recording_map)
    time = signals.time_s
    if len(time) < 2 or np.any(np.diff(time) <= 0):
        raise UserError(f"recording {path}: time is not strictly increasing; nothing to split")
    _, gaps = sampling_gaps(time)
    cuts = [int(np.searchsorted(time, at)) + 1 for at, _ in gaps]
    bounds = list(zip([0, *cuts], [*cuts, len(time)]))
    stem = path.name.split(".")[0]
    counts = signals.metadata.get("counts_per_rev")
    written: list[Path] = []
    with atomic_dir(out_dir, keep=True) as folder:
        for k, (a, b) in enumerate(bounds, start=1):
            if time[b - 1] - time[a] < MIN_DURATION_S:
                continue
            piece = {
                "time_s": time[a:b],
                "voltage_V": signals.voltage_V[a:b],
                "shaft_angle_rad": signals.shaft_angle_rad[a:b],
            }
            if signals.current_A is not None:
                piece["current_A"] = signals.current_A[a:b]
            comments = [
                f"piece {k} of {len(bounds)} of {path.name} between gaps: {time[a]:.6g} s to {time[b - 1]:.6g} s",
                *([f"counts_per_rev: {counts}"] if counts else []),
            ]
            target = folder / f"{stem}_part{k}.csv"
            write_table(target, piece, comments=comments, fmt="%.12g")
            written.append(Path(out_dir) / target.name)
        if not written:
            raise UserError(
                f"recording {path}: no piece between its {len(gaps)} gap(s) lasts {MIN_DURATION_S:g} s"
            )
    return written
