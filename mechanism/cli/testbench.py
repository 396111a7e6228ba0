"""`mechanism testbench`: write a virtual bench recording with concealed effects."""

from __future__ import annotations

from mechanism.files.limits import number

ORDER = 70


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "testbench",
        help="write a virtual bench recording (CSV + truth JSON) with concealed effects",
        description=(
            "Simulate the sewing machine on a virtual test bench and write a recording in the bench "
            "CSV format (time [s], voltage [V], arm_angle [rad], current [A], 1 kHz): 4-20 V plateaus "
            "and 0 V stops in a per-seed random order, 5000-line encoder quantisation, current noise. "
            "The truth model is the thesis's lumped machine (parameters scattered per seed) plus the "
            "named effects; what is concealed goes to REC.truth.json next to the CSV, never into it. A --machine "
            "whose shaft rocks between stops is moved point to point inside its travel instead (voltages of both "
            "signs, 0 V rests), its truth carrying the CAD model's inertia and gravity over the travel and the stops; "
            "effects that need whole turns are refused."
        ),
    )
    parser.add_argument(
        "--effect",
        metavar="NAME[,NAME]",
        help="concealed effect(s), comma-separated; 'none' for the clean machine (see --list)",
    )
    parser.add_argument(
        "--machine",
        metavar="FILE.toml",
        help="machine description: the drive (ratio, motor, CAD inertia, friction) every bound and start "
        "scales from (default: the shipped Sapphire 870's thesis-identified numbers)",
    )
    parser.add_argument(
        "--seed",
        type=number(0, 2**32 - 1, integer=True),
        default=0,
        metavar="N",
        help="random seed: machine parameters, effect magnitudes, voltage profile, start angle, noise (default 0)",
    )
    parser.add_argument(
        "--duration",
        type=number(0, 3600, "s", low_open=True),
        default=60.0,
        metavar="S",
        help="recording length [s] (default 60)",
    )
    parser.add_argument(
        "--rate",
        type=number(100, 10000, "Hz"),
        default=1000.0,
        metavar="HZ",
        help="sample rate, 100-10000 Hz (default 1000)",
    )
    parser.add_argument(
        "--counts",
        type=number(500, 20000, integer=True),
        default=20000,
        metavar="N",
        help="encoder counts per shaft turn (default 20000)",
    )
    parser.add_argument(
        "-o",
        "--output",
        metavar="REC.csv",
        help="recording to write (REC.csv, REC.csv.gz, REC.parquet or REC.mat); the truth goes to REC.truth.json",
    )
    parser.add_argument(
        "--format",
        choices=["csv", "csv.gz", "parquet", "mat"],
        help="recording format (default: from the -o file name, which must agree); parquet needs "
        "pip install 'mechanism[parquet]'",
    )
    parser.add_argument(
        "--list",
        action="store_true",
        help="print the effect vocabulary with one line of physics each and exit",
    )
    parser.set_defaults(handler=run, outputs=("output", _truth_output))


def _truth_output(args):
    """REC.truth.json next to -o REC.csv (checked with the CSV before the run)."""
    from mechanism.testbench import truth_path_for

    from mechanism.errors import UserError

    try:
        return truth_path_for(args.output) if args.output else None
    except UserError:
        return None  # the run refuses the name itself


def run(args) -> int:
    from mechanism.errors import UserError
    from mechanism.testbench import EFFECTS, make_recording, truth_path_for, write_recording
    from mechanism.cli._choices import chosen
    from mechanism.files.formats import WRITE_FORMATS

    if args.list:
        width = max(map(len, EFFECTS))
        print(
            f"{'none':<{width}}  the clean machine: thesis lumped model, Coulomb + viscous friction, stick-slip"
        )
        for effect in EFFECTS.values():
            print(f"{effect.name:<{width}}  {effect.physics}")
        return 0
    if not args.effect or not args.output:
        raise UserError("testbench needs --effect NAME[,NAME] (or none) and -o REC.csv (or --list)")
    truth_path_for(args.output)  # a bad file name fails before the simulation runs
    if args.format:
        from mechanism.testbench.recording import recording_format

        if recording_format(args.output)[0] != args.format:
            raise UserError(
                f"--format {args.format} but the file name {args.output} ends as a {recording_format(args.output)[0]} file"
            )
        if args.format == "parquet":
            from mechanism.files.formats import require_pyarrow

            require_pyarrow(".parquet")
    from mechanism.cli._nominal import drive_nominal

    recording = make_recording(
        args.effect,
        seed=args.seed,
        duration_s=args.duration,
        nominal=drive_nominal(args),
        sample_rate_hz=args.rate,
        encoder_counts_per_rev=args.counts,
    )
    fmt = None if args.format is None else chosen(args.format, WRITE_FORMATS, "--format")
    csv_path, truth_path = write_recording(recording, args.output, fmt)
    what = ", ".join(recording.effects) or "no effect (clean)"
    print(f"wrote {csv_path} ({len(recording.time)} samples, {what}) and {truth_path}")
    return 0
