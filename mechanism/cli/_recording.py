"""The options every verb that reads a recording shares: ``--recording-map`` and the
``[recording]`` table of ``--machine``'s description."""

from __future__ import annotations

MAP_HELP = (
    "TOML with a [recording] table: which columns are time, voltage, shaft_angle, current, in which units, "
    "sign, offset, unwrapping (keys in docs/machine.md); wins over the [recording] table of --machine"
)


def add_recording_map_argument(parser) -> None:
    parser.add_argument("--recording-map", metavar="FILE.toml", help=MAP_HELP)


def recording_map_from_args(args):
    """The RecordingMap of ``--recording-map``, else of ``--machine``'s description, else None."""
    from mechanism.sysid.recording_map import resolve_recording_map

    description = None
    if getattr(args, "machine", None) and not getattr(args, "recording_map", None):
        from mechanism.machine.machine import resolve_description

        description = resolve_description(args.machine)
    return resolve_recording_map(description, getattr(args, "recording_map", None))


def read_recording_from_args(args, path):
    """The recording at ``path`` read with the map the options name."""
    from mechanism.sysid.recording import read_recording

    return read_recording(path, recording_map_from_args(args), motor_joint=main_motor(args))


def main_motor(args) -> str | None:
    """The described main motor's joint (its JOINT_V recording column is the voltage), with --machine."""
    if not getattr(args, "machine", None):
        return None
    from mechanism.machine.machine import resolve_description

    return resolve_description(args.machine).motor_joint
