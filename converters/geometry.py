"""Part geometry: STL (ascii or binary, in the export's length unit) and STEP (tessellated by
OpenCASCADE through trimesh + cascadio), turned into binary STL meshes in metres.

Meshes keep their CAD triangles (only faces with non-finite or repeated-vertex corners are
dropped) because the clearance checker measures exact distances on them. A part is convex
when its volume is within 1% of its convex hull's; only convex parts collide in MuJoCo.
Identical meshes (same bytes) are written once and shared.
"""

from __future__ import annotations

import hashlib
import io
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mechanism.converters.assembly import Assembly, Part
from mechanism.converters.names import Namer
from mechanism.converters.safety import MAX_GEOMETRY_BYTES

# tessellation chord error: 0.05 mm is below CAD tolerances of machined parts
STEP_LINEAR_DEFLECTION_MM = 0.05
STEP_ANGULAR_DEFLECTION_RAD = 0.5
CONVEX_VOLUME_RATIO = 0.99
PLAUSIBLE_DENSITY = (20.0, 30000.0)  # kg/m^3: foam to tungsten; outside it a mesh unit is wrong
ALTERNATIVE_UNITS = {"mm": 1e-3, "m": 1.0, "in": 0.0254, "cm": 1e-2}
STL_HEADER = b"mechanism converter: binary STL, metres".ljust(80, b" ")

FORMATS = {".stl": "stl", ".step": "step", ".stp": "step", ".obj": "obj", ".ply": "ply"}


@dataclass
class Mesh:
    """A mesh asset in its part's frame, metres."""

    name: str  # MJCF asset name (file is ``name + ".stl"``)
    vertices: np.ndarray
    faces: np.ndarray
    data: bytes  # binary STL
    convex: bool

    @property
    def filename(self) -> str:
        return self.name + ".stl"


class GeometryError(Exception):
    """A geometry file that exists but cannot be used (the part falls back to a box)."""


def _load(path: Path, scale: float):
    import trimesh

    file_type = FORMATS.get(path.suffix.lower())
    if file_type is None:
        raise GeometryError(f"format '{path.suffix}' is not supported (STL, STEP, OBJ, PLY)")
    if path.stat().st_size > MAX_GEOMETRY_BYTES:
        raise GeometryError(f"larger than {MAX_GEOMETRY_BYTES} bytes")
    if path.stat().st_size == 0:
        raise GeometryError("file is empty")
    try:
        if file_type == "step":
            loaded = trimesh.load(
                str(path),
                file_type="step",
                tol_linear=STEP_LINEAR_DEFLECTION_MM,
                tol_angular=STEP_ANGULAR_DEFLECTION_RAD,
            )
            scale = 1.0  # OpenCASCADE converts STEP units; glTF is in metres
        else:
            loaded = trimesh.load(io.BytesIO(path.read_bytes()), file_type=file_type, process=False)
    except Exception as exc:  # noqa: BLE001 - any reader failure means "unusable geometry"
        raise GeometryError(
            f"cannot be read ({exc.__class__.__name__}: {' '.join(str(exc).split())[:120]})"
        ) from None
    mesh: object = loaded  # a scene's flattening can be a list of geometries: checked below
    if isinstance(loaded, trimesh.Scene):
        mesh = (
            loaded.to_geometry()
            if hasattr(loaded, "to_geometry")
            else loaded.dump(concatenate=True)
        )
    if not isinstance(mesh, trimesh.Trimesh):
        raise GeometryError("contains no triangles")
    vertices = np.asarray(mesh.vertices, dtype=float) * scale
    faces = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    return vertices, faces


