"""The motor inputs every dynamic verb shares: ``--voltage V`` (the one motor) or ``--voltage JOINT=V``
(repeatable), ``--goal JOINT=RAD`` for a servo, ``--current JOINT=A`` for a current drive."""

from __future__ import annotations

import argparse


def voltage_text(text: str):
    """``--voltage``: a number of volts (the one motor) or JOINT=V; both checked against the described
    motor's rated voltage when the run starts."""
    if "=" in text:
        return text
    from mechanism.files.limits import number

    return number(0, 1000, "V")(text)


def add_input_arguments(
    parser: argparse.ArgumentParser, group=None, what: str = "dynamic simulation from rest"
) -> None:
    (group or parser).add_argument(
        "--voltage",
        action="append",
        type=voltage_text,
        metavar="V|JOINT=V",
        help=f"{what} under this motor voltage [V]: V (0 to the motor's rated_voltage_V, default 30) for the one (main) motor, or JOINT=V for the dc motor "
        "on JOINT (repeat for several motors; negative reverses)",
    )
    parser.add_argument(
        "--goal",
        action="append",
        default=[],
        metavar="JOINT=RAD",
        help="goal angle [rad] of the servo on JOINT, the joint's own coordinate (0 at the export's pose; "
        "repeatable; default: hold where the run starts)",
    )
    parser.add_argument(
        "--current",
        action="append",
        default=[],
        metavar="JOINT=A",
        help="current command [A] of the current drive on JOINT (repeatable; default 0)",
    )


def has_inputs(args: argparse.Namespace) -> bool:
    return bool(
        getattr(args, "voltage", None)
        or getattr(args, "goal", None)
        or getattr(args, "current", None)
    )


def inputs_from_args(args: argparse.Namespace, description):
    """The run's inputs: the main motor's voltage (a number, ``--voltage V`` alone) or a mapping
    joint -> input in its unit (V, goal rad, A)."""
    from mechanism.errors import UserError
    from mechanism.machine.machine import input_unit
    from mechanism.physics.inputs import parse_joint_values

    units = {joint: input_unit(description, joint) for joint in description.drive_tables}
    voltages = list(getattr(args, "voltage", None) or [])
    plain = [v for v in voltages if not isinstance(v, str)]
    if plain and len(voltages) > 1:
        raise UserError("--voltage V is for one motor; give --voltage JOINT=V for each of several")
    inputs: dict = {}
    if plain:
        if units[description.motor_joint] != "V":
            option = "--goal" if units[description.motor_joint] == "rad" else "--current"
            raise UserError(
                f"--voltage {plain[0]:g}: the main motor on {description.motor_joint} is a "
                f"{description.motor['type']} drive; give {option} {description.motor_joint}=..."
            )
        if not (args.goal or args.current):
            return plain[0]
        inputs[description.motor_joint] = plain[0]
    inputs.update(
        parse_joint_values([v for v in voltages if isinstance(v, str)], "--voltage", "V", units)
    )
    inputs.update(parse_joint_values(args.goal, "--goal", "rad", units))
    inputs.update(parse_joint_values(args.current, "--current", "A", units))
    return inputs
