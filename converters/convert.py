"""Export file in, MJCF model and meshes out: the whole conversion behind ``mechanism convert``."""

from __future__ import annotations

import contextlib
import copy
import difflib
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mechanism.converters import inertia, mjcf, tree
from mechanism.converters.errors import ExportError
from mechanism.converters.geometry import load_meshes
from mechanism.converters.load import read
from mechanism.converters.names import sanitize
from mechanism.tolerances import JOINT_RANK_TOLERANCE as RANK_TOLERANCE


@dataclass
class ConversionReport:
    """What a conversion produced; the CLI prints it, tests and notebooks read it."""

    mjcf_path: Path
    mesh_dir: Path
    model_name: str
    source: Path
    export_format: str
    n_parts: int
    n_bodies: int
    joints_by_type: dict[str, int]
    n_loop_closures: int
    n_couplings: int
    n_meshes: int
    # joint DOF minus independent loop and coupling constraints, at the assembly pose
    degrees_of_freedom: int
    total_mass_kg: float  # of the compiled model (export masses plus any repair, see warnings)
    export_mass_kg: float  # sum of the part masses as the export states them
    warnings: list[str] = field(default_factory=list)
    # per export joint: what it came from, what it became
    joint_origins: list[str] = field(default_factory=list)

    @property
    def n_joints(self) -> int:
        return sum(self.joints_by_type.values())

    def summary_lines(self, extra=(), explain: bool = False) -> list[str]:
        """The printed summary of a conversion, the one place for its wording. ``extra`` lines
        (quantities the simulator computes from the model) go after the totals, before the warnings;
        ``explain`` adds a line per joint naming the mates (or export joint) it came from."""
        joints = (
            ", ".join(f"{count} {kind}" for kind, count in self.joints_by_type.items() if count)
            or "none"
        )
        lines = [
            f"wrote {self.mjcf_path} ({self.export_format}, {self.n_parts} parts, {self.n_meshes} meshes in {self.mesh_dir})",
            f"bodies: {self.n_bodies}",
            f"joints: {self.n_joints} ({joints})",
            f"loop closures: {self.n_loop_closures}",
            f"couplings: {self.n_couplings}",
            f"degrees of freedom: {self.degrees_of_freedom}",
            f"total mass: {self.total_mass_kg:.6g} kg (export: {self.export_mass_kg:.6g} kg)",
            *extra,
            *(self.joint_origins if explain else []),
            f"warnings: {len(self.warnings)}",
        ]
        return lines + [f"warning: {warning}" for warning in self.warnings]


# Peak memory of a conversion: about 256 MiB for the libraries, and some 30-45 bytes for each byte
# of export and geometry (measured: the Sapphire 870's 0.7 MB and the youBot's 13.7 MB exports).
CONVERSION_BASE_BYTES = 256 << 20
CONVERSION_BYTES_PER_INPUT_BYTE = 48


def check_conversion_memory(export_path: Path, geometry) -> None:
    """Refuse, before reading it, an export whose conversion would not fit in memory."""
    from mechanism.files.limits import check_memory

    size = 0
    for path in {export_path, *geometry}:
        try:
            size += Path(path).stat().st_size
        except OSError:
            continue  # a missing file is reported (as a warning) where it is read
    check_memory(
        CONVERSION_BASE_BYTES + CONVERSION_BYTES_PER_INPUT_BYTE * size,
        f"converting {export_path.name} ({size / 2**20:.3g} MiB of export and geometry files)",
    )


