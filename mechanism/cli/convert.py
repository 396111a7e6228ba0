"""``mechanism convert``: a CAD assembly export becomes an MJCF model with its meshes."""

from __future__ import annotations

ORDER = 10


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "convert",
        help="convert a CAD assembly export (Simscape Multibody XML) to an MJCF model",
        description=(
            "Convert a CAD assembly export to MuJoCo. Reads first-generation PhysicalModelingXMLFile "
            "(SimMechanics Link from Creo/Pro-E, SolidWorks, Inventor) and second-generation "
            "SimscapeMultibodyImportXML exports with their STL/STEP geometry, plus the optional couplings "
            "side-car EXPORT_STEM.couplings.json (belts, gears). Writes OUTDIR/NAME.xml and OUTDIR/meshes/ "
            "(binary STL in metres) and prints a summary. Units are converted to SI (m, kg, kg*m^2)."
        ),
    )
    parser.add_argument(
        "export", metavar="EXPORT.xml", help="the CAD export (its geometry files lie next to it)"
    )
    parser.add_argument(
        "-o",
        "--out",
        dest="outdir",
        metavar="OUTDIR",
        required=True,
        help="output folder for NAME.xml (created if missing; other files in it are kept)",
    )
    parser.add_argument(
        "--name", metavar="NAME", help="model and file name (default: the export's file name stem)"
    )
    parser.add_argument(
        "--mesh-dir",
        metavar="DIR",
        help="folder for the meshes (default: OUTDIR/meshes); the MJCF refers to it by relative path",
    )
    parser.add_argument(
        "--up",
        default="z",
        metavar="AXIS",
        help="the export's world axis that points up: x, y, z, -x, -y or -z (write --up=-z; default z); gravity "
        "(9.81 m/s^2) acts against it. Exports do not record it: SolidWorks and Inventor "
        "assemblies are often Y-up (--up y)",
    )
    parser.add_argument(
        "--driver",
        action="append",
        default=[],
        metavar="JOINT",
        help="a joint you turn (a crank, the motor shaft): it stays a joint of the model and loops close "
        "elsewhere (repeatable; by default joints in a bearing on the frame stay, pins between moving "
        "parts close the loops)",
    )
    parser.add_argument(
        "--explain",
        action="store_true",
        help="also print, per joint, the CAD mates (by name) or the export joint it came from and "
        "what it became in the MJCF (a joint, a loop closure, a merged body)",
    )
    parser.set_defaults(handler=run, inputs=("export",), outputs=(_model_file,))


def _model_file(args):
    """OUTDIR/NAME.xml, the file convert writes (checked against the export before the run)."""
    from pathlib import Path

    return Path(args.outdir) / f"{args.name or Path(args.export).stem}.xml"


def run(args) -> int:
    from mechanism.converters import convert

    from mechanism.machine.roles import drive_lines

    report = convert(
        args.export,
        args.outdir,
        name=args.name,
        mesh_dir=args.mesh_dir,
        up=args.up,
        drivers=tuple(args.driver),
    )
    print(
        "\n".join(
            report.summary_lines(
                extra=drive_lines(report.mjcf_path, report.degrees_of_freedom), explain=args.explain
            )
        )
    )
    return 0
