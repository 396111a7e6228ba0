"""`mechanism diagnose`: find what physics the baseline misses in a bench recording."""

from __future__ import annotations

import argparse

ORDER = 61


class _EffectsInHelp(argparse.HelpFormatter):
    """Writes the effect library's names and the selection's thresholds into the help text when
    help is asked for (the library is imported then, not at every start of the command line)."""

    def add_text(self, text):
        if text and "{effects}" in text:
            from mechanism.sysid.diagnosis import GENERIC_GAIN, KEEP_GAIN_JOINT, MIN_RELATIVE_GAIN
            from mechanism.sysid.effects import EFFECTS

            text = text.format(
                effects=", ".join(EFFECTS),
                alone=f"{MIN_RELATIVE_GAIN:.0%}",
                joint=f"{KEEP_GAIN_JOINT:.0%}",
                generic=f"{GENERIC_GAIN:.0%}",
            )
        super().add_text(text)


def register(subparsers) -> None:
    from mechanism.cli.identify import add_recording_arguments

    from mechanism.cli._batch import add_batch_arguments

    parser = subparsers.add_parser(
        "diagnose",
        help="find the physics a model is missing from a bench recording, model it, show the fit improve",
        formatter_class=_EffectsInHelp,
        description=(
            "Fit the baseline, locate where its velocity residual lives (time, shaft angle, motor angle, speed, "
            "frequency; dynamics vs sensor artefact), then add candidate effects from the library -- {effects} -- "
            "one at a time with a joint refit and a backward step, fitting on one half of the recording and keeping "
            "what the other half supports (one effect alone must lower its error by at least {alone}, each of several "
            "by {joint} when added last); where none explains the residual, generic models are tried and kept at a "
            "{generic} cut, flagged generic. JSON: baseline params and rmse, "
            "the effects found in order (name, one-sentence evidence, params, rmse), final params and rmse; every "
            "rmse is the RMS shaft-velocity residual [rad/s] on the held-out half. A recording at one constant "
            "voltage is not identifiable: exit status 2, and the JSON says so."
        ),
        epilog="examples: mechanism diagnose rec.csv --json out/diagnosis.json --report out/diagnosis; "
        "mechanism diagnose recordings/ --workers 2 --out out/fleet",
    )
    add_recording_arguments(parser, "diagnosis")
    for action in parser._actions:  # several recordings, or folders of them: a fleet
        if action.dest == "recording":
            action.nargs, action.metavar = "+", "REC.csv|DIR"
            action.help += "; several recordings or a folder of recordings (*.csv, *.mat, ...): a fleet, diagnosed in parallel into --out"
    parser.add_argument(
        "--effects",
        metavar="NAME[,NAME]",
        help="restrict the candidates to these effects (default: the whole library)",
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        help="fleet output folder: one JSON per recording (as --json writes for one), summary.csv "
        "(effects, rmse, fitted parameters, time per recording; errors of bad recordings) and "
        "summary.html (each parameter's spread over the fleet, outliers by robust z-score > 3.5)",
    )
    add_batch_arguments(parser, "a fleet of recordings")
    parser.set_defaults(
        handler=run,
        inputs=("recording", "model", "machine", "recording_map"),
        outputs=("json",),
        output_dirs=("report", "out"),
    )