def convert(
    export_path,
    outdir,
    *,
    name: str | None = None,
    mesh_dir=None,
    up: str | None = "z",
    drivers: tuple[str, ...] = (),
    ground: str | None = None,
) -> ConversionReport:
    """Convert a CAD export to ``outdir/<name>.xml`` with meshes in ``mesh_dir`` (default ``outdir/meshes``).

    ``name`` defaults to the export's file stem. ``up`` is the export's world axis that points up
    (``x``, ``y``, ``z``, ``-x``, ...): gravity acts against it; the export's frame is kept, since
    exports do not say which way is up (SolidWorks and Inventor assemblies are often Y-up). ``drivers``
    names joints a user turns (export or sanitised names): they stay joints of the kinematic tree
    and loops close elsewhere; a name the export lacks is an error. The MJCF refers to the meshes by a path
    relative to ``outdir``. ``up=None``: the export's own gravity vector where it carries one
    (:func:`detect_up`), else z. ``ground`` names a part (export or sanitised name) fixed to the
    world besides whatever the export grounds. Nothing is written unless the whole conversion
    succeeds; other files already in ``outdir`` and ``mesh_dir`` are left alone.
    """
    export_path = Path(export_path)
    outdir = Path(outdir)
    mesh_dir = Path(mesh_dir) if mesh_dir is not None else outdir / "meshes"
    model_name = sanitize(name or export_path.stem)
    if outdir.exists() and not outdir.is_dir():
        raise ExportError(f"output {outdir}: exists and is not a folder")

    check_conversion_memory(export_path, [])
    assembly = read(export_path)
    check_conversion_memory(
        export_path, [part.geometry for part in assembly.real_parts if part.geometry is not None]
    )
    if up is None:
        up = detect_up(assembly)[0]
    gravity = mjcf.gravity_along(up)
    if ground is not None:
        ground_part(assembly, ground)
    meshes = load_meshes(assembly)
    inertia.repair_parts(assembly, meshes)
    joint_names = {j.name for j in assembly.joints} | {sanitize(j.name) for j in assembly.joints}
    for driver in drivers:
        if driver not in joint_names:
            raise ExportError(
                f"export {export_path.name}: no joint {driver!r} to keep as a driver; close matches: "
                f"{', '.join(difflib.get_close_matches(driver, sorted(joint_names), 3)) or 'none'}"
            )
    plan = tree.plan(assembly, set(drivers))
    meshdir = os.path.relpath(mesh_dir.resolve(), outdir.resolve()).replace(os.sep, "/")
    built = mjcf.build(
        assembly, plan, meshes, model_name=model_name, meshdir=meshdir, gravity=gravity
    )
    used = {m.name: m for m in meshes.values() if m is not None}

    mjcf_path = outdir / f"{model_name}.xml"
    dof = locked = None
    with _staging(outdir, meshdir) as (stage_model, stage_meshes):
        for mesh in used.values():
            (stage_meshes / mesh.filename).write_bytes(mesh.data)
        built.spec.modelfiledir = str(stage_model)
        try:
            model = built.spec.compile()
            built.spec.compiler.savecompiled = False
            xml = built.spec.to_xml()
            dof, locked = mobility(model)
        except Exception as exc:  # MuJoCo reports model errors as ValueError with several lines
            raise ExportError(
                f"export {export_path.name}: MuJoCo rejects the converted model: {' '.join(str(exc).split())}"
            ) from None
        (stage_model / mjcf_path.name).write_text(xml, encoding="utf-8")
        _publish(
            stage_model / mjcf_path.name,
            mjcf_path,
            [(stage_meshes / m.filename, mesh_dir / m.filename) for m in used.values()],
            inputs=[export_path, *(p.geometry for p in assembly.parts.values())],
        )

    return ConversionReport(
        mjcf_path=mjcf_path,
        mesh_dir=mesh_dir,
        model_name=model_name,
        source=export_path,
        export_format=assembly.format,
        n_parts=len(assembly.real_parts),
        n_bodies=built.n_bodies,
        joints_by_type=dict(built.joints_by_type),
        n_loop_closures=built.n_closures,
        n_couplings=built.n_couplings,
        n_meshes=len(used),
        degrees_of_freedom=dof,
        total_mass_kg=float(model.body_mass.sum()),
        export_mass_kg=assembly.total_mass,
        warnings=assembly.warnings + plan.warnings + built.warnings + _locked_warning(locked),
        joint_origins=_joint_origins(assembly, plan, built),
    )


def ground_part(assembly, part: str) -> None:
    """Fix ``part`` (export or sanitised name) to the world: a synthetic weld to the ground."""
    from mechanism.converters.assembly import GROUND, Joint

    matches = [
        p for p in assembly.parts.values() if not p.virtual and part in (p.name, sanitize(p.name))
    ]
    if not matches:
        names = sorted({sanitize(p.name) for p in assembly.parts.values() if not p.virtual})
        raise ExportError(
            f"export {assembly.source.name}: no part {part!r} to fix to the world; close matches: "
            f"{', '.join(difflib.get_close_matches(part, names, 3)) or 'none'}"
        )
    chosen = matches[0]
    assembly.joints.insert(
        0,
        Joint(
            name=f"ground:{sanitize(chosen.name)}",
            kind="weld",
            base=GROUND,
            follower=chosen.key,
            base_frame=chosen.frame,
            follower_frame=chosen.frame,
            synthetic=True,
        ),
    )


def detect_up(assembly) -> tuple[str, str]:
    """(up axis, why): against the export's gravity vector where it carries one, else z (assumed)."""
    gravity = getattr(assembly, "gravity", None)
    if gravity is not None and float(np.linalg.norm(gravity)) > 0:
        axis = int(np.argmax(np.abs(gravity)))
        down = ("-" if gravity[axis] < 0 else "") + "xyz"[axis]
        up = down[1:] if down.startswith("-") else "-" + down
        return (
            up,
            f"the export's gravity vector ({', '.join(f'{v:g}' for v in gravity)}) points along {down}",
        )
    return (
        "z",
        "assumed: the export carries no gravity vector (give --up when its up axis is another)",
    )


