"""Exact part shapes for distance and interference queries.

Each geom of a part becomes an fcl collision object in its geom frame: a mesh geom keeps
the exact triangles stored in the compiled model (``mesh_vert``/``mesh_face``, already in
the geom frame after MuJoCo's re-centring; never MuJoCo's convex hull), primitives become
the matching fcl primitive. Poses come from ``data.geom_xpos``/``geom_xmat``.

Distances (:meth:`PartShape.distance`) are fcl's BVH distances: exact for the stored
triangles up to floating point, so the only difference from the CAD surface is the
export's tessellation (chordal) error. fcl reports 0 for any overlap, so penetration is
measured separately (:func:`penetration`): the overlap solid ``A ∩ B`` comes from
manifold3d's exact mesh boolean; its surface consists of pieces of A's surface inside B
and of B's surface inside A, so the deepest point of either surface inside the other
lies on it. The surface is refined to a spacing of 1/4 of the overlap's size (at
least 1 µm), every vertex's depth is its distance to the other part's surface (fcl point
queries), and the triangles around the three deepest vertices are sampled 8 times finer.
The depth reported is the largest. For two convex bodies that is the translational
penetration depth (two spheres or parallel cylinders: r1 + r2 - d). It is exact when
the deepest point is a mesh vertex (a sharp point, a tessellated cylinder's facing
vertex); otherwise it is low by at most the final spacing, 1/32 of the overlap's largest
extent (and by much less near a smooth maximum, where depth varies quadratically).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import warnings

import fcl
import mujoco
import numpy as np

from mechanism.machine import parts
from mechanism.errors import UserError
from mechanism.tolerances import MIN_DEPTH_SPACING_M

# tessellation of primitives for the overlap solid only (distances use exact primitives)
PRIMITIVE_SECTIONS = 256
DEPTH_REFINEMENT = 4  # overlap surface refined to (overlap size / this) ...
FINE_PASS_VERTICES = 3  # ... then 8x finer around the deepest few vertices
ON_SURFACE_M = 1e-9  # a point this close to a surface lies on it


def _fcl_geometry(model: mujoco.MjModel, geom: int):
    kind = model.geom_type[geom]
    size = model.geom_size[geom]
    T = mujoco.mjtGeom
    if kind == T.mjGEOM_MESH:
        vertices, faces = mesh_triangles(model, geom)
        bvh = fcl.BVHModel()
        bvh.beginModel(len(vertices), len(faces))
        bvh.addSubModel(vertices, faces)
        bvh.endModel()
        return bvh
    if kind == T.mjGEOM_SPHERE:
        return fcl.Sphere(size[0])
    if kind == T.mjGEOM_CAPSULE:
        return fcl.Capsule(size[0], 2 * size[1])
    if kind == T.mjGEOM_CYLINDER:
        return fcl.Cylinder(size[0], 2 * size[1])
    if kind == T.mjGEOM_BOX:
        return fcl.Box(*(2 * size))
    if kind == T.mjGEOM_ELLIPSOID:
        return fcl.Ellipsoid(*size)
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or f"#{geom}"
    raise UserError(
        f"geom {name!r}: type {mujoco.mjtGeom(kind).name[7:].lower()} is not supported in clearance checks"
    )


def mesh_triangles(model: mujoco.MjModel, geom: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices [m] (in the geom frame) and faces of a mesh geom, as compiled."""
    mesh = model.geom_dataid[geom]
    v0, nv = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    f0, nf = model.mesh_faceadr[mesh], model.mesh_facenum[mesh]
    return model.mesh_vert[v0 : v0 + nv].astype(float), model.mesh_face[f0 : f0 + nf].astype(
        np.int64
    )


