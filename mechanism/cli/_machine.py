"""The options every machine verb shares: which machine (``--machine``) and which model."""

from __future__ import annotations

import argparse

MACHINE_HELP = (
    "machine description (TOML: the motor and shaft joints, the shaft's zero, motor datasheet, "
    "friction, tool); default: the shipped Sapphire 870 sewing machine"
)


def add_machine_arguments(parser: argparse.ArgumentParser, model: bool = True) -> None:
    parser.add_argument("--machine", metavar="FILE.toml", help=MACHINE_HELP)
    if model:
        parser.add_argument(
            "--model",
            metavar="FILE.xml",
            help="use this MJCF instead of the description's model (same joint and site names)",
        )


def description_from_args(args: argparse.Namespace):
    """The description named by ``--machine`` (default: shipped), with ``--model`` applied."""
    from dataclasses import replace
    from pathlib import Path

    from mechanism.machine.machine import resolve_description

    description = resolve_description(getattr(args, "machine", None))
    if getattr(args, "model", None):
        description = replace(description, model=Path(args.model))
    return description


def machine_from_args(args: argparse.Namespace, extend=None, **config):
    """The Machine of ``--machine``/``--model`` under the operating conditions ``config``."""
    from mechanism.machine.machine import Machine, MachineConfig

    return Machine(description_from_args(args), MachineConfig(**config), extend=extend)


def inspection_target(args: argparse.Namespace):
    """(model path, driver joint, description or None) for the kinematic verbs: ``--model``
    alone inspects a bare MJCF (driver: ``--driver`` or the guessed shaft); otherwise the
    described machine (driver: ``--driver`` or its shaft joint)."""
    from mechanism.machine.models import load_model, model_path, resolve_model

    if getattr(args, "model", None) and not getattr(args, "machine", None):
        path = model_path(args.model)
        if args.driver:
            return path, args.driver, None
        from mechanism.machine.roles import guess_driver

        return path, guess_driver(load_model(path)), None
    description = description_from_args(args)
    return resolve_model(description), args.driver or description.shaft_joint, description


DRIVER_HELP = (
    "the joint turned through the cycle (default: the machine's shaft joint; with --model alone, the "
    "model's slowest fully revolving joint)"
)
