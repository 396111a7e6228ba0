"""``mechanism stepper``: run a step sequence on a PM25S-048 model, or sweep step rates."""

from __future__ import annotations

from mechanism.files.limits import number

import argparse
import json
import math
import sys

ORDER = 60

EPILOG = """\
sequences:
  thread-cut          the thesis's thread cut: 350 full steps (2625 deg) out and straight back
                      at the step rate (1000 steps/s, thesis 3.4.1)
  thread-cut-ramped   the same stroke, ramping linearly to rest over --ramp-steps before the
                      reversal and back up after it
  FILE.csv            time_s,rate_steps_s   piecewise-linear step rate (ramps), rate 0 before
                                            the first row, ends at the last row
                      time_s,target_steps   at each time head for the target (full steps from
                                            the start) at --rate; ends at the last target

Positions and rates are in full steps (7.5 deg) in every drive mode. The CSV has
time_s, commanded_position_deg, rotor_position_deg (unwrapped, 0 at the start),
rotor_speed_rad_s, phase_a_current_A, phase_b_current_A, torque_Nm, commanded_rate_steps_s.
With --sweep the CSV has one row per step rate with the lost steps of each model.

examples:
  mechanism stepper --sequence thread-cut --csv out/thread_cut.csv --plot out/thread_cut.png
  mechanism stepper --sequence thread-cut-ramped --model physical --mode micro16 --csv out/ramped.csv
  mechanism stepper --sweep 500:6000:500 --model both --csv out/pull_out.csv --plot out/pull_out.png
"""


def _sweep_range(text: str) -> list[float]:
    try:
        parts = [float(x) for x in text.split(":")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected FROM:TO:STEP in steps/s, got {text!r}"
        ) from None
    if len(parts) != 3 or not (0 < parts[0] <= parts[1]) or parts[2] <= 0:
        raise argparse.ArgumentTypeError(
            f"expected FROM:TO:STEP with 0 < FROM <= TO and STEP > 0, got {text!r}"
        )
    count = int((parts[1] - parts[0]) / parts[2] + 1e-9) + 1
    if count > 200:
        raise argparse.ArgumentTypeError(f"{count} rates is too many for one sweep (at most 200)")
    return [parts[0] + k * parts[2] for k in range(count)]


