"""``mechanism init``: a first machine description for a CAD export or an MJCF model."""

from __future__ import annotations

ORDER = 12


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "init",
        help="draft a machine description (TOML) for a CAD export: joints, guessed roles, placeholders",
        description=(
            "Convert a CAD export (or read an MJCF), list its joints and degrees of freedom, guess the roles "
            "a machine description needs (the shaft: the slowest joint turning whole revolutions on the frame; "
            "the motor: the joint turning fastest; the zero: the site that rises and falls most) and write a "
            "commented draft with every guess marked GUESS and every placeholder TODO. Every verb accepts the "
            "draft with --machine at once."
        ),
        epilog="example: mechanism init my_export/press.xml -o press.toml && mechanism simulate --machine press.toml --voltage 12 --duration 2 --summary",
    )
    parser.add_argument(
        "model",
        metavar="EXPORT_OR_MJCF",
        help="a CAD export (converted once, cached) or a converted MJCF",
    )
    parser.add_argument(
        "-o", "--out", required=True, metavar="MACHINE.toml", help="the draft description to write"
    )
    parser.add_argument("--name", metavar="NAME", help="machine name (default: the file's stem)")
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace MACHINE.toml if it exists (default: refuse, since a description is usually edited by hand)",
    )
    parser.add_argument(
        "--up",
        metavar="AXIS",
        choices=("x", "y", "z", "-x", "-y", "-z", "+x", "+y", "+z"),
        help="the export's world axis that points up, as convert --up (default: the export's gravity "
        "vector where it carries one, else z); written to the draft as [machine] up",
    )
    parser.set_defaults(handler=run, inputs=("model",), outputs=("out",))


def run(args) -> int:
    import os
    from pathlib import Path

    from mechanism.errors import UserError
    from mechanism.files.outputs import atomic_file
    from mechanism.machine.draft import draft_description
    from mechanism.machine.models import converted_model, is_mjcf

    source = Path(args.model)
    if not source.is_file():
        raise UserError(f"{source}: no such file")
    out = Path(args.out)
    if out.resolve() == source.resolve():
        raise UserError(f"-o {out}: is the input; choose another file")
    if out.exists() and not args.force:
        raise UserError(
            f"-o {out}: exists (a description you may have edited); choose another file or add --force to replace it"
        )
    if is_mjcf(source):
        mjcf, up, why = source, None, "the MJCF's own gravity"
    else:
        from mechanism.converters import ExportError
        from mechanism.converters.convert import detect_up
        from mechanism.converters.load import read

        if args.up:
            up, why = args.up, "given by --up"
        else:
            try:
                up, why = detect_up(read(source))
            except ExportError as exc:
                raise UserError(str(exc)) from None
        # the conversion every verb of the draft reuses
        mjcf = converted_model(source, up=up if args.up else None)
    reference = os.path.relpath(source.resolve(), out.resolve().parent)
    text, summary = draft_description(
        mjcf, reference, args.name or source.stem, up=up, up_reason=why
    )
    with atomic_file(out) as handle:
        handle.write(text)
    print("\n".join(summary))
    print(f"wrote {out}: check the GUESS lines and fill in the TODO lines")
    return 0
