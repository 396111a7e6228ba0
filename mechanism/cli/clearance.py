"""``mechanism clearance``: minimum distances and interferences between parts over the cycle."""

from __future__ import annotations

from mechanism.cli._batch import add_batch_arguments, backend_from_args, check_batch_arguments
from mechanism.files.limits import number

from mechanism.cli._machine import DRIVER_HELP, add_machine_arguments, inspection_target

ORDER = 45


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "clearance",
        help="minimum clearance and interferences between real part shapes over shaft revolutions, for design variants",
        description=(
            "Turn the shaft through whole revolutions (sampled every --resolution degrees, minima refined on the "
            "angle to 1e-5 rad) and measure the exact distance between the parts' triangle meshes (never their "
            "convex hulls: a pin passing through a hole is a clearance). Reports per pair the "
            "minimum clearance [mm], the shaft angle [deg, 0 = the described zero] where it occurs, the closest "
            "points [mm, world], and every interference: its shaft-angle range and largest penetration depth [mm] "
            "(a negative minimum clearance is minus that depth). With --variants, every design variant of the file "
            "is checked (in parallel with --workers) and the CSV has one row per variant."
        ),
        epilog=(
            "examples: mechanism clearance --pairs needle:hook,needle:needle_plate --required 0.05 --csv c.csv --json c.json; "
            "mechanism clearance --pairs needle:hook --variants variants.json --workers 2 --csv variants.csv; "
            "mechanism clearance --pairs needle:hook --variants variants.json --backend ray --ray-address 10.0.0.5:6379 --csv variants.csv"
        ),
    )
    add_machine_arguments(parser)
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument(
        "--pairs",
        action="append",
        metavar="A:B[,C:D...]",
        help="part pairs to check (CAD part names)",
    )
    which.add_argument(
        "--all-pairs",
        action="store_true",
        help="every pair of parts that move relative to each other (parts joined to each other by a "
        "joint between two moving bodies are skipped)",
    )
    parser.add_argument(
        "--cycle",
        type=number(0, 100, low_open=True),
        default=1.0,
        metavar="N",
        help="shaft revolutions to check (default 1)",
    )
    parser.add_argument(
        "--resolution",
        type=number(0.01, 360, "deg"),
        default=0.5,
        metavar="DEG",
        help="sampling step of the shaft angle [deg] (default 0.5)",
    )
    parser.add_argument(
        "--required",
        type=number(-1000, 1000, "mm"),
        default=0.0,
        metavar="MM",
        help="required clearance [mm]: a pair passes if its minimum clearance is at least this (default 0: no interference)",
    )
    parser.add_argument(
        "--variants",
        metavar="FILE",
        help="design variants (JSON or CSV; parameters such as hook_timing_deg, crank_radius_mm, "
        "needle_bar_height_mm or coupling:/joint:/body:/part: targets, offsets from nominal in deg or mm)",
    )
    add_batch_arguments(parser, "--variants")
    parser.add_argument("--driver", metavar="JOINT", help=DRIVER_HELP)
    parser.add_argument(
        "--csv",
        required=True,
        metavar="OUT.csv",
        help="one row per pair (or per variant with --variants)",
    )
    parser.add_argument(
        "--json",
        metavar="OUT.json",
        help="full report: closest points, interference ranges, depths",
    )
    parser.add_argument(
        "--strict", action="store_true", help="exit with status 1 when any check fails"
    )
    parser.set_defaults(
        handler=run, inputs=("machine", "model", "variants"), outputs=("csv", "json")
    )


def run(args) -> int:
    from mechanism.inspection.clearance import (
        all_pairs,
        check_clearance,
        parse_pairs,
        write_json,
        write_rows,
    )
    from mechanism.machine.models import load_model

    check_batch_arguments(args, bool(args.variants), "--variants")
    path, args.driver, description = inspection_target(args)
    model = load_model(path)
    pairs = all_pairs(model) if args.all_pairs else parse_pairs(args.pairs, model)
    if args.variants:
        from mechanism.inspection.variants import read_variants, run_variants

        variants = read_variants(
            args.variants, description.variant_presets if description else None
        )
        batch = run_variants(
            model,
            variants,
            pairs,
            args.required,
            args.driver,
            args.cycle,
            args.resolution,
            args.workers,
            backend_from_args(args),
            ray_address=args.ray_address,
            description=description,
        )
        table = batch.table()
        write_rows(
            args.csv,
            table,
            comments=[
                f"required clearance: {args.required:g} mm; one row per variant; "
                "min_mm < 0 is minus the penetration depth"
            ],
        )
        if args.json:
            write_json(
                args.json,
                {
                    "format": "mechanism-clearance-variants/1",
                    "required_mm": args.required,
                    "pairs": [p.label for p in pairs],
                    "seconds": batch.seconds,
                    "variants": table,
                },
            )
        print(
            f"{len(table)} variants in {batch.seconds:.1f} s ({len(table) / max(batch.seconds, 1e-9):.1f}/s), "
            f"{batch.failed} fail the required clearance of {args.required:g} mm; wrote {args.csv}"
        )
        failed = batch.failed > 0
    else:
        report = check_clearance(
            model,
            pairs,
            args.cycle,
            args.resolution,
            args.required,
            args.driver,
            description=description,
            progress=True,
        )
        write_rows(
            args.csv,
            report.rows(),
            comments=[
                f"required clearance: {args.required:g} mm; angles: "
                + (
                    "the shaft angle [deg] (0 at the described zero)"
                    if description and args.driver == description.shaft_joint
                    else f"{args.driver} [deg]"
                )
            ],
        )
        if args.json:
            write_json(args.json, report.to_json())
        for result in report.results:
            verdict = "pass" if result.passes(args.required) else "FAIL"
            line = f"{result.pair.label}: min {result.min_distance_mm:.4f} mm at {result.angle_deg:.2f} deg  {verdict}"
            for hit in result.interferences:
                line += f"; interference {hit.start_deg:.2f}-{hit.end_deg:.2f} deg, depth {hit.depth_mm:.4f} mm"
            print(line)
        failed = not report.passed
    return 1 if (failed and args.strict) else 0
