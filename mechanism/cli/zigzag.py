"""``mechanism zigzag``: time a zigzag needle move against the needle's time above the fabric."""

from __future__ import annotations

from mechanism.files.limits import number

import argparse
import json
import math

ORDER = 61

EPILOG = """\
The needle may only move sideways while its point is above the fabric (needle-plate top
plus --clearance-mm). A move starts when the needle leaves the fabric; it is FLAGGED when
the needle is not yet within --tolerance-mm of its target when it re-enters. Exit status:
0 = the move fits, 1 = flagged, 2 = bad input.

needle height over arm angle (0 = needle TDC, z from the needle-plate top):
  --needle slider-crank   analytic crank --crank-mm / rod --rod-mm, TDC --tdc-height-mm above the plate
  --needle machine        the sewing machine's needle table from its kinematics (default; the
                          shipped machine, or --machine-model MJCF)
  --needle-csv FILE       a table with arm_angle_deg (or arm_angle_rad) and needle_z_mm

linkage (assumed): full width 7 mm = 40 full steps (0.175 mm per 7.5 deg step), needle bar and
swing frame 30 g at the needle.

examples:
  mechanism zigzag --spm 1000 --rate 1000
  mechanism zigzag --spm 1000 --rate 1500 --stitches 8 --csv out/zigzag.csv --plot out/zigzag.png
"""


