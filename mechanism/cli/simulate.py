"""mechanism simulate: run a described machine under a motor voltage."""

from __future__ import annotations

from mechanism.files.limits import number

import argparse
import sys

from mechanism.cli._inputs import add_input_arguments, has_inputs, inputs_from_args
from mechanism.cli._machine import add_machine_arguments, description_from_args

ORDER = 30
WARM_DEFAULT_S = 120.0  # the thesis's warm column: after 2 minutes of running


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate",
        help="run the machine under a motor voltage (DC motor, couplings, friction, loads)",
        description=(
            "Simulate a described machine in MuJoCo from rest: the motor as a native <dcmotor> on the described "
            "motor joint (Kt != Ke kept exactly), the model's couplings and loops, the described friction per "
            "joint (Coulomb, viscous, Stribeck, position-dependent), optional fabric on the tool. Default machine: "
            "the shipped Sapphire 870 (Domel motor R 1.1 ohm, Kt 0.017 N m/A, Ke 0.021 V s/rad, belt 8:1). "
            "Writes a CSV with units in every column name; its arm_* columns are the described shaft's."
        ),
        epilog="example: mechanism simulate --voltage 12.49 --duration 3 --csv out/run.csv --summary",
    )
    add_machine_arguments(parser)
    source = parser.add_mutually_exclusive_group()
    add_input_arguments(parser, source, "a run")
    source.add_argument(
        "--profile",
        metavar="FILE",
        help="input profile CSV: time_s (or time) and voltage_V (or voltage) for the main motor, or one "
        "column per motor named JOINT_V (dc), JOINT_rad (servo goal) or JOINT_A (current drive); "
        "each value holds until the next time (zero-order hold)",
    )
    source.add_argument(
        "--duty",
        type=float,
        metavar="PCT",
        help="PWM duty cycle [%%] of the described supply; converted to motor voltage with its "
        "measured (non-linear) map ([supply] in the description)",
    )
    parser.add_argument(
        "--duration",
        type=float,
        metavar="S",
        help="simulated time [s] (default with --profile: the profile's last time)",
    )
    warm = parser.add_mutually_exclusive_group()
    warm.add_argument(
        "--warm-s",
        type=number(0, 1e6, "s"),
        default=0.0,
        metavar="S",
        help="the machine after S seconds of running: friction warmed as the description's [warm] says",
    )
    warm.add_argument(
        "--warm",
        action="store_const",
        const=WARM_DEFAULT_S,
        dest="warm_s",
        help=f"shortcut for --warm-s {WARM_DEFAULT_S:g} (the thesis's warm column)",
    )
    parser.add_argument(
        "--layers",
        type=int,
        default=0,
        metavar="N",
        help="fabric layers under the tool (default 0)",
    )
    parser.add_argument(
        "--no-needle", action="store_true", help="tool removed: no fabric penetration load"
    )
    parser.add_argument(
        "--feeding",
        action="store_true",
        help="feed mechanism engaged (the description's [loads] feeding)",
    )
    parser.add_argument(
        "--belt-tension",
        choices=["low", "normal", "hard"],
        default="normal",
        help="belt tension setting (the description's [loads]; default normal)",
    )
    parser.add_argument(
        "--start-angle",
        type=number(-3600, 3600, "deg"),
        default=0.0,
        metavar="DEG",
        help="shaft angle at rest at the start [deg], 0 = the described zero",
    )
    parser.add_argument(
        "--inductance",
        type=number(0, 1, "H"),
        metavar="H",
        help="motor winding inductance [H] (default: the description's)",
    )
    parser.add_argument(
        "--cogging",
        type=number(0, 10, "N m"),
        metavar="NM",
        help="motor cogging torque amplitude [N m] (periods per turn: the description's)",
    )
    parser.add_argument(
        "--thermal", action="store_true", help="winding resistance rises with temperature"
    )
    parser.add_argument(
        "--timestep",
        type=number(0.01, 2, "ms"),
        metavar="MS",
        help="simulation time step [ms] (default: the description's, else 0.5); loops and belts stiffen "
        "with it: at ~1000 rpm the Sapphire's crank loop opens ~0.2 mm at 0.5 ms, ~0.05 mm at 0.25 ms",
    )
    parser.add_argument(
        "--reduced",
        action="store_true",
        help="use the fast reduced 1-DOF model instead of the full multibody model",
    )
    parser.add_argument(
        "--rate",
        type=number(0, 1e5, "Hz", low_open=True),
        default=1000.0,
        metavar="HZ",
        help="output sample rate [Hz] (default 1000)",
    )
    parser.add_argument("--csv", metavar="OUT.csv", help="write the time series")
    parser.add_argument(
        "--plot", metavar="OUT.png", help="plot speed, current and tool height over time"
    )
    parser.add_argument(
        "--summary",
        action="store_true",
        help="print mean/min/max shaft speed [rpm] over the last second",
    )
    parser.set_defaults(
        handler=run,
        inputs=("profile", "machine", "model"),
        outputs=("csv", "plot"),
        plots=("plot",),
    )