def geom_mesh(
    model: mujoco.MjModel, geom: int, sections: int = PRIMITIVE_SECTIONS
) -> tuple[np.ndarray, np.ndarray]:
    """A closed triangle mesh of the geom in its own frame: a mesh geom's own triangles,
    primitives tessellated with ``sections`` around their axis."""
    import trimesh

    kind, size = model.geom_type[geom], model.geom_size[geom]
    T = mujoco.mjtGeom
    if kind == T.mjGEOM_MESH:
        return mesh_triangles(model, geom)
    if kind == T.mjGEOM_SPHERE:
        mesh = trimesh.creation.icosphere(subdivisions=_subdivisions(sections), radius=size[0])
    elif kind == T.mjGEOM_CAPSULE:
        mesh = trimesh.creation.capsule(
            height=2 * size[1], radius=size[0], count=[sections, max(4, sections // 2)]
        )
    elif kind == T.mjGEOM_CYLINDER:
        mesh = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=sections)
    elif kind == T.mjGEOM_BOX:
        mesh = trimesh.creation.box(extents=2 * size)
    elif kind == T.mjGEOM_ELLIPSOID:
        mesh = trimesh.creation.icosphere(subdivisions=_subdivisions(sections), radius=1.0)
        mesh.apply_scale(size)
    else:
        _fcl_geometry(model, geom)  # raises the unsupported-type error
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)


def _subdivisions(sections: int) -> int:
    """Icosphere subdivisions giving about ``sections`` edges around a great circle."""
    return int(np.clip(np.round(np.log2(max(sections, 5) / 5)), 1, 5))


class PartShape:
    """The real shape of one part: fcl objects for its shape geoms, posed from ``data``."""

    def __init__(self, model: mujoco.MjModel, part: str):
        self.name = part
        self.model = model
        self.geoms = parts.shape_geoms(model, part)
        self.body = int(model.geom_bodyid[self.geoms[0]])
        geometries = [_fcl_geometry(model, g) for g in self.geoms]
        self.objects = [fcl.CollisionObject(g, fcl.Transform()) for g in geometries]
        self._local_objects = [fcl.CollisionObject(g, fcl.Transform()) for g in geometries]
        self._probe = fcl.CollisionObject(fcl.Sphere(0.0), fcl.Transform())
        self._poses: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        # one manifold3d solid per geom, built on first use; False when a mesh is not a closed solid
        self._solids: list[Any] | Literal[False] | None = None

    def update(self, data: mujoco.MjData) -> None:
        for geom, obj in zip(self.geoms, self.objects):
            rotation, origin = (
                data.geom_xmat[geom].reshape(3, 3).copy(),
                data.geom_xpos[geom].copy(),
            )
            self._poses[geom] = (rotation, origin)
            obj.setTransform(fcl.Transform(rotation, origin))

    def distance(self, other: "PartShape") -> tuple[float, np.ndarray, np.ndarray]:
        """Smallest distance [m] and the closest points (world, m); 0 when they overlap."""
        best: tuple[float, np.ndarray, np.ndarray] | None = None
        request = fcl.DistanceRequest(enable_nearest_points=True)
        for a in self.objects:
            for b in other.objects:
                result = fcl.DistanceResult()
                value = max(fcl.distance(a, b, request, result), 0.0)
                if best is None or value < best[0]:
                    best = (
                        value,
                        np.array(result.nearest_points[0]),
                        np.array(result.nearest_points[1]),
                    )
                if value == 0.0:
                    return best
        assert best is not None, "a PartShape has at least one geom (its body is its first geom's)"
        return best

    def point_distance(self, point: np.ndarray) -> tuple[float, np.ndarray]:
        """Unsigned distance [m] from a world point to the part's surface, and the nearest point.

        Queried in each geom's own frame: fcl returns the nearest point of a shape-vs-mesh
        query in the mesh's local frame, so the mesh stays at the identity there."""
        request = fcl.DistanceRequest(enable_nearest_points=True)
        best: tuple[float, np.ndarray] | None = None
        for geom, local in zip(self.geoms, self._local_objects):
            rotation, origin = self._poses[geom]
            self._probe.setTranslation(rotation.T @ (np.asarray(point, dtype=float) - origin))
            result = fcl.DistanceResult()
            value = fcl.distance(local, self._probe, request, result)
            if best is None or value < best[0]:
                best = (max(value, 0.0), origin + rotation @ np.asarray(result.nearest_points[0]))
        assert best is not None, "a PartShape has at least one geom (its body is its first geom's)"
        return best

    def solid(self, data: mujoco.MjData):
        """The part as a posed manifold3d solid (union of its geoms), or None when one of
        its meshes is not a closed solid (then overlaps have no volume or depth)."""
        import manifold3d

        if self._solids is None:
            self._solids = []
            for geom in self.geoms:
                vertices, faces = geom_mesh(self.model, geom)
                solid = manifold3d.Manifold(
                    manifold3d.Mesh64(vert_properties=vertices, tri_verts=faces.astype(np.uint32))
                )
                if solid.status() != manifold3d.Error.NoError:
                    name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, geom)
                    warnings.warn(
                        f"part {self.name!r}: the mesh of geom {name!r} is not a closed solid "
                        f"({solid.status().name}); its interferences get no depth"
                    )
                    self._solids = False
                    break
                self._solids.append(solid)
        if self._solids is False:
            return None
        posed = []
        for geom, solid in zip(self.geoms, self._solids):
            transform = np.hstack(
                [data.geom_xmat[geom].reshape(3, 3), data.geom_xpos[geom].reshape(3, 1)]
            )
            posed.append(solid.transform(transform))
        return (
            manifold3d.Manifold.batch_boolean(posed, manifold3d.OpType.Add)
            if len(posed) > 1
            else posed[0]
        )