def _clean(vertices: np.ndarray, faces: np.ndarray):
    finite = np.all(np.isfinite(vertices), axis=1)
    keep = finite[faces].all(axis=1)
    keep &= (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    faces = faces[keep]
    if len(faces) == 0:
        raise GeometryError("contains no usable triangles")
    used, inverse = np.unique(faces.ravel(), return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3)


def stl_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A deterministic binary STL (float32, fixed header, zero attribute bytes)."""
    triangles = vertices[faces].astype(np.float32)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]).astype(
        np.float64
    )
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0).astype(
        np.float32
    )
    record = np.zeros(
        len(faces), dtype=[("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")]
    )
    record["normal"] = normals
    record["corners"] = triangles
    return STL_HEADER + struct.pack("<I", len(faces)) + record.tobytes()


def is_convex(vertices: np.ndarray, faces: np.ndarray) -> bool:
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=True)
    try:
        hull = mesh.convex_hull.volume
    except Exception:  # noqa: BLE001 - flat or degenerate point sets have no hull
        return False
    return bool(hull > 0 and abs(mesh.volume) >= CONVEX_VOLUME_RATIO * hull)


def load_meshes(assembly: Assembly) -> dict[str, Mesh | None]:
    """The mesh of every part that names a geometry file (None where it is missing or unusable).

    Problems become warnings on ``assembly``: one summary for missing files, one per unusable file.
    """
    raw = _read_all([part.geometry for part in assembly.real_parts if part.geometry is not None])
    scaled: dict[tuple, Mesh] = {}
    by_digest: dict[str, Mesh] = {}
    namer = Namer()
    missing: list[str] = []
    meshes: dict[str, Mesh | None] = {}
    for part in assembly.real_parts:
        if part.geometry is None:
            continue
        loaded = raw[part.geometry]
        meshes[part.key] = None
        if loaded is None:
            missing.append(part.geometry_name)
            continue
        if isinstance(loaded, GeometryError):
            assembly.warn(
                f"geometry file {part.geometry_name} of part {part.name} {loaded}: the part gets an "
                f"equivalent-inertia box instead"
            )
            continue
        vertices, faces, has_units, convex = loaded
        scale = 1.0 if has_units else _choose_scale(assembly, part, vertices, faces)
        if (part.geometry, scale) not in scaled:
            scaled[(part.geometry, scale)] = _mesh(
                part, vertices * scale, faces, namer, by_digest, convex if scale == 1.0 else None
            )
        mesh = meshes[part.key] = scaled[(part.geometry, scale)]
        _check_placement(assembly, part, mesh)
    if missing:
        unique = list(dict.fromkeys(missing))
        shown = ", ".join(unique[:8]) + (f" and {len(unique) - 8} more" if len(unique) > 8 else "")
        assembly.warn(
            f"{len(unique)} geometry file(s) are missing from {assembly.source.parent} ({shown}): "
            f"{len(missing)} part(s) get equivalent-inertia boxes instead of meshes"
        )
    return meshes


def _read_all(paths: list[Path]) -> dict[Path, tuple | GeometryError | None]:
    """Every distinct file read once. STEP files are tessellated in worker processes, one per
    core: OpenCASCADE takes seconds per part inside C++, where a Ctrl-C waits for it to return;
    the main process only waits for the workers, stops them at once on an interrupt, and an
    export of many parts converts in a fraction of the time."""
    distinct = list(dict.fromkeys(paths))
    steps = [p for p in distinct if FORMATS.get(p.suffix.lower()) == "step" and p.exists()]
    found: dict[Path, tuple | GeometryError | None] = {}
    if steps:
        found.update(_read_in_workers(steps))
    for path in distinct:
        if path not in found:
            found[path] = _read(path)
    return found


def _read_in_workers(paths: list[Path]) -> dict[Path, tuple | GeometryError | None]:
    import multiprocessing
    import sys
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from tqdm import tqdm

    from mechanism.files.interrupts import ignore_in_worker, stop_pool
    from mechanism.files.limits import usable_cores

    method = "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"
    pool = ProcessPoolExecutor(
        max_workers=max(1, min(len(paths), usable_cores())),
        mp_context=multiprocessing.get_context(method),
        initializer=ignore_in_worker,
    )
    finished = False
    try:
        # the largest first: the workers then end together
        order = sorted(paths, key=lambda p: -p.stat().st_size)
        futures = {pool.submit(_read, path, judge_convexity=True): path for path in order}
        found = {}
        # a bar on a terminal (hidden otherwise): an export of many parts reads for seconds
        with tqdm(
            total=len(futures),
            desc="reading STEP geometry",
            unit=" file",
            file=sys.stderr,
            disable=None,
            leave=False,
        ) as bar:
            for future in as_completed(futures):
                found[futures[future]] = future.result()
                bar.update(1)
        finished = True
        return found
    finally:
        stop_pool(pool, at_once=not finished)


def _read(path: Path, judge_convexity: bool = False) -> tuple | GeometryError | None:
    """(vertices, faces, carries_units, convex) of a geometry file in its own units, None if it
    does not exist. ``convex`` is None unless asked for (a worker judges it beside the reading:
    a second or two of an export of many parts, then on every core)."""
    if not path.exists():
        return None
    try:
        vertices, faces = _clean(*_load(path, 1.0))
    except GeometryError as exc:
        return exc
    convex = is_convex(vertices, faces) if judge_convexity else None
    return vertices, faces, FORMATS.get(path.suffix.lower()) == "step", convex


def _holds_com(part: Part, vertices: np.ndarray, scale: float) -> bool:
    com = part.frame.inverse().apply(part.com)
    low, high = vertices.min(axis=0) * scale, vertices.max(axis=0) * scale
    margin = 0.1 * float(np.linalg.norm(high - low)) + 1e-9
    return not (np.any(com < low - margin) or np.any(com > high + margin))


def _density_plausible(part: Part, vertices: np.ndarray, faces: np.ndarray, scale: float) -> bool:
    import trimesh

    mesh = trimesh.Trimesh(vertices * scale, faces, process=True)
    if not mesh.is_watertight or abs(mesh.volume) <= 0:
        return True
    return bool(PLAUSIBLE_DENSITY[0] <= part.mass / abs(mesh.volume) <= PLAUSIBLE_DENSITY[1])


def _choose_scale(assembly: Assembly, part: Part, vertices, faces) -> float:
    """STL carries no unit: take the export's, unless the part's centre of mass only falls inside
    the mesh in another common unit (then the density decides between candidates)."""
    if part.mass <= 0 or _holds_com(part, vertices, part.geometry_scale):
        return part.geometry_scale
    fits = [
        (unit, scale)
        for unit, scale in ALTERNATIVE_UNITS.items()
        if scale != part.geometry_scale and _holds_com(part, vertices, scale)
    ]
    fits.sort(key=lambda fit: not _density_plausible(part, vertices, faces, fit[1]))
    if not fits:
        return part.geometry_scale
    unit, scale = fits[0]
    assembly.warn(
        f"geometry file {part.geometry_name} of part {part.name} only fits the part's mass properties "
        f"in {unit}: read in {unit} instead of the export's length unit"
    )
    return scale


def _mesh(
    part: Part, vertices, faces, namer: Namer, by_digest: dict, convex: bool | None = None
) -> Mesh:
    """The part's mesh asset (one per distinct STL); ``convex`` if already judged on these very
    vertices."""
    data = stl_bytes(vertices, faces)
    digest = hashlib.sha256(data).hexdigest()
    if digest not in by_digest:
        by_digest[digest] = Mesh(
            name=namer(Path(part.geometry_name.replace("\\", "/")).stem),
            vertices=vertices,
            faces=faces,
            data=data,
            convex=is_convex(vertices, faces) if convex is None else convex,
        )
    return by_digest[digest]


def _check_placement(assembly: Assembly, part: Part, mesh: Mesh) -> None:
    """Warn when the centre of mass lies far outside the mesh: wrong units or wrong frame."""
    if part.mass <= 0:
        return
    com = part.frame.inverse().apply(part.com)
    low, high = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    margin = 0.25 * float(np.linalg.norm(high - low)) + 1e-6
    if np.any(com < low - margin) or np.any(com > high + margin):
        assembly.warn(
            f"part {part.name}: its centre of mass lies outside its geometry ({part.geometry_name}); "
            f"check the geometry's units and frame"
        )