def _finite(value):
    """JSON has no NaN or infinity: write null (a move that never settles)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "zigzag",
        help="check that a zigzag needle move fits in the needle's time above the fabric",
        description=(
            "Simulate the zigzag stepper (PM25S-048 model with the needle-bar linkage) moving the needle "
            "sideways, timed against the arm shaft at a sewing speed, and flag moves that are still under way "
            "when the needle is back in the fabric. Optionally simulate a run of zigzag stitches."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--spm",
        type=number(0, 5000, "stitches/min", low_open=True),
        required=True,
        metavar="STITCHES_PER_MIN",
        help="sewing speed [stitches per minute] = arm shaft rpm",
    )
    parser.add_argument(
        "--width-mm",
        type=number(0, 50, "mm", low_open=True),
        default=None,
        metavar="MM",
        help="sideways move [mm] (default: the full zigzag width, 7 mm)",
    )
    parser.add_argument(
        "--rate",
        type=number(0, 1e5, "steps/s", low_open=True),
        default=None,
        metavar="STEPS_PER_S",
        help="stepper slew rate [full steps/s] (default: the thesis's 1000)",
    )
    parser.add_argument(
        "--ramp-steps",
        type=number(0, 1e4, "steps"),
        default=0.0,
        metavar="STEPS",
        help="linear ramps at both ends of the move [full steps] (default 0: abrupt)",
    )
    parser.add_argument(
        "--model",
        default="circuit",
        choices=["circuit", "physical"],
        help="motor model (default circuit)",
    )
    parser.add_argument(
        "--mode", default="full", metavar="full|half|microN", help="drive mode (default full)"
    )
    parser.add_argument(
        "--needle",
        default="machine",
        choices=["machine", "slider-crank"],
        help="needle height source (default machine; see below)",
    )
    parser.add_argument(
        "--machine",
        metavar="FILE.toml",
        help="machine description for --needle machine: its tool's height table (default: the shipped sewing machine)",
    )
    parser.add_argument(
        "--machine-model",
        metavar="MJCF",
        help="an MJCF with the description's names instead of its model",
    )
    parser.add_argument(
        "--needle-csv", metavar="FILE", help="needle height table (overrides --needle)"
    )
    parser.add_argument(
        "--crank-mm",
        type=number(0, 1000, "mm", low_open=True),
        default=16.5,
        metavar="MM",
        help="slider-crank: crank radius [mm] (default 16.5)",
    )
    parser.add_argument(
        "--rod-mm",
        type=number(0, 1e4, "mm", low_open=True),
        default=50.0,
        metavar="MM",
        help="slider-crank: rod length [mm] (default 50)",
    )
    parser.add_argument(
        "--tdc-height-mm",
        type=number(-1000, 1000, "mm"),
        default=21.0,
        metavar="MM",
        help="slider-crank: needle point above the plate at TDC [mm] (default 21)",
    )
    parser.add_argument(
        "--clearance-mm",
        type=number(0, 100, "mm"),
        default=0.0,
        metavar="MM",
        help="fabric thickness: the needle must be this far above the plate to move [mm] (default 0)",
    )
    parser.add_argument(
        "--tolerance-mm",
        type=number(0, 100, "mm", low_open=True),
        default=None,
        metavar="MM",
        help="the move is done when the needle stays this close to its target [mm] "
        "(default half a step, 0.0875 mm)",
    )
    parser.add_argument(
        "--stitches",
        type=number(1, 1000, integer=True),
        default=6,
        metavar="N",
        help="stitches simulated for --csv/--plot (default 6)",
    )
    parser.add_argument("--csv", metavar="OUT.csv", help="write the needle path of the stitch run")
    parser.add_argument("--plot", metavar="OUT.png", help="plot the needle path of the stitch run")
    parser.add_argument(
        "--json", metavar="OUT.json", help="write the move check (and stitch summary) as JSON"
    )
    parser.set_defaults(
        handler=run,
        inputs=("needle_csv", "machine_model", "machine"),
        outputs=("csv", "plot", "json"),
        plots=("plot",),
    )


def run(args) -> int:
    from mechanism.cli._choices import chosen
    from mechanism.steppers import KINDS, zigzag
    from mechanism.errors import UserError
    from mechanism.files.outputs import atomic_file
    from mechanism.files.tables import write_table

    for name in ("spm", "width_mm", "rate", "crank_mm", "rod_mm", "tolerance_mm"):
        value = getattr(args, name)
        if value is not None and not (value > 0 and math.isfinite(value)):
            raise UserError(f"--{name.replace('_', '-')} must be a positive number, got {value:g}")
    for name in ("ramp_steps", "clearance_mm"):
        value = getattr(args, name)
        if not (value >= 0 and math.isfinite(value)):
            raise UserError(f"--{name.replace('_', '-')} must not be negative, got {value:g}")
    if args.needle_csv:
        needle = zigzag.NeedleProfile.from_csv(args.needle_csv)
    elif args.needle == "machine":
        needle = zigzag.machine_needle_profile(args.machine, args.machine_model)
    else:
        needle = zigzag.NeedleProfile.slider_crank(args.crank_mm, args.rod_mm, args.tdc_height_mm)
    options = dict(
        width_mm=args.width_mm,
        rate=args.rate,
        kind=chosen(args.model, KINDS, "--model"),
        mode=args.mode,
        clearance_mm=args.clearance_mm,
        tolerance_mm=args.tolerance_mm,
    )
    check = zigzag.check_move(args.spm, needle, ramp_steps=args.ramp_steps, **options)
    print(f"needle: {needle.name}")
    print(
        f"at {args.spm:g} stitches/min the needle is above the fabric from {check.exit_angle_deg:.1f} to "
        f"{check.entry_angle_deg:.1f} deg arm angle: {check.window_s * 1e3:.1f} ms"
    )
    finished = (
        f"done after {check.move_time_s * 1e3:.1f} ms (arm at {check.finish_angle_deg:.1f} deg, "
        f"needle {check.needle_z_at_finish_mm:+.1f} mm)"
        if math.isfinite(check.move_time_s)
        else "never settles (lost steps)"
    )
    print(
        f"a {check.width_mm:.3f} mm move ({check.steps} steps at {check.rate_steps_s:g} steps/s): {finished}"
    )
    print(
        "FLAGGED: the needle is still moving sideways when it enters the fabric"
        if check.flagged
        else f"fits, with {check.margin_s * 1e3:.1f} ms to spare"
    )
    result = {"move": check.as_dict()}
    if args.csv or args.plot:
        sewing = zigzag.sew(args.spm, needle, stitches=args.stitches, **options)
        result["stitches"] = sewing.summary
        s = sewing.summary
        print(
            f"{s['stitches']} zigzag stitches: worst sideways error in the fabric {s['worst_error_in_fabric_mm']:.3f} mm"
            + (
                f", moving in the fabric in stitches {s['stitches_moving_in_fabric']}"
                if s["stitches_moving_in_fabric"]
                else ""
            )
        )
        if args.csv:
            write_table(
                args.csv,
                sewing.columns,
                comments=[f"needle: {needle.name}", f"stitches_per_minute: {args.spm:g}"],
            )
        if args.plot:
            zigzag.plot_sewing(sewing, args.plot)
    if args.json:
        with atomic_file(args.json) as handle:
            json.dump(_finite(result), handle, indent=2)
    return 1 if check.flagged else 0