@dataclass
class Penetration:
    depth: float  # [m], 0 when the solids only touch
    point_a: np.ndarray  # deepest point pair (world, m): on A's surface and on B's surface
    point_b: np.ndarray
    volume: float  # overlap volume [m³]


def overlap_volume(a: PartShape, b: PartShape, data: mujoco.MjData) -> float:
    """Volume [m³] of the overlap of two posed parts (0 when they are apart or only touch;
    NaN when a mesh is not closed)."""
    solid_a, solid_b = a.solid(data), b.solid(data)
    if solid_a is None or solid_b is None:
        return float("nan")
    return max((solid_a ^ solid_b).volume(), 0.0)


def penetration(a: PartShape, b: PartShape, data: mujoco.MjData) -> Penetration:
    """The overlap of two posed parts: largest depth of either surface inside the other
    (NaN depth and volume when a mesh is not a closed solid)."""
    solid_a, solid_b = a.solid(data), b.solid(data)
    if solid_a is None or solid_b is None:
        _, pa, pb = a.distance(b)
        return Penetration(float("nan"), pa, pb, float("nan"))
    overlap = solid_a ^ solid_b
    volume = overlap.volume()
    if overlap.is_empty() or volume <= 0.0:
        _, pa, pb = a.distance(b)
        return Penetration(0.0, pa, pb, 0.0)
    low, high = (np.asarray(v) for v in _bounds(overlap))
    spacing = max(float(np.max(high - low)) / DEPTH_REFINEMENT, MIN_DEPTH_SPACING_M)
    mesh = overlap.refine_to_length(spacing).to_mesh64()
    points = np.asarray(mesh.vert_properties)[:, :3]
    triangles = np.asarray(mesh.tri_verts)
    coarse = _depths(a, b, points)
    best = max(coarse, key=lambda item: item.depth)
    # second pass: the triangles around the deepest few vertices, sampled 8x finer
    top = np.argsort([-item.depth for item in coarse])[:FINE_PASS_VERTICES]
    around = points[triangles[np.any(np.isin(triangles, top), axis=1)]]
    weights = np.array([(i, j, 8 - i - j) for i in range(9) for j in range(9 - i)], dtype=float) / 8
    finer = _depths(a, b, np.einsum("kv,tvd->tkd", weights, around).reshape(-1, 3))
    best = max([best, *finer], key=lambda item: item.depth)
    return Penetration(best.depth, best.point_a, best.point_b, volume)


def _depths(a: PartShape, b: PartShape, points: np.ndarray) -> list[Penetration]:
    """Depth of each point of the overlap's surface: a point on B's surface lies inside A
    (depth = its distance to A's surface), a point on A's surface inside B."""
    found = []
    for point in points:
        depth_in_a, on_a = a.point_distance(point)
        if depth_in_a > ON_SURFACE_M:
            found.append(Penetration(depth_in_a, on_a, point, 0.0))
            continue
        depth_in_b, on_b = b.point_distance(point)
        found.append(Penetration(depth_in_b, point, on_b, 0.0))
    return found


def _bounds(solid):
    box = solid.bounding_box()
    return box[:3], box[3:]