def run(args) -> int:
    import sys
    from pathlib import Path

    from mechanism.cli._batch import check_batch_arguments
    from mechanism.cli._nominal import drive_nominal
    from mechanism.cli.identify import progress_bar, resolve_baseline, write_outputs
    from mechanism.sysid.diagnosis import diagnose, not_identifiable_json
    from mechanism.sysid.effects import effect
    from mechanism.sysid.identification import NotIdentifiable
    from mechanism.cli._recording import read_recording_from_args

    candidates = None
    if args.effects:
        candidates = [effect(name.strip()).name for name in args.effects.split(",") if name.strip()]
    fleet = args.out is not None or len(args.recording) > 1 or Path(args.recording[0]).is_dir()
    check_batch_arguments(args, fleet, "a fleet (several recordings, a folder, or --out)")
    if fleet:
        return run_fleet(args, candidates)
    rec = read_recording_from_args(args, args.recording[0])
    try:
        bar, tick = progress_bar("diagnose")
        with bar:
            nominal = drive_nominal(args)
            result = diagnose(
                rec,
                resolve_baseline(args, nominal),
                candidates,
                progress=tick,
                model_path=args.model,
                nominal=nominal,
            )
            # the report's plots take seconds: the bar stays and says so
            tick("writing the outputs")
            from mechanism.sysid.report import diagnosis_report

            data = result.to_json()
            write_outputs(args, data, lambda folder: diagnosis_report(result, folder))
    except NotIdentifiable as exc:
        # a finding, not a crash: say so in the JSON as well as on stderr (exit 2)
        write_outputs(args, not_identifiable_json(rec.source, str(exc), rec.reading))
        sys.stderr.write(f"error: recording {rec.source}: not identifiable: {exc}\n")
        return 2
    print(f"baseline ({args.baseline}): rmse {data['baseline']['rmse']:.4g} rad/s")
    if not data["effects"]:
        print("nothing is missing: no candidate effect lowers the validation error clearly")
    for item in data["effects"]:
        print(f"+ {item['name']}: rmse {item['rmse']:.4g} rad/s -- {item['evidence']}")
    print(f"final: rmse {data['final']['rmse']:.4g} rad/s")
    if "unexplained" in data:
        print(
            f"unexplained: {data['unexplained']['times_noise_floor']:.1f}x the noise floor -- {data['unexplained']['sentence']}"
        )
    return 0


def run_fleet(args, candidates) -> int:
    """Several recordings: one JSON each and a summary in --out; exit 2 if none was diagnosed."""
    import sys

    from mechanism.errors import UserError
    from mechanism.sysid.fleet import SUMMARY_CSV, SUMMARY_HTML, diagnose_fleet
    from mechanism.cli._nominal import drive_nominal
    from mechanism.cli._recording import recording_map_from_args

    if args.out is None:
        raise UserError("several recordings need --out DIR (one JSON per recording and a summary)")
    if args.json or args.report:
        raise UserError(
            "--json and --report are for one recording; a fleet writes them per recording into --out"
        )
    from mechanism.cli._batch import backend_from_args
    from mechanism.cli.identify import resolve_baseline

    nominal = drive_nominal(args)
    result = diagnose_fleet(
        args.recording,
        args.out,
        workers=args.workers,
        backend=backend_from_args(args),
        ray_address=args.ray_address,
        progress=sys.stderr.isatty(),
        baseline=resolve_baseline(args, nominal),
        candidates=candidates,
        model_path=args.model,
        nominal=nominal,
        recording_map=recording_map_from_args(args),
    )
    for row in result.rows:
        if row["status"] == "ok":
            print(
                f"{row['recording']}: effects {row['effects'] or 'none'}, rmse {row['baseline_rmse_rad_s']:.4g} -> "
                f"{row['final_rmse_rad_s']:.4g} rad/s ({row['time_s']:.1f} s)"
            )
        else:
            print(f"{row['recording']}: not diagnosed: {row['error']}")
    for item in result.outliers:
        print(
            f"outlier: {item['recording']} {item['parameter']} = {item['value']:.5g} (robust z {item['robust_z']:.1f})"
        )
    print(
        f"{result.diagnosed} of {len(result.rows)} recordings diagnosed in {result.seconds:.1f} s; "
        f"wrote {args.out}/{SUMMARY_CSV}, {args.out}/{SUMMARY_HTML} and one JSON per recording"
    )
    if not result.diagnosed:
        sys.stderr.write(
            f"error: none of the {len(result.rows)} recordings could be diagnosed (see {args.out}/{SUMMARY_CSV})\n"
        )
        return 2
    return 0
