"""``mechanism sweep``: dynamic design variants (flywheel, counterweight, pulley ratio, motor, friction, supply)."""

from __future__ import annotations

from mechanism.cli._batch import add_batch_arguments, backend_from_args, check_batch_arguments
from mechanism.cli._machine import add_machine_arguments
from mechanism.files.limits import number

ORDER = 47


def register(subparsers) -> None:
    from mechanism.inspection.sweep_metrics import METRICS

    parser = subparsers.add_parser(
        "sweep",
        help="run dynamic design variants (flywheel, counterweight, pulley ratio, motor, friction, supply) and tabulate what they do",
        description=(
            "Run every variant of a variants file from rest under a voltage step on the reduced 1-DOF model (the "
            "exact equation of the linkage, ~1000x real time on one core) and write one CSV row per variant: its parameters, "
            "then "
            + ", ".join(METRICS)
            + ". Targets (mechanism-variants/1, docs/sweeps.md): inertia:<joint>_kgm2 "
            "(a flywheel: inertia added about a frame-mounted joint's axis), mass:<part>_kg (a point mass at the "
            "part's frame, moved with part:<name>:<x|y|z>_mm: a counterweight), ratio:<coupling> (another pulley), "
            "motor:<key>, supply:<key>, "
            "tool:<key>, friction:<joint>:<key> (machine-description values, as offsets), the geometric targets "
            "of `mechanism clearance`, and the operating point voltage_V, duty_percent, layers (absolute). Rows "
            "stream to OUT.csv.partial as they finish; an interrupted sweep continues with --resume; OUT.csv "
            "appears when all are done."
        ),
        epilog=(
            "examples: mechanism sweep --variants flywheel.json --csv out/flywheel.csv --plot out/flywheel.png; "
            "mechanism sweep --machine press.toml --variants v.csv --workers 8 --csv v_out.csv --resume; "
            "mechanism sweep --variants big.json --backend ray --ray-address 10.0.0.5:6379 --csv big.csv --yes"
        ),
    )
    add_machine_arguments(parser)
    parser.add_argument(
        "--variants",
        required=True,
        metavar="FILE",
        help="design variants (JSON or CSV, mechanism-variants/1)",
    )
    parser.add_argument(
        "--csv",
        required=True,
        metavar="OUT.csv",
        help="one row per variant: parameters, then metrics with units in their names",
    )
    parser.add_argument(
        "--plot",
        metavar="OUT.png",
        help="speed, ripple, settling time and peak current against a parameter",
    )
    parser.add_argument(
        "--plot-x",
        metavar="NAME",
        help="the plot's x axis (default: the first parameter that varies)",
    )
    parser.add_argument(
        "--plot-group",
        metavar="NAME",
        help="one line per value of this parameter (default: the next that varies)",
    )
    parser.add_argument(
        "--voltage",
        type=number(-1000, 1000, "V"),
        default=12.0,
        metavar="V",
        help="motor voltage step at t = 0 for variants that do not set voltage_V or duty_percent (default 12)",
    )
    parser.add_argument(
        "--duration",
        type=number(0.05, 600, "s"),
        default=2.0,
        metavar="S",
        help="simulated time per variant [s] (default 2): long enough to reach steady running",
    )
    parser.add_argument(
        "--layers",
        type=number(0, 20, integer=True),
        default=0,
        metavar="N",
        help="fabric layers (default 0)",
    )
    parser.add_argument(
        "--warm-s",
        type=number(0, 1e6, "s"),
        default=0.0,
        metavar="S",
        help="friction warmed by S seconds of running",
    )
    parser.add_argument(
        "--full",
        action="store_true",
        help="run the full multibody model (belts and loops compliant, inductance, everything the "
        "description has) instead of the reduced 1-DOF one: variants compiled and run in groups "
        "through mujoco.rollout, --workers threads; ~100x slower per variant",
    )
    parser.add_argument(
        "--bearings",
        metavar="J1,J2",
        help="joints whose peak reaction force [N] over the last revolution "
        "is reported (bearing_<joint>_peak_N; needs --full)",
    )
    add_batch_arguments(parser, "the variants (with --full: rollout threads)")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted sweep with the same inputs from OUT.csv.partial (rows done are kept)",
    )
    parser.add_argument(
        "--yes", action="store_true", help="run more than 100000 variants (at most 1000000)"
    )
    parser.set_defaults(
        handler=run, inputs=("machine", "model", "variants"), outputs=("csv",), plots=("plot",)
    )


def run(args) -> int:
    from mechanism.cli._machine import machine_from_args
    from mechanism.inspection.clearance import write_rows
    from mechanism.inspection.sweep import METRICS, SweepOptions, plot_sweep, run_sweep
    from mechanism.inspection.sweep_journal import journal_path
    from mechanism.inspection.variants import read_variants

    from mechanism.errors import UserError
    from mechanism.inspection.sweep import check_bearings

    check_batch_arguments(args, True, "the variants")
    bearings = tuple(j.strip() for j in (args.bearings or "").split(",") if j.strip())
    if bearings and not args.full:
        raise UserError("--bearings needs --full: the reduced model has no reaction forces")
    machine = machine_from_args(args, warm_s=args.warm_s, layers=args.layers)
    check_bearings(machine.model, bearings)
    variants = read_variants(args.variants, machine.description.variant_presets, confirmed=args.yes)
    options = SweepOptions(
        voltage_V=args.voltage,
        duration_s=args.duration,
        layers=args.layers,
        full=args.full,
        bearings=bearings,
    )
    journal = journal_path(args.csv)
    result = run_sweep(
        machine,
        variants,
        options,
        workers=args.workers,
        backend=backend_from_args(args),
        ray_address=args.ray_address,
        journal=journal,
        resume=args.resume,
    )
    table = result.table()
    write_rows(
        args.csv,
        table,
        comments=[
            f"mechanism sweep of {machine.name}: {len(table)} variants, each {args.duration:g} s from rest under a voltage step "
            f"(default {args.voltage:g} V); parameters are offsets from nominal except voltage_V, duty_percent, layers",
            *(f"{name}: {doc}" for name, doc in METRICS.items()),
        ],
    )
    if args.plot:
        plot_sweep(result, args.plot, args.plot_x, args.plot_group)
    unsteady = sum(1 for row in table if row["note"])
    kept = f", {result.resumed} kept from the interrupted run" if result.resumed else ""
    print(
        f"{len(table)} variants ({result.model}) in {result.seconds:.1f} s{kept}; {unsteady} with a note (no steady running or a "
        f"variant that cannot run); wrote {args.csv}"
    )
    journal.unlink(missing_ok=True)
    return 0
