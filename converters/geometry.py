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

from converters.assembly import Assembly, Part
from converters.names import Namer
from converters.safety import MAX_GEOMETRY_BYTES

STEP_LINEAR_DEFLECTION_MM = 0.05  # tessellation chord error: 0.05 mm is below CAD tolerances of machined parts
STEP_ANGULAR_DEFLECTION_RAD = 0.5
CONVEX_VOLUME_RATIO = 0.99
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
            loaded = trimesh.load(str(path), file_type="step", tol_linear=STEP_LINEAR_DEFLECTION_MM,
                                  tol_angular=STEP_ANGULAR_DEFLECTION_RAD)
            scale = 1.0  # OpenCASCADE converts STEP units; glTF is in metres
        else:
            loaded = trimesh.load(io.BytesIO(path.read_bytes()), file_type=file_type, process=False)
    except Exception as exc:  # noqa: BLE001 - any reader failure means "unusable geometry"
        raise GeometryError(f"cannot be read ({exc.__class__.__name__}: {' '.join(str(exc).split())[:120]})") from None
    if isinstance(loaded, trimesh.Scene):
        loaded = loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded.dump(concatenate=True)
    if not isinstance(loaded, trimesh.Trimesh):
        raise GeometryError("contains no triangles")
    vertices = np.asarray(loaded.vertices, dtype=float) * scale
    faces = np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    return vertices, faces


def _clean(vertices: np.ndarray, faces: np.ndarray):
    finite = np.all(np.isfinite(vertices), axis=1)
    keep = finite[faces].all(axis=1)
    keep &= (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    faces = faces[keep]
    if len(faces) == 0:
        raise GeometryError("contains no usable triangles")
    used, inverse = np.unique(faces.ravel(), return_inverse=True)
    return vertices[used], inverse.reshape(-1, 3)


def stl_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A deterministic binary STL (float32, fixed header, zero attribute bytes)."""
    triangles = vertices[faces].astype(np.float32)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]).astype(np.float64)
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0).astype(np.float32)
    record = np.zeros(len(faces), dtype=[("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
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
    cache: dict[tuple, Mesh | GeometryError | None] = {}
    by_digest: dict[str, Mesh] = {}
    namer = Namer()
    missing: list[str] = []
    meshes: dict[str, Mesh | None] = {}
    for part in assembly.real_parts:
        if part.geometry is None:
            continue
        key = (part.geometry, part.geometry_scale)
        if key not in cache:
            cache[key] = _mesh_for(part, namer, by_digest)
        result = cache[key]
        if result is None:
            missing.append(part.geometry_name)
            meshes[part.key] = None
        elif isinstance(result, GeometryError):
            assembly.warn(f"geometry file {part.geometry_name} of part {part.name} {result}: the part gets an "
                          f"equivalent-inertia box instead")
            meshes[part.key] = None
        else:
            meshes[part.key] = result
            _check_placement(assembly, part, result)
    if missing:
        unique = list(dict.fromkeys(missing))
        shown = ", ".join(unique[:8]) + (f" and {len(unique) - 8} more" if len(unique) > 8 else "")
        assembly.warn(f"{len(unique)} geometry file(s) are missing from {assembly.source.parent} ({shown}): "
                      f"{len(missing)} part(s) get equivalent-inertia boxes instead of meshes")
    return meshes


def _mesh_for(part: Part, namer: Namer, by_digest: dict) -> Mesh | GeometryError | None:
    if not part.geometry.exists():
        return None
    try:
        vertices, faces = _clean(*_load(part.geometry, part.geometry_scale))
    except GeometryError as exc:
        return exc
    data = stl_bytes(vertices, faces)
    digest = hashlib.sha256(data).hexdigest()
    if digest in by_digest:
        return by_digest[digest]
    mesh = Mesh(name=namer(Path(part.geometry_name.replace("\\", "/")).stem), vertices=vertices, faces=faces,
                data=data, convex=is_convex(vertices, faces))
    by_digest[digest] = mesh
    return mesh


def _check_placement(assembly: Assembly, part: Part, mesh: Mesh) -> None:
    """Warn when the centre of mass lies far outside the mesh: wrong units or wrong frame."""
    if part.mass <= 0:
        return
    com = part.frame.inverse().apply(part.com)
    low, high = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    margin = 0.25 * float(np.linalg.norm(high - low)) + 1e-6
    if np.any(com < low - margin) or np.any(com > high + margin):
        assembly.warn(f"part {part.name}: its centre of mass lies outside its geometry ({part.geometry_name}); "
                      f"check the geometry's units and frame")