def _joint_origins(assembly, plan, built) -> list[str]:
    """``joint <name> (<kind>): from mates a, b -> <what the MJCF has>`` for every joint of the
    export or of the mate inference (welds the mates make included; grounding and rigid
    sub-assemblies left out)."""
    closing = {id(closure.joint) for closure in plan.closures}
    lines = []
    for joint in assembly.joints:
        if joint.synthetic and not joint.sources:
            continue
        origin = (
            f"from mates {', '.join(joint.sources)}" if joint.sources else "from the export's joint"
        )
        if id(joint) in closing:
            result = "closes a loop (a loop: equality constraint)"
        elif joint.name in built.joint_names:
            result = "MJCF joint(s) " + ", ".join(built.joint_names[joint.name])
        elif joint.is_weld:
            result = "parts merged into one body"
        else:
            result = "inside one rigid body: no MJCF joint"
        lines.append(f"joint {joint.name} ({joint.kind}): {origin} -> {result}")
    return lines


def _locked_warning(locked: list[str]) -> list[str]:
    if not locked:
        return []
    shown = ", ".join(locked[:10]) + (f" and {len(locked) - 10} more" if len(locked) > 10 else "")
    return [
        f"{len(locked)} joint(s) cannot move at the assembly pose because closed loops lock them: {shown} "
        f"(check the export for welds or joints that over-constrain the mechanism)"
    ]


# Relative singular value below which a loop equation counts as dependent. Exports print 6 to 9
# digits: axes that are parallel in the CAD model come out parallel to ~1e-6 rad, so a loop that
# over-constrains a real motion (a pin mated to a plane and a bore) leaves a singular value near
# 1e-8 where that motion should be, while genuine constraints give 1e-3 and more.


def mobility(model) -> tuple[int, list[str]]:
    """Degrees of freedom the equality constraints leave at the assembly pose (``nv - rank(J_eq)``)
    and the joints they lock completely.

    A joint that is only instantaneously immobile at a dead centre (a slider-crank's slider at
    top dead centre) is not locked: the check also looks at poses a small step away along
    the allowed motions, and a joint counts as locked only if it cannot move at any of them."""
    import mujoco
    import numpy as np

    model = copy.copy(model)
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    data = mujoco.MjData(model)

    def allowed_motions(qpos):
        data.qpos[:] = qpos
        mujoco.mj_forward(model, data)
        rows = data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        jacobian = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)[rows]
        if jacobian.size == 0:
            return 0, np.eye(model.nv)
        _, singular, vt = np.linalg.svd(jacobian)
        rank = int(np.sum(singular > RANK_TOLERANCE * max(singular.max(), 1e-300)))
        return rank, vt[rank:].T  # columns span the motions the constraints allow

    if model.nv == 0:
        return 0, []
    rank, free_motions = allowed_motions(model.qpos0)
    movable = np.zeros(model.nv, bool)
    probes = [None] + [
        np.random.default_rng(k).normal(size=free_motions.shape[1]) for k in range(3)
    ]
    for direction in probes:
        qpos = model.qpos0.copy()
        if direction is not None:
            if not free_motions.size:
                break
            step = free_motions @ direction
            mujoco.mj_integratePos(model, qpos, 0.02 * step / max(np.abs(step).max(), 1e-300), 1.0)
        _, motions = allowed_motions(qpos)
        if motions.size:
            movable |= np.linalg.norm(motions, axis=1) > 1e-6
    locked = []
    for joint in range(model.njnt):
        start = model.jnt_dofadr[joint]
        width = {0: 6, 1: 3}.get(int(model.jnt_type[joint]), 1)
        if not movable[start : start + width].any():
            locked.append(model.joint(joint).name)
    return int(model.nv - rank), locked


@contextlib.contextmanager
def _staging(outdir: Path, meshdir: str):
    """A scratch tree mirroring ``outdir`` and its mesh folder, removed afterwards."""
    ups = sum(1 for piece in Path(meshdir).parts if piece == "..")
    root = Path(tempfile.mkdtemp(prefix=".mechanism-convert-"))
    try:
        model_dir = root.joinpath(*[f"d{i}" for i in range(ups)], "model")
        mesh_stage = Path(os.path.normpath(model_dir / meshdir))
        model_dir.mkdir(parents=True)
        mesh_stage.mkdir(parents=True, exist_ok=True)
        yield model_dir, mesh_stage
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _publish(model_file: Path, target: Path, meshes: list[tuple[Path, Path]], inputs=()) -> None:
    """Publish the model and its meshes as one output (see mechanism.files.outputs)."""
    from mechanism.files.outputs import publish_files

    publish_files([*meshes, (model_file, target)], folder=target.parent, inputs=inputs)