def _sequence_file(args):
    return None if args.sequence in (None, "thread-cut", "thread-cut-ramped") else args.sequence


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "stepper",
        help="simulate the PM25S-048 stepper (thread cutter, zigzag motor): circuit or physical model",
        description=(
            "Run a step sequence on a stepper-motor model of the PM25S-048 (2-phase bipolar PM, 7.5 deg/step) "
            "as a MuJoCo actuator: the circuit model (phase R, L, back-EMF, detent torque, chopper constant-"
            "current drive on a 24 V supply) or the physical equivalent-spring model (Righettini et al., thesis "
            "eq. 19-26). Prints peak position, final error, lost steps and the overshoot at each reversal."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument(
        "--sequence",
        metavar="NAME|FILE",
        help="thread-cut, thread-cut-ramped, or a CSV sequence file (see below)",
    )
    what.add_argument(
        "--sweep",
        metavar="FROM:TO:STEP",
        type=_sweep_range,
        help="instead of a sequence: ramp up to each step rate [full steps/s], hold, ramp down, "
        "count lost steps and report the pull-out rate",
    )
    parser.add_argument(
        "--model",
        default="circuit",
        choices=["circuit", "physical", "both"],
        help="motor model (default circuit); 'both' only with --sweep",
    )
    parser.add_argument(
        "--mode",
        default="full",
        metavar="full|half|microN",
        help="drive mode: full (both phases on), half, or microN sine/cosine microstepping with "
        "N = 2..256 positions per full step (default full)",
    )
    parser.add_argument(
        "--rate",
        type=number(0, 1e5, "steps/s", low_open=True),
        metavar="STEPS_PER_S",
        help="slew rate [full steps/s] for thread-cut and target files (default: the thesis's 1000)",
    )
    parser.add_argument(
        "--ramp-steps",
        type=number(0, 1e5, "steps", low_open=True),
        default=None,
        metavar="STEPS",
        help="thread-cut-ramped: full steps of the ramp to rest before the reversal (default 25)",
    )
    parser.add_argument(
        "--machine",
        metavar="FILE.toml|NAME",
        help="machine description whose [stepper] and [thread_cut] to use (default: the shipped sewing machine)",
    )
    parser.add_argument(
        "--load-torque",
        type=number(0, 10, "N m"),
        default=0.0,
        metavar="NM",
        help="load torque Tl [N m] on the motor shaft, as Coulomb friction (default 0)",
    )
    parser.add_argument(
        "--load-inertia",
        type=number(0, 1, "kg m^2"),
        default=0.0,
        metavar="KG_M2",
        help="load inertia [kg m^2] reflected to the motor shaft (default 0: the bare rotor, 5e-8)",
    )
    parser.add_argument(
        "--settle",
        type=number(0, 60, "s"),
        default=0.1,
        metavar="S",
        help="seconds simulated after the sequence ends, before the lost-step check (default 0.1)",
    )
    parser.add_argument(
        "--sample-period",
        type=number(0, 1, "s", low_open=True),
        default=1e-4,
        metavar="S",
        help="CSV row spacing [s] (default 1e-4; the simulation step is 5 us for the circuit model)",
    )
    parser.add_argument("--csv", required=True, metavar="OUT.csv", help="output table")
    parser.add_argument(
        "--plot",
        metavar="OUT.png",
        help="also plot position, speed, currents and torque (or the sweep)",
    )
    parser.add_argument("--json", metavar="OUT.json", help="also write the summary as JSON")
    parser.set_defaults(
        handler=run,
        inputs=(_sequence_file, "machine"),
        outputs=("csv", "plot", "json"),
        plots=("plot",),
    )


def run(args) -> int:
    from mechanism import steppers
    from mechanism.cli._choices import chosen
    from mechanism.steppers import step_profiles
    from mechanism.errors import UserError
    from mechanism.files.outputs import atomic_file
    from mechanism.files.tables import write_table

    mode = steppers.drive_mode(args.mode)
    if args.rate is not None and not (args.rate > 0 and args.rate != float("inf")):
        raise UserError(
            f"--rate must be a positive number of full steps per second, got {args.rate:g}"
        )
    for name in ("settle", "sample_period"):
        value = getattr(args, name)
        if not (value >= 0 if name == "settle" else value > 0) or value != value or value > 60:
            raise UserError(f"--{name.replace('_', '-')} out of range: {value:g} s")
    for name in ("load_torque", "load_inertia"):
        value = getattr(args, name)
        if not (value >= 0 and math.isfinite(value)):
            raise UserError(
                f"--{name.replace('_', '-')} must be a non-negative number, got {value:g}"
            )
    params = steppers.described_stepper(
        args.machine, load_torque_Nm=args.load_torque, load_inertia_kg_m2=args.load_inertia
    )

    if args.sweep:
        kinds = (
            list(steppers.KINDS)
            if args.model == "both"
            else [chosen(args.model, steppers.KINDS, "--model")]
        )
        results, pull_out = {}, {}
        for kind in kinds:
            results[kind] = steppers.sweep_rates(
                args.sweep, kind, mode, params, progress=sys.stderr.isatty()
            )
            failing = [r["rate_steps_s"] for r in results[kind] if r["lost_steps"] or r["slips"]]
            if failing:
                holding = [
                    r["rate_steps_s"] for r in results[kind] if r["rate_steps_s"] < failing[0]
                ]
                low = holding[-1] if holding else None
                pull_out[kind] = (
                    steppers.pull_out_rate(kind, mode, params, low=low, high=failing[0])
                    if low is not None
                    else failing[0]
                )
            else:
                pull_out[kind] = None
        columns = {"rate_steps_s": args.sweep}
        for kind in kinds:
            columns[f"{kind}_lost_steps"] = [r["lost_steps"] for r in results[kind]]
            columns[f"{kind}_slips"] = [r["slips"] for r in results[kind]]
        write_table(
            args.csv,
            columns,
            comments=[f"mode: {mode.name}", "ramped moves: 0.1 s up, 0.05 s hold, 0.1 s down"],
        )
        for kind in kinds:
            rate = pull_out[kind]
            print(
                f"{kind} model ({mode.name} step): "
                + (
                    f"pull-out rate {rate:.0f} steps/s ({rate * params.step_angle_deg / 360 * 60:.0f} rpm)"
                    if rate
                    else f"no lost steps up to {max(args.sweep):g} steps/s"
                )
            )
        if args.plot:
            steppers.plot_sweep(results, args.plot)
        if args.json:
            with atomic_file(args.json) as handle:
                json.dump(
                    {"mode": mode.name, "pull_out_rate_steps_s": pull_out, "sweep": results},
                    handle,
                    indent=2,
                )
        return 0

    if args.model == "both":
        raise UserError(
            "--model both only works with --sweep; run each model separately for a sequence"
        )
    ramp = step_profiles.DEFAULT_RAMP_STEPS if args.ramp_steps is None else args.ramp_steps
    if args.ramp_steps is not None and args.sequence != "thread-cut-ramped":
        raise UserError("--ramp-steps only applies to --sequence thread-cut-ramped")
    if not ramp > 0:
        raise UserError(f"--ramp-steps must be positive, got {ramp:g}")
    profile = step_profiles.resolve(args.sequence, args.rate, ramp, machine=args.machine)
    result = steppers.simulate(profile, args.model, mode, params, settle_s=args.settle)
    s = result.summary
    write_table(
        args.csv,
        result.columns(args.sample_period),
        comments=[
            f"sequence: {profile.name}",
            f"model: {args.model}",
            f"mode: {mode.name}",
            f"step_angle_deg: {params.step_angle_deg:g}",
            f"timestep_s: {result.time_s[1] - result.time_s[0]:g}",
        ],
    )
    if args.plot:
        steppers.plot_run(result, args.plot)
    if args.json:
        with atomic_file(args.json) as handle:
            json.dump(s, handle, indent=2)
    step = params.step_angle_deg
    print(
        f"{profile.name} on the {args.model} model ({mode.name} step, {result.backend} callbacks): "
        f"{s['duration_s']:.3f} s simulated in {result.wall_s:.2f} s ({result.real_time_factor:.1f}x real time)"
    )
    print(
        f"  peak position {s['peak_position_deg']:.2f} deg (commanded {s['peak_command_deg']:.2f} deg = "
        f"{s['peak_command_deg'] / step:.0f} steps)"
    )
    print(
        f"  final position {s['final_position_deg']:.2f} deg, error {s['final_error_deg']:+.2f} deg; "
        f"lost steps {s['lost_steps']}"
    )
    for t, n in s["slips"][:10]:
        print(f"  slip at {t:.4f} s: {n:+d} steps")
    if len(s["slips"]) > 10:
        print(f"  ... {len(s['slips']) - 10} more slips")
    for r in s["reversals"]:
        print(
            f"  reversal at {r['time_s']:.3f} s: overshoot {r['overshoot_deg']:.2f} deg, peak speed "
            f"{r['peak_speed_rad_s']:.0f} rad/s, peak speed error {r['peak_speed_error_rad_s']:.0f} rad/s "
            f"(within 50 ms)"
        )
    return 0
