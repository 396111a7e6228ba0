"""``mechanism tool``: the tool's motion over one shaft revolution (and a described hook's timing).

``mechanism needle`` is the sewing machine's name of this verb: the same numbers, with the
table's historical column names (``arm_angle_deg``, ``needle_z_mm``, ...).
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from mechanism.cli._machine import add_machine_arguments, machine_from_args
from mechanism.files.limits import number

if TYPE_CHECKING:  # the simulator's imports belong to the run, not to every start of the command
    from mechanism.inspection.tool import ColumnNames

ORDER = 20

EPILOG = """\
CSV columns: shaft_angle_deg (0 = the described zero), tool_z_mm (the described tool site above
the described plate's top), tool_velocity_mm_per_rad (= mm/s per rad/s of shaft speed),
tool_acceleration_mm_per_rad2 (= mm/s^2 per (rad/s)^2 at constant shaft speed), with --speed
also tool_velocity_mm_s and tool_acceleration_mm_s2, then hook_angle_deg (a described hook
joint from the assembly pose) and hook_point_to_tool_mm (the hook point to the tool axis, across
the hook axis; empty without a hook). The key numbers are printed and repeated as '#' comment
lines at the top of the CSV.

'mechanism needle' computes the same numbers and writes them under the sewing machine's
historical column names: arm_angle_deg, needle_z_mm, needle_velocity_mm_per_rad,
needle_acceleration_mm_per_rad2, needle_velocity_mm_s, needle_acceleration_mm_s2,
hook_angle_deg, hook_point_to_needle_mm.

examples:
  mechanism tool --machine press --csv out/tool.csv --plot out/tool.png
  mechanism tool --machine my_machine.toml --csv out/tool.csv --speed 1000
"""


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "tool",
        help="the tool's position, velocity, acceleration (and a hook's timing) over one shaft revolution",
        description=(
            "Inspect the motion of a machine's described tool ([tool] site) over one shaft revolution "
            "(shaft angle 0 = the described zero): print the stroke, the top and bottom dead-centre shaft "
            "angles and the peak velocity and acceleration; where the description names a rotary hook "
            "([hook]), also the shaft angle where the hook's point passes the tool, the tool's rise above "
            "bottom dead centre there and the hook point's clearance to the tool."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_options(parser, angle="shaft angle", speed="shaft speed")
    parser.set_defaults(handler=run)


def add_options(parser: argparse.ArgumentParser, angle: str, speed: str) -> None:
    """The machine, the outputs, the sampling and the speed: the options of ``tool`` and of
    ``needle``, in the words of each (``angle``: what the table runs over; ``speed``: what
    --speed is)."""
    add_machine_arguments(parser)
    parser.add_argument(
        "--csv",
        required=True,
        metavar="OUT.csv",
        help="table over the revolution (units in column names)",
    )
    parser.add_argument(
        "--plot",
        metavar="OUT.png",
        help=f"position, velocity and acceleration vs {angle} (PNG, SVG or PDF)",
    )
    parser.add_argument(
        "--samples",
        type=int,
        default=360,
        metavar="N",
        help=f"equally spaced {angle}s over the revolution (36 to 36000, default 360 = 1 deg)",
    )
    parser.add_argument(
        "--speed",
        type=number(0, 1e5, "rpm", low_open=True),
        metavar="RPM",
        help=f"{speed} [rpm]: adds velocity in mm/s and acceleration in mm/s^2 at that constant speed",
    )
    parser.set_defaults(inputs=("machine", "model"), outputs=("csv", "plot"), plots=("plot",))


def run(args) -> int:
    return run_with(args, "tool")


def run_with(args, names: ColumnNames) -> int:
    """Compute, write the CSV (column ``names``) and the plot, print the summary: the one body of
    ``mechanism tool`` and ``mechanism needle``."""
    from mechanism.inspection.tool import plot, tool_motion, write_csv

    motion = tool_motion(machine_from_args(args), samples=args.samples, speed_rpm=args.speed)
    write_csv(motion, args.csv, names)
    if args.plot:
        plot(motion, args.plot)
    print("\n".join(motion.summary_lines()))
    print(f"wrote {args.csv}" + (f" and {args.plot}" if args.plot else ""))
    return 0
