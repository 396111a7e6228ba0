"""``mechanism probe``: watch points of parts and the loads in joints over a cycle or a run."""

from __future__ import annotations

from mechanism.files.limits import number

from mechanism.cli._inputs import add_input_arguments, has_inputs, inputs_from_args
from mechanism.cli._machine import (
    DRIVER_HELP,
    add_machine_arguments,
    description_from_args,
    inspection_target,
)

ORDER = 40


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "probe",
        help="sensor probes: position/velocity/acceleration of a point, force/torque in a joint",
        description=(
            "Add MuJoCo sensors to the model and record them over a kinematic cycle (--cycle: the shaft "
            "turning at a constant speed, loads by rigid inverse dynamics without friction) or a dynamic "
            "simulation (--voltage and --duration: motor, friction and loads). All values are in the world "
            "frame (z up). position [mm], velocity [m/s], acceleration [m/s^2, gravity removed]; force [N] and "
            "torque [N m]: the load the parent side of a joint exerts on its child side (for a loop joint: on "
            "its follower), torque about the joint anchor (or --point); the torque component along a hinge "
            "axis is what its drive transmits, the rest is the bearing's bending moment. Writes a CSV with "
            "units in every column name."
        ),
        epilog=(
            "examples: mechanism probe --part needle_tip --quantity position,velocity,acceleration --cycle --csv tip.csv; "
            "mechanism probe --part crank_pin --quantity force,torque --part needle_bar --quantity force "
            "--voltage 12 --duration 2 --csv loads.csv --plot loads.png"
        ),
    )
    add_machine_arguments(parser)
    parser.add_argument(
        "--part",
        action="append",
        required=True,
        metavar="NAME[,NAME...]",
        help="what to probe: a CAD part (its part frame), a user-named frame (needle_tip) or a body; "
        "for force/torque, a joint name (joints come first), else the load a part's body receives "
        "from its parent. Repeat for several probe groups",
    )
    parser.add_argument(
        "--quantity",
        action="append",
        required=True,
        metavar="Q[,Q...]",
        help="position, velocity, acceleration, force, torque; once for all --part groups or once per group",
    )
    parser.add_argument(
        "--point",
        action="append",
        default=[],
        metavar="X,Y,Z",
        help="point [mm] in the part frame (for force/torque: the moment reference in the joint's body "
        "frame, from the joint anchor); once for all groups or once per group (default: the origin)",
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--cycle", action="store_true", help="one kinematic cycle of the shaft at --speed"
    )
    add_input_arguments(parser, mode)
    parser.add_argument(
        "--duration",
        type=number(0, 3600, "s", low_open=True),
        metavar="S",
        help="simulated time [s] (with --voltage)",
    )
    parser.add_argument(
        "--speed",
        type=number(0, 1e5, "rpm"),
        default=600.0,
        metavar="RPM",
        help="shaft speed for --cycle [rpm] (default 600; 0 = static)",
    )
    parser.add_argument(
        "--revolutions",
        type=number(0, 100, low_open=True),
        default=1.0,
        metavar="N",
        help="shaft revolutions for --cycle (default 1)",
    )
    parser.add_argument(
        "--resolution",
        type=number(0.01, 360, "deg"),
        default=0.5,
        metavar="DEG",
        help="shaft angle step for --cycle [deg] (default 0.5)",
    )
    parser.add_argument("--driver", metavar="JOINT", help=DRIVER_HELP)
    parser.add_argument("--csv", required=True, metavar="OUT.csv", help="write the probe table")
    parser.add_argument(
        "--plot",
        metavar="OUT.png",
        help="plot every probe over the shaft angle (cycle) or time (simulation)",
    )
    parser.set_defaults(
        handler=run, inputs=("machine", "model"), outputs=("csv", "plot"), plots=("plot",)
    )


def run(args) -> int:
    from mechanism.errors import UserError
    from mechanism.inspection.probes import parse_probes, run_probes

    dynamic = has_inputs(args)
    if not (args.cycle or dynamic):
        raise UserError(
            "give --cycle (a kinematic cycle) or a motor input (--voltage, --goal, --current) for a dynamic run"
        )
    if args.cycle and (args.goal or args.current):
        raise UserError("--goal and --current belong to a dynamic run, not to --cycle")
    if dynamic and args.duration is None:
        raise UserError("--voltage needs --duration (simulated time in seconds)")
    if args.cycle and args.duration is not None:
        raise UserError("--duration belongs to a dynamic run (--voltage), not to --cycle")
    probes = parse_probes(args.part, args.quantity, args.point)
    path, driver, description = inspection_target(args)
    description = description or description_from_args(args)
    inputs = inputs_from_args(args, description) if dynamic else None
    result = run_probes(
        probes,
        path,
        inputs,
        args.duration,
        args.speed,
        args.revolutions,
        args.resolution,
        driver,
        progress=dynamic,
        description=description,
    )
    result.write_csv(args.csv)
    if args.plot:
        result.plot(args.plot, probes)
    print(
        f"wrote {args.csv} ({len(result.columns['time_s'])} samples, {len(result.columns) - 2} columns)"
    )
    return 0
