"""`mechanism inspect-recording`: what a recording holds, before any fit."""

from __future__ import annotations

ORDER = 59


def register(subparsers) -> None:
    from mechanism.cli._recording import add_recording_map_argument

    parser = subparsers.add_parser(
        "inspect-recording",
        help="show what a bench recording holds (columns, units, rate, ranges, encoder step, gaps, excitation) before any fit",
        description=(
            "Read a recording (CSV/TSV plain or .gz/.bz2/.xz/.zip, MATLAB .mat, Parquet, Feather, TDMS, JSON) with "
            "the column map of --recording-map or the --machine description's [recording] table, and print the "
            "columns found and chosen, units and conversions, sample rate, duration, each signal's range, the "
            "encoder's quantisation step, gaps in the sampling, and whether the recording excites the machine "
            "enough to identify inertia, viscous and Coulomb friction and the winding's L/R. Nothing is fitted. "
            "Exit 2 when the recording cannot be used by identify/diagnose as it is."
        ),
        epilog="example: mechanism inspect-recording servo.jsonl --recording-map servo.toml --json out/inspect.json",
    )
    parser.add_argument("recording", metavar="REC", help="the recording file")
    parser.add_argument(
        "--machine",
        metavar="FILE.toml",
        help="machine description whose [recording] table maps the columns",
    )
    add_recording_map_argument(parser)
    parser.add_argument(
        "--json", metavar="OUT.json", help="write the inspection as JSON (units in every key)"
    )
    parser.add_argument(
        "--split",
        metavar="DIR",
        help="cut the recording at its gaps into gap-free pieces of 2 s or more, written as CSVs (the map "
        "applied) into DIR: a fleet for diagnose --out (gaps are never interpolated over)",
    )
    parser.set_defaults(
        handler=run,
        inputs=("recording", "machine", "recording_map"),
        outputs=("json",),
        output_dirs=("split",),
    )


def run(args) -> int:
    import json
    import sys

    from mechanism.cli._recording import recording_map_from_args
    from mechanism.files.outputs import atomic_file
    from mechanism.sysid.inspect_recording import format_inspection, inspect_recording

    data = inspect_recording(args.recording, recording_map_from_args(args))
    if args.json:
        with atomic_file(args.json) as handle:
            json.dump(data, handle, indent=2)
            handle.write("\n")
    print(format_inspection(data))
    if args.split:
        from mechanism.sysid.inspect_recording import split_at_gaps

        pieces = split_at_gaps(args.recording, args.split, recording_map_from_args(args))
        print(
            f"wrote {len(pieces)} gap-free piece(s) into {args.split}: {', '.join(p.name for p in pieces)}"
        )
        return 0
    if not data.get("usable", False):
        problem = (data.get("problems") or ["not usable"])[0]
        sys.stderr.write(f"error: {problem}\n")
        return 2
    return 0
