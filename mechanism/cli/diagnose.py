"""`mechanism diagnose`: find what physics the baseline misses in a bench recording."""

from __future__ import annotations

ORDER = 61


def register(subparsers) -> None:
    from mechanism.cli.identify import add_recording_arguments

    parser = subparsers.add_parser(
        "diagnose",
        help="find the physics a model is missing from a bench recording, model it, show the fit improve",
        description=(
            "Fit the baseline, locate where its velocity residual lives (time, arm angle, motor angle, speed, "
            "frequency; dynamics vs sensor artefact), then add candidate effects one at a time -- torque_ripple, "
            "linkage_dynamics, position_friction, stribeck, thermal_drift, needle_penetration, belt_compliance, "
            "voltage_nonlinearity, encoder_eccentricity, backlash, sensor_delay, winding_heating -- refitting on one half of the recording and keeping an "
            "effect only if it lowers the error on the other half by at least 35%. JSON: baseline params and rmse, "
            "the effects found in order (name, one-sentence evidence, params, rmse), final params and rmse; every "
            "rmse is the RMS arm-velocity residual [rad/s] on the held-out half. A recording at one constant "
            "voltage is not identifiable: exit status 2, and the JSON says so."
        ),
        epilog="example: mechanism diagnose rec.csv --json out/diagnosis.json --report out/diagnosis",
    )
    add_recording_arguments(parser, "diagnosis")
    parser.add_argument("--effects", metavar="NAME[,NAME]",
                        help="restrict the candidates to these effects (default: the whole library)")
    parser.set_defaults(handler=run)


def run(args) -> int:
    import sys

    from mechanism.cli._nominal import drive_nominal
    from mechanism.cli.identify import progress_bar, write_outputs
    from mechanism.sysid.diagnosis import diagnose, not_identifiable_json
    from mechanism.sysid.effects import effect
    from mechanism.sysid.identification import NotIdentifiable
    from mechanism.sysid.recording import read_recording

    candidates = None
    if args.effects:
        candidates = [effect(name.strip()).name for name in args.effects.split(",") if name.strip()]
    rec = read_recording(args.recording)
    try:
        bar, tick = progress_bar("diagnose")
        with bar:
            result = diagnose(rec, args.baseline, candidates, progress=tick, model_path=args.model, nominal=drive_nominal(args))
    except NotIdentifiable as exc:
        # a finding, not a crash: say so in the JSON as well as on stderr (exit 2)
        write_outputs(args, not_identifiable_json(rec.source, str(exc)))
        sys.stderr.write(f"error: recording {rec.source}: not identifiable: {exc}\n")
        return 2
    from mechanism.sysid.report import diagnosis_report

    data = result.to_json()
    write_outputs(args, data, lambda folder: diagnosis_report(result, folder))
    print(f"baseline ({args.baseline}): rmse {data['baseline']['rmse']:.4g} rad/s")
    if not data["effects"]:
        print("nothing is missing: no candidate effect lowers the validation error clearly")
    for item in data["effects"]:
        print(f"+ {item['name']}: rmse {item['rmse']:.4g} rad/s -- {item['evidence']}")
    print(f"final: rmse {data['final']['rmse']:.4g} rad/s")
    if "unexplained" in data:
        print(f"unexplained: {data['unexplained']['times_noise_floor']:.1f}x the noise floor -- {data['unexplained']['sentence']}")
    return 0