def motor_inputs_from_args(args: argparse.Namespace, machine):
    """The run's inputs: one VoltageProfile for the main motor (--voltage V, --duty, a voltage_V
    profile) or joint -> input (--voltage JOINT=V, --goal, --current, JOINT_* profile columns)."""
    from mechanism.machine.machine import input_unit
    from mechanism.physics.inputs import VoltageProfile, read_motor_profiles

    given = inputs_from_args(args, machine.description)
    if not isinstance(given, dict):
        return VoltageProfile.constant(given)
    main = None
    if args.duty is not None:
        main = VoltageProfile.from_duty(args.duty, machine.duty_map())
    elif args.profile is not None:
        from mechanism.files.tables import read_table

        header = read_table(
            args.profile,
            required=["time"],
            optional=["voltage", "voltage_V"],
            aliases={"time": ["time_s"]},
            what="input profile",
        )
        if "voltage" in header.columns or "voltage_V" in header.columns:
            main = VoltageProfile.from_csv(args.profile)
        else:
            units = {joint: input_unit(machine.description, joint) for joint in machine.drives}
            return {**read_motor_profiles(args.profile, units), **given}
    if main is not None and not given:
        return main
    return {**({machine.motor_joint: main} if main is not None else {}), **given}


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    import numpy as np

    from mechanism.dynamics.simulation import plot_simulation, simulate
    from mechanism.errors import UserError
    from mechanism.files.tables import write_table
    from mechanism.cli._choices import chosen
    from mechanism.machine.machine import (
        BELT_TENSIONS,
        Machine,
        MachineConfig,
        motor_from_description,
    )
    from mechanism.physics.motor import Thermal

    if not (args.csv or args.plot or args.summary):
        raise UserError("nothing to output: give --csv, --plot and/or --summary")
    if (
        args.duration is not None and 0 < args.duration <= 3600
    ):  # else the simulation names the range
        from mechanism.files.limits import check_elements

        check_elements(args.duration * args.rate * 16, "--duration x --rate")
    if not has_inputs(args) and args.profile is None and args.duty is None:
        raise UserError("no input: give --voltage, --profile, --duty, --goal or --current")
    description = description_from_args(args)
    motor = None
    if description.motor["type"] == "dc":
        motor = motor_from_description(description.motor)
        options = {"inductance_H": args.inductance, "cogging_Nm": args.cogging}
        motor = replace(motor, **{k: v for k, v in options.items() if v is not None})
        if args.thermal and motor.thermal is None:
            motor = replace(motor, thermal=Thermal())
    elif args.inductance is not None or args.cogging is not None or args.thermal:
        raise UserError(
            f"--inductance, --cogging and --thermal change a dc motor; the main motor on "
            f"{description.motor_joint} is a {description.motor['type']} drive"
        )
    config = MachineConfig(
        warm_s=args.warm_s,
        layers=args.layers,
        needle=not args.no_needle,
        feeding=args.feeding,
        belt_tension=chosen(args.belt_tension, BELT_TENSIONS, "--belt-tension"),
        motor=motor,
        timestep_s=None if args.timestep is None else args.timestep * 1e-3,
    )
    machine = Machine(description, config)
    voltage = motor_inputs_from_args(args, machine)
    duration = args.duration
    if duration is None:
        ends = [p.end_s for p in (voltage.values() if isinstance(voltage, dict) else [voltage])]
        if args.profile is None or max(ends) <= 0:
            raise UserError("--duration is required (simulated time in seconds)")
        duration = max(ends)
    start = float(np.deg2rad(args.start_angle))
    if args.reduced:
        from mechanism.dynamics.reduced import ReducedModel

        if isinstance(voltage, dict) or len(machine.drives) > 1:
            raise UserError(
                "the reduced model drives one dc motor with --voltage, --duty or a voltage_V profile"
            )
        result = ReducedModel(machine).simulate(
            voltage, duration, start_angle_rad=start, sample_rate_hz=args.rate
        )
    else:
        result = simulate(
            voltage,
            duration,
            machine=machine,
            start_angle_rad=start,
            sample_rate_hz=args.rate,
            progress=True,
        )
    if args.csv:
        comments = [
            f"mechanism simulate: machine {machine.name} ({machine.model_path.name}); shaft {machine.shaft_joint}",
            f"warm_s: {args.warm_s:g}; layers: {args.layers}; needle: {not args.no_needle}; feeding: {args.feeding}; "
            f"belt tension: {args.belt_tension}; model: {'reduced' if args.reduced else 'full multibody'}",
        ]
        write_table(args.csv, result.columns(), comments=comments)
    if args.plot:
        plot_simulation(result, args.plot)
    if args.summary:
        last = min(1.0, duration)
        s = result.speed_summary(last)
        print(
            f"shaft speed over the last {last:g} s: mean {s['mean_rpm']:.1f} rpm, "
            f"min {s['min_rpm']:.1f} rpm, max {s['max_rpm']:.1f} rpm"
        )
    sys.stdout.flush()
    return 0
