"""``mechanism needle``: needle-bar motion and hook timing over one arm-shaft revolution.

The sewing machine's name of ``mechanism tool`` (mechanism.cli.tool): the same numbers, with the
table's historical column names, header and help, unchanged (scripts read its files).
"""

from __future__ import annotations

import argparse

from mechanism.cli.tool import add_options

ORDER = 21  # after its generic name, mechanism tool

EPILOG = """\
CSV columns: arm_angle_deg, needle_z_mm (needle point above the needle-plate top),
needle_velocity_mm_per_rad (= mm/s per rad/s of arm speed), needle_acceleration_mm_per_rad2
(= mm/s^2 per (rad/s)^2 at constant arm speed), with --speed also needle_velocity_mm_s and
needle_acceleration_mm_s2, then hook_angle_deg (hook joint from the assembly pose) and
hook_point_to_needle_mm (hook point to the needle axis, across the hook axis). The key
numbers are printed and repeated as '#' comment lines at the top of the CSV.

examples:
  mechanism needle --csv out/needle.csv --plot out/needle.png
  mechanism needle --model my_mjcf/sewing_machine.xml --csv out/needle.csv --speed 1000
"""


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "needle",
        help="needle-bar position, velocity, acceleration and hook timing over one arm revolution "
        "(the sewing machine's name of 'tool', with its historical column names)",
        description=(
            "Inspect the needle motion of a converted machine over one arm-shaft revolution (arm angle 0 = "
            "needle top dead centre): print the stroke, the top and bottom dead-centre arm angles, and the arm "
            "angle where the rotary hook's point passes the needle (with the needle's rise above bottom dead "
            "centre there and the hook point's clearance to the needle)."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_options(parser, angle="arm angle", speed="arm-shaft speed")
    parser.set_defaults(handler=run)


def run(args) -> int:
    from mechanism.cli.tool import run_with

    return run_with(args, "needle")
