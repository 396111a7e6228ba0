"""`mechanism identify`: fit the baseline model to a bench recording."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mechanism.sysid.lumped_baseline import Baseline

ORDER = 60


def add_recording_arguments(parser, what: str, optional: bool = False) -> None:
    """Options shared by identify and diagnose."""
    from mechanism.cli._recording import add_recording_map_argument

    parser.add_argument(
        "recording",
        metavar="REC.csv",
        nargs="?" if optional else None,
        help="bench recording: CSV with columns time [s], voltage [V], shaft_angle (or arm_angle) [rad, "
        "unwrapped, 0 = the described zero], optional current [A]; leading '#' lines are metadata; "
        "also .csv.gz/.bz2/.xz/.zip, .tsv, .mat, .parquet, .feather, .tdms, .json/.jsonl, other "
        "columns and units through --recording-map",
    )
    parser.add_argument(
        "--baseline",
        choices=["lumped", "multibody"],
        default=None,
        help="lumped: thesis eq. 15-16 (constant inertia, viscous + Coulomb friction, DC motor through "
        "the belt); multibody: the CAD model's reduced 1-DOF dynamics (angle-dependent inertia "
        "and gravity) with fitted friction (default lumped; multibody for a --machine whose shaft "
        "rocks between stops, where the angle-dependent terms are the machine)",
    )
    parser.add_argument(
        "--machine",
        metavar="FILE.toml",
        help="machine description: the drive (ratio, motor, CAD inertia, friction) every bound and start "
        "scales from (default: the shipped Sapphire 870's thesis-identified numbers)",
    )
    parser.add_argument(
        "--model",
        metavar="MJCF",
        help="MJCF for --baseline multibody (default: the shipped sewing machine)",
    )
    add_recording_map_argument(parser)
    parser.add_argument(
        "--json",
        metavar="OUT.json",
        help=f"write the {what} as JSON (rmse in rad/s of shaft velocity)",
    )
    parser.add_argument(
        "--report", metavar="DIR", help="write an HTML report with plots to DIR (DIR/index.html)"
    )


def resolve_baseline(args, nominal) -> Baseline:
    """The baseline asked for, else multibody for a described machine whose shaft rocks (its
    inertia and gravity vary over the travel), else lumped."""
    from mechanism.cli._choices import chosen
    from mechanism.sysid.lumped_baseline import BASELINES

    if args.baseline:
        return chosen(args.baseline, BASELINES, "--baseline")
    rocks = (
        getattr(nominal, "travel_rad", None) is not None
        and getattr(nominal, "linkage", None) is not None
    )
    baseline: Baseline = "multibody" if rocks else "lumped"
    args.baseline = baseline
    return baseline


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "identify",
        help="fit inertia, viscous and Coulomb friction to a bench recording (simulation-error fit)",
        description=(
            "Fit the baseline model to a bench recording by simulation-error minimisation (scipy least squares; "
            "multiple shooting: 1 s segments restarted from the measured velocity). Fitted: inertia (motor side, "
            "kg m^2), viscous friction (motor side, N m s/rad), Coulomb friction (shaft side, N m) and the winding's "
            "L/R [s]; the motor constants stay at the datasheet values (R 1.1 ohm, Kt 0.017 N m/A, Ke 0.021 V s/rad) "
            "unless --free names them. Half of the segments (interleaved) are held out: the reported rmse [rad/s] "
            "is on them. With --table2 instead of a recording: the steady-state friction fit of the thesis's "
            "Table 2 (cold, warm 30 s, warm 2 min) and what its 24 V point says is missing."
        ),
        epilog="examples: mechanism identify rec.csv --json out/identify.json --report out/identify; "
        "mechanism identify --table2",
    )
    add_recording_arguments(
        parser, "fitted parameters with 1-sigma uncertainties and rmse", optional=True
    )
    parser.add_argument(
        "--table2",
        action="store_true",
        help="fit Coulomb and viscous friction to the thesis's Table 2 steady-state speeds (no recording)",
    )
    parser.add_argument(
        "--free",
        metavar="Kt,Ke,R",
        default="",
        help="motor constants to fit as well, comma-separated from R, Kt, Ke (default: none)",
    )
    parser.set_defaults(
        handler=run,
        inputs=("recording", "model", "machine", "recording_map"),
        outputs=("json",),
        output_dirs=("report",),
    )


def write_outputs(args, data: dict, report=None) -> None:
    """The JSON (atomically) and, with --report, the HTML report, for identify and diagnose."""
    import json

    from mechanism.files.outputs import atomic_file

    if getattr(args, "json", None):
        with atomic_file(args.json) as handle:
            json.dump(data, handle, indent=2)
    if getattr(args, "report", None) and report is not None:
        report(args.report)


def progress_bar(description: str):
    """A tqdm bar on stderr (hidden when stderr is not a terminal) and its tick function."""
    import sys

    from tqdm import tqdm

    bar = tqdm(desc=description, unit=" step", file=sys.stderr, disable=None, leave=False)

    def tick(what: str = "") -> None:
        if what:
            bar.set_postfix_str(what[:40])
        bar.update(1)

    return bar, tick


def run(args) -> int:
    from mechanism.cli._nominal import drive_nominal
    from mechanism.errors import UserError
    from mechanism.cli._recording import read_recording_from_args
    from mechanism.sysid.identification import identify

    if args.table2:
        return run_table2(args)
    if not args.recording:
        raise UserError("identify needs a recording REC.csv (or --table2)")
    free = tuple(x.strip() for x in args.free.split(",") if x.strip())
    rec = read_recording_from_args(args, args.recording)
    bar, tick = progress_bar("identify")
    with bar:
        nominal = drive_nominal(args)
        result = identify(
            rec,
            resolve_baseline(args, nominal),
            free,
            progress=lambda: tick(),
            model_path=args.model,
            nominal=nominal,
        )
        tick("writing the outputs")  # the report's plots take seconds
        from mechanism.sysid.report import identification_report

        write_outputs(args, result.to_json(), lambda folder: identification_report(result, folder))
    for name, value in result.params.items():
        unc = result.fit.uncertainties.get(name)
        print(
            f"{name:40s} {value:.5g}" + (f" +- {unc:.2g}" if unc == unc and unc is not None else "")
        )
    print(f"{'rmse (validation) [rad/s]':40s} {result.rmse:.4g}")
    return 0


def run_table2(args) -> int:
    from mechanism.cli._nominal import thesis_table2

    columns = thesis_table2()
    write_outputs(args, {name: col.to_json() for name, col in columns.items()})
    print(
        f"{'column':10s} {'Coulomb arm [N m]':>18s} {'viscous motor [N m s/rad]':>26s} {'24 V rpm pred/meas':>19s} {'supply short [V]':>17s}"
    )
    for name, col in columns.items():
        fit = col.fit
        print(
            f"{name:10s} {fit.coulomb_arm_Nm:9.3f} +- {fit.coulomb_sigma:5.3f} {fit.viscous_motor_side_Nm_s_per_rad:14.3g} +- "
            f"{fit.viscous_sigma:7.2g} {col.high_rpm_predicted:9.0f}/{col.high_rpm_measured:<9.0f} {col.supply_deficit_V:12.2f}"
        )
    return 0
