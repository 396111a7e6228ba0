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
    parser.add_argument("export", metavar="EXPORT.xml", help="the CAD export (its geometry files lie next to it)")
    parser.add_argument("-o", "--out", dest="outdir", metavar="OUTDIR", required=True,
                        help="output folder for NAME.xml (created if missing; other files in it are kept)")
    parser.add_argument("--name", metavar="NAME", help="model and file name (default: the export's file name stem)")
    parser.add_argument("--mesh-dir", metavar="DIR",
                        help="folder for the meshes (default: OUTDIR/meshes); the MJCF refers to it by relative path")
    parser.add_argument("--up", default="z", metavar="AXIS",
                        help="the export's world axis that points up: x, y, z, -x, -y or -z (write --up=-z; default z); gravity "
                             "(9.81 m/s^2) acts against it. Exports do not record it: SolidWorks and Inventor "
                             "assemblies are often Y-up (--up y)")
    parser.set_defaults(handler=run)


def summary_lines(report, extra=()) -> list[str]:
    """The printed summary of a conversion, the one place for its wording. ``extra`` lines (e.g.
    quantities the simulator computes from the model) go after the totals, before the warnings."""
    joints = ", ".join(f"{count} {kind}" for kind, count in report.joints_by_type.items() if count) or "none"
    lines = [
        f"wrote {report.mjcf_path} ({report.export_format}, {report.n_parts} parts, {report.n_meshes} meshes in {report.mesh_dir})",
        f"bodies: {report.n_bodies}",
        f"joints: {report.n_joints} ({joints})",
        f"loop closures: {report.n_loop_closures}",
        f"couplings: {report.n_couplings}",
        f"degrees of freedom: {report.degrees_of_freedom}",
        f"total mass: {report.total_mass_kg:.6g} kg (export: {report.export_mass_kg:.6g} kg)",
        *extra,
        f"warnings: {len(report.warnings)}",
    ]
    lines += [f"warning: {warning}" for warning in report.warnings]
    return lines


def drive_lines(report) -> list[str]:
    """Moving mass and, for a one-degree-of-freedom machine, the effective inertia reflected to
    its driving joint over one revolution (motor through the belts included)."""
    import mujoco
    import numpy as np

    from mechanism.kinematics.pose import PoseError
    from mechanism.machine.models import load_model
    from mechanism.kinematics.linkage import compute_tables

    try:
        model = load_model(report.mjcf_path)
    except Exception as exc:  # noqa: BLE001 - the model is written; a summary extra must not end the command
        return [f"moving mass: not computed ({' '.join(str(exc).split())[:120]})"]
    moving = float(sum(model.body_mass[b] for b in range(1, model.nbody) if model.body_weldid[b] != 0))
    lines = [f"moving mass: {moving:.6g} kg"]
    if report.degrees_of_freedom != 1:
        return lines
    hinges = [model.joint(j).name for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    driver = "arm_shaft" if "arm_shaft" in hinges else (hinges[0] if hinges else None)
    if driver is None:
        return lines
    try:
        tables = compute_tables(model, driver, n=180)
    except PoseError as exc:
        return lines + [f"reflected inertia: not computed ({exc})"]
    except Exception as exc:  # noqa: BLE001 - numerical trouble in an odd export only loses this line
        return lines + [f"reflected inertia: not computed ({exc.__class__.__name__}: {' '.join(str(exc).split())[:100]})"]
    inertia = tables.inertia_kgm2
    lines.append(f"reflected inertia at {driver}: {inertia.mean():.4g} kg*m^2 mean over a revolution "
                 f"({inertia.min():.4g} to {inertia.max():.4g})")
    geared = {joint: abs(ratio[0]) for joint, ratio in tables.ratios.items()
              if joint != driver and np.ptp(ratio) < 1e-9 and abs(ratio[0]) > 2}
    if geared:  # the fastest geared joint, normally the motor behind its belt
        joint = max(geared, key=geared.get)
        lines.append(f"  = {inertia.mean() / geared[joint] ** 2:.4g} kg*m^2 referred to {joint} (ratio {geared[joint]:g}:1)")
    return lines


def run(args) -> int:
    from mechanism.converters import convert

    report = convert(args.export, args.outdir, name=args.name, mesh_dir=args.mesh_dir, up=args.up)
    print("\n".join(summary_lines(report, extra=drive_lines(report))))
    return 0
