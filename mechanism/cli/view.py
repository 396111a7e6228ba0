"""``mechanism view``: the machine's motion as a self-contained HTML animation (meshcat)."""

from __future__ import annotations

from mechanism.files.limits import number

from mechanism.cli._inputs import add_input_arguments, has_inputs, inputs_from_args
from mechanism.cli._machine import (
    DRIVER_HELP,
    add_machine_arguments,
    description_from_args,
    inspection_target,
)

ORDER = 50


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "view",
        help="animate the machine in a self-contained HTML page (meshcat), or serve it live",
        description=(
            "Build a meshcat scene of the model (its visual meshes in the export's colours) and animate one shaft "
            "revolution (default), a dynamic simulation (--voltage and --duration) or a bench recording "
            "(--recording: CSV with time [s], voltage [V], shaft_angle (or arm_angle) [rad, 0 = the described zero], replayed kinematically). "
            "The HTML embeds meshcat's viewer and opens in a browser with no server and no network. Probe markers "
            "(--probe) and clearance minima (--pairs: markers at the closest points and a line between them) can "
            "be overlaid."
        ),
        epilog="example: mechanism view --frames 120 --probe needle_tip --pairs needle:hook --html out/machine.html",
    )
    add_machine_arguments(parser)
    motion = parser.add_mutually_exclusive_group()
    motion.add_argument("--cycle", action="store_true", help="one shaft revolution (the default)")
    add_input_arguments(parser, motion)
    motion.add_argument(
        "--recording",
        metavar="FILE",
        help="replay a recording CSV (time, voltage, shaft_angle or arm_angle) kinematically",
    )
    parser.add_argument(
        "--duration",
        type=number(0, 3600, "s", low_open=True),
        metavar="S",
        help="simulated time [s] (with --voltage)",
    )
    parser.add_argument(
        "--frames", type=int, default=120, metavar="N", help="animation frames (default 120)"
    )
    parser.add_argument(
        "--probe",
        action="append",
        default=[],
        metavar="NAME",
        help="mark a part frame or named frame (repeatable)",
    )
    parser.add_argument(
        "--pairs", metavar="A:B[,C:D...]", help="show the clearance minimum of these part pairs"
    )
    parser.add_argument("--driver", metavar="JOINT", help=DRIVER_HELP)
    parser.add_argument("--html", metavar="OUT.html", help="write the self-contained animation")
    parser.add_argument(
        "--serve",
        action="store_true",
        help="start a live meshcat server on localhost and wait (Ctrl-C ends)",
    )
    parser.set_defaults(handler=run, inputs=("machine", "model", "recording"), outputs=("html",))


def run(args) -> int:
    from mechanism.errors import UserError
    from mechanism.inspection.viewer import view

    if not args.html and not args.serve:
        raise UserError("nothing to do: give --html OUT.html and/or --serve")
    dynamic = has_inputs(args)
    if dynamic and args.recording:
        raise UserError(
            "choose one motion: a simulation (--voltage, --goal, --current) or --recording"
        )
    if dynamic and args.duration is None:
        raise UserError("--voltage needs --duration (simulated time in seconds)")
    if args.duration is not None and not dynamic:
        raise UserError("--duration belongs to a simulated motion (--voltage)")
    path, driver, description = inspection_target(args)
    description = description or description_from_args(args)
    summary = view(
        args.html,
        path,
        inputs_from_args(args, description) if dynamic else None,
        args.duration,
        args.recording,
        args.frames,
        args.probe,
        args.pairs,
        serve=args.serve,
        driver=driver,
        description=description,
    )
    for note in summary["notes"]:
        print(note)
    if args.html:
        print(f"wrote {args.html} ({summary['frames']} frames)")
    if args.serve:
        import time

        print(f"meshcat is serving the scene at {summary['url']} (Ctrl-C to stop)", flush=True)
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            return 0
    return 0
