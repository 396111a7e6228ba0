"""The described drive's numbers for identify, diagnose and testbench: those of the machine of
``--machine``, or without it of the default shipped machine (:func:`mechanism.api.drive_nominal`:
its description and CAD model, or its ``[lumped]`` numbers where it has them)."""

from __future__ import annotations


def drive_nominal(args=None):
    """The :class:`~mechanism.dynamics.lumped.DriveNominal` of the machine the verb works on."""
    from mechanism.api import drive_nominal as build

    if args is not None and getattr(args, "machine", None):
        from mechanism.machine.machine import load_machine

        return build(load_machine(args.machine))
    return build(None)


def thesis_table2(valid_below_V: float | None = None):
    """The steady-state friction fit of the thesis's Table 2 (its input data) with the
    shipped motor."""
    from mechanism.data.reference import thesis
    from mechanism.sysid.steady_state import table2

    ref = thesis()
    limit = valid_below_V if valid_below_V is not None else ref["main_motor"]["model_validity_V"][1]
    return table2(ref["steady_state_speed_table_2"], drive_nominal().motor, limit)
