"""CAD mates (assembly constraints) -> joints: what second-generation exports from SolidWorks,
Creo and Inventor carry instead of joints.

Those exporters write the assembly's mates (``<Coincident>``, ``<Concentric>``, ``<Parallel>``...,
each between two pieces of geometry: a plane, an axis, a point) and leave it to the importer to
find the joints, as Simscape's ``smimport`` does. This module does the same, for any mate set:

* Parts fixed together by the instance tree (grounded parts, rigid sub-assemblies, rigid groups)
  form units. Mates are grouped by the pair of units they join.
* The mates of a pair are linearised at the assembly pose: each becomes residual equations in the
  relative pose of the two units, and the null space of their Jacobian is the set of motions the
  mates allow. Its dimension is the number of freedoms; its rotation directions, the point the
  rotations pass through and its translations give the joint: weld, revolute, prismatic,
  cylindrical, planar, spherical, universal, pin-slot, or a compound of slides and hinges.
* Each pair is analysed once, as Simscape's import does: a pair the mates weld becomes one body, every
  other pair its own joint, also where pairs close a loop through parts welded to each other (a
  bearing mated to a plane of one part and to a bore of a part bolted to it turns on a planar and a
  cylindrical joint closing a loop; weights stacked on a bracket, each mated to the bracket and to
  its neighbour, are held by prismatic and planar joints that lock them). Re-analysing the pairs
  after merging the welds would give fewer joints, but not the ones Simscape's import lists
  (checked on a SolidWorks export whose Simscape DataFile lists 63 joints).

Mate geometry comes in world coordinates (metres) at the assembly pose. Mate kinds with no
positional meaning (gears, cams, unknown constraints) are not handled here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from mechanism.converters.assembly import BALL, HINGE, SLIDE, Joint, Primitive
from mechanism.converters.graph import UnionFind
from mechanism.converters.pose import Pose
from mechanism.tolerances import MATE_RANK_TOLERANCE as RANK_TOLERANCE, PIVOT_TOLERANCE

PLANE, AXIS, POINT = "plane", "axis", "point"
SPHERE = "sphere"
GEOMETRY_KINDS = {
    "plane": PLANE,
    "face": PLANE,
    "planarface": PLANE,
    "surface": PLANE,
    "cylinder": AXIS,
    "circle": AXIS,
    "arc": AXIS,
    "cone": AXIS,
    "line": AXIS,
    "axis": AXIS,
    "edge": AXIS,
    "ellipse": AXIS,
    "torus": AXIS,
    "linearedge": AXIS,
    "circularedge": AXIS,
    "point": POINT,
    "vertex": POINT,
    "sphere": POINT,
    "origin": POINT,
}
CIRCULAR = {"circle", "arc", "circularedge"}

# mate names as CAD tools write them (SolidWorks, Inventor, Creo, Onshape) -> the kind analysed here
MATE_KINDS = {
    "coincident": "coincident",
    "mate": "coincident",
    "flush": "coincident",
    "align": "coincident",
    "aligned": "coincident",
    "pointonline": "coincident",
    "pntonline": "coincident",
    "pointonsurface": "coincident",
    "pntonsrf": "coincident",
    "coplanar": "coincident",
    "concentric": "concentric",
    "coaxial": "concentric",
    "centered": "concentric",
    "insert": "insert",
    "parallel": "parallel",
    "orient": "parallel",
    "perpendicular": "perpendicular",
    "normal": "perpendicular",
    "distance": "distance",
    "offset": "distance",
    "distanceconstraint": "distance",
    "angle": "angle",
    "angleconstraint": "angle",
    "tangent": "tangent",
    "lock": "weld",
    "rigid": "weld",
    "fixed": "weld",
    "fix": "weld",
    "fastened": "weld",
    "weld": "weld",
    "default": "weld",
    "coordsys": "weld",
    "csys": "weld",
    # a mate the exporter could not describe (a SolidWorks lock, width or symmetric mate): Simscape's
    # import makes it rigid (the Furuta export's Lock3: its DataFile has no joint between the two parts)
    "unknownconstraint": "weld",
}

STEP = 1e-6  # finite-difference step (rad, and units of the pair's size)
ORIGIN_PLACEMENT_DOF = 4  # mates to the assembly origin leaving this many freedoms or more place a part, they make no joint


@dataclass
class MateGeometry:
    """One side of a mate, in world coordinates at the assembly pose."""

    part: str  # part key (or GROUND)
    shape: str  # the export's geomType, lower case
    position: np.ndarray  # m
    axis: np.ndarray | None  # unit vector (plane normal, axis direction), or None for points

    @property
    def kind(self) -> str:
        return GEOMETRY_KINDS.get(
            re.sub(r"[^a-z]", "", self.shape), POINT if self.axis is None else AXIS
        )


@dataclass
class Mate:
    name: str
    tag: str  # element name as written in the export (Coincident, Concentric, ...)
    first: MateGeometry
    second: MateGeometry

    @property
    def kind(self) -> str | None:
        return mate_kind(self.tag)


def mate_kind(tag: str) -> str | None:
    """The kind analysed here of a mate element named ``tag``; None for one with no positional meaning."""
    return MATE_KINDS.get(re.sub(r"[^a-z]", "", tag.lower()))


@dataclass
class Freedoms:
    """The motions a set of mates leaves between two units, at the assembly pose."""

    kind: str  # weld, revolute, prismatic, cylindrical, planar, spherical, universal, pinslot, ... or free
    primitives: list[Primitive]
    anchor: np.ndarray  # a point on every rotation axis (world, m)
    main_axis: np.ndarray  # the joint frame's z axis

    @property
    def dof(self) -> int:
        return sum(3 if p.kind == BALL else 1 for p in self.primitives)


@dataclass
class Inferred:
    joints: list[Joint] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


# -- residuals -------------------------------------------------------------------------------


def _direction(g: MateGeometry) -> np.ndarray | None:
    return g.axis if g.kind in (PLANE, AXIS) else None


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 1e-300 else v


def _pair(a: MateGeometry, b: MateGeometry, order: tuple[str, ...]):
    """(a, b) reordered so that a's kind comes first in ``order`` (residuals are symmetric)."""
    return (a, b) if order.index(a.kind) <= order.index(b.kind) else (b, a)


def residuals(kind: str, a: MateGeometry, b: MateGeometry, scale: float) -> np.ndarray | None:
    """The equations ``kind`` imposes between geometries ``a`` and ``b`` (distances divided by
    ``scale``), or None when the mate has no positional meaning for these geometry kinds."""
    if kind == "weld":
        return None  # handled as a full lock
    da, db = _direction(a), _direction(b)
    if kind == "parallel":
        return None if da is None or db is None else np.cross(da, db)
    if kind == "perpendicular":
        return None if da is None or db is None else np.array([da @ db])
    if kind == "angle":
        if da is None or db is None:
            return None
        return np.cross(da, db) if abs(da @ db) > 1 - 1e-9 else np.array([da @ db])
    a, b = _pair(a, b, (PLANE, AXIS, POINT))
    da, db = _direction(a), _direction(b)
    if (a.kind != POINT and da is None) or (b.kind != POINT and db is None):
        return (
            None  # a plane or an axis exported without its direction: it constrains nothing known
        )
    # from here a direction is None exactly for a point, and a point comes last in the pair's order
    gap = (b.position - a.position) / scale
    if kind in ("coincident", "distance", "tangent"):
        exact = kind == "coincident"
        if da is None:  # two points
            return gap if exact or np.linalg.norm(gap) < 1e-9 else np.array([np.linalg.norm(gap)])
        if a.kind == PLANE:
            if db is None:
                return np.array([gap @ da])
            if b.kind == PLANE:
                return np.concatenate([np.cross(da, db), [gap @ da]])
            return np.array([da @ db, gap @ da])
        if db is None:  # an axis and a point
            return _off_line(gap, da, exact)
        if exact and a.shape in CIRCULAR and b.shape in CIRCULAR:
            return np.concatenate([np.cross(da, db), gap])
        return np.concatenate([np.cross(da, db), _off_line(gap, da, exact)])
    if kind in ("concentric", "insert"):
        if a.kind == PLANE:
            return None
        if da is None:  # two points
            return gap
        if db is None:  # an axis and a point
            return np.cross(gap, da)
        along = gap if kind == "insert" else np.cross(gap, da)
        return np.concatenate([np.cross(da, db), along])
    return None


def _off_line(gap: np.ndarray, direction: np.ndarray, exact: bool) -> np.ndarray:
    """A point ``gap`` away stays on the line (exact) or at its distance from it."""
    off = np.cross(gap, direction)
    if exact or np.linalg.norm(off) < 1e-9:
        return off
    return np.array([np.linalg.norm(off)])


def _rotation(rotvec: np.ndarray) -> np.ndarray:
    angle = np.linalg.norm(rotvec)
    if angle < 1e-300:
        return np.eye(3)
    k = rotvec / angle
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew


def _moved(g: MateGeometry, twist: np.ndarray, centre: np.ndarray, scale: float) -> MateGeometry:
    rotation = _rotation(twist[:3])
    position = centre + rotation @ (g.position - centre) + twist[3:] * scale
    axis = None if g.axis is None else rotation @ g.axis
    return MateGeometry(g.part, g.shape, position, axis)


def jacobian(
    mates: list[tuple[str, MateGeometry, MateGeometry]], centre: np.ndarray, scale: float
) -> np.ndarray:
    """d(residuals)/d(twist of the second unit): twist = (rotation about ``centre`` [rad],
    translation [units of ``scale``]). ``mates``: (kind, geometry on unit A, geometry on unit B)."""
    rows = []
    for kind, a, b in mates:
        if kind == "weld":
            rows.append(np.eye(6))
            continue
        columns = []
        for i in range(6):
            step = np.zeros(6)
            step[i] = STEP
            plus = residuals(kind, a, _moved(b, step, centre, scale), scale)
            minus = residuals(kind, a, _moved(b, -step, centre, scale), scale)
            if (
                plus is None or minus is None
            ):  # moving b changes no geometry kind: the mate was never usable
                raise ValueError(
                    f"a {kind} mate between a {a.kind} and a {b.kind} constrains nothing (see usable())"
                )
            columns.append((plus - minus) / (2 * STEP))
        rows.append(np.array(columns).T)
    return np.vstack(rows) if rows else np.zeros((0, 6))


def _null_space(matrix: np.ndarray, tolerance: float) -> np.ndarray:
    """Orthonormal columns spanning the null space (relative ``tolerance`` on singular values)."""
    if matrix.size == 0:
        return np.eye(matrix.shape[1])
    _, singular, vt = np.linalg.svd(matrix)
    rank = int(np.sum(singular > tolerance * max(singular.max(), 1.0)))
    return vt[rank:].T


def frame_with_z(z: np.ndarray) -> np.ndarray:
    z = _unit(z)
    helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
    x = _unit(np.cross(helper, z))
    return np.column_stack([x, np.cross(z, x), z])


def freedoms(mates: list[tuple[str, MateGeometry, MateGeometry]]) -> Freedoms:
    """The joint the mates between two units amount to (linearised at the assembly pose)."""
    points = np.array([g.position for _, a, b in mates for g in (a, b)])
    centre = points.mean(axis=0)
    scale = max(float(np.max(np.linalg.norm(points - centre, axis=1))), 1e-3)
    motions = _null_space(jacobian(mates, centre, scale), RANK_TOLERANCE)  # 6 x d twists
    rotations, translations = motions[:3], motions[3:] * scale
    if motions.shape[1] == 0:
        return Freedoms("weld", [], centre, np.array([0, 0, 1.0]))
    # pure translations: motions with no rotation
    pure = motions @ _null_space(rotations, 1e-6) if rotations.size else motions
    slides = _orthonormal_columns(pure[3:]) if pure.size else np.zeros((3, 0))
    spin_basis = _orthonormal_columns(rotations)
    r = spin_basis.shape[1]
    if r == 0:
        kind = {1: "prismatic", 2: "rectangular", 3: "cartesian"}[slides.shape[1]]
        prims = [Primitive(SLIDE, slides[:, i].copy()) for i in range(slides.shape[1])]
        return Freedoms(kind, prims, centre, slides[:, 0].copy())
    anchor = _rotation_centre(rotations, translations, slides, spin_basis, centre)
    if r == 1:
        axis = _canonical(spin_basis[:, 0])
        # the point of the axis nearest the mates
        anchor = anchor + ((centre - anchor) @ axis) * axis
        along = [i for i in range(slides.shape[1]) if abs(slides[:, i] @ axis) > 0.999]
        across = _orthonormal_columns(slides - np.outer(axis, axis @ slides))
        if not slides.shape[1]:
            return Freedoms("revolute", [Primitive(HINGE, axis)], anchor, axis)
        if along and slides.shape[1] == 1:
            return Freedoms(
                "cylindrical", [Primitive(SLIDE, axis.copy()), Primitive(HINGE, axis)], anchor, axis
            )
        if not along and across.shape[1] == 2 and slides.shape[1] == 2:
            frame = frame_with_z(axis)
            return Freedoms(
                "planar",
                [
                    Primitive(SLIDE, frame[:, 0]),
                    Primitive(SLIDE, frame[:, 1]),
                    Primitive(HINGE, axis),
                ],
                anchor,
                axis,
            )
        if not along and slides.shape[1] == 1:
            return Freedoms(
                "pinslot",
                [Primitive(SLIDE, across[:, 0].copy()), Primitive(HINGE, axis)],
                anchor,
                axis,
            )
        prims = [Primitive(SLIDE, slides[:, i].copy()) for i in range(slides.shape[1])] + [
            Primitive(HINGE, axis)
        ]
        return Freedoms("compound", prims, anchor, axis)
    prims = [Primitive(SLIDE, slides[:, i].copy()) for i in range(slides.shape[1])]
    if r == 2:
        first, second = _canonical(spin_basis[:, 0]), _canonical(spin_basis[:, 1])
        kind = "universal" if not slides.shape[1] else "compound"
        return Freedoms(
            kind, prims + [Primitive(HINGE, first), Primitive(HINGE, second)], anchor, first
        )
    kind = {0: "spherical", 3: "free"}.get(slides.shape[1], "compound")
    return Freedoms(kind, prims + [Primitive(BALL)], anchor, np.array([0, 0, 1.0]))


def _canonical(v: np.ndarray) -> np.ndarray:
    """A unit vector with a deterministic sign (largest component positive)."""
    v = _unit(np.asarray(v, dtype=float))
    return v if v[np.argmax(np.abs(v))] > 0 else -v


def _orthonormal_columns(matrix: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the span of ``matrix``'s columns (unit-size motions: an absolute
    threshold, so the rounding noise of a pure translation does not count as a rotation)."""
    if matrix.size == 0:
        return np.zeros((3, 0))
    u, singular, _ = np.linalg.svd(matrix, full_matrices=False)
    rank = int(np.sum(singular > 1e-6))
    basis = u[:, :rank]
    if rank == 3:
        return np.eye(3)
    return (
        np.column_stack([_canonical(basis[:, i]) for i in range(rank)])
        if rank
        else np.zeros((3, 0))
    )


def _rotation_centre(rotations, translations, slides, spin_basis, centre) -> np.ndarray:
    """The point every allowed rotation passes through: for a twist with rotation w about
    ``centre`` and translation v, the axis passes through p where w x (centre - p) = v, up to the
    free translations.

    Solved for the offset ``p - centre`` with an absolute cut-off on the singular values (the
    rotations are unit vectors, so the equations are of order one): a direction the equations do
    not fix (a planar joint's pivot, a cylindrical joint's position along its axis) stays at the
    mates' centre instead of turning the exporter's rounding noise into a pivot metres away."""
    rows, rhs = [], []
    drop = np.eye(3) - slides @ slides.T if slides.size else np.eye(3)
    for w_dir in spin_basis.T:
        coefficients, *_ = np.linalg.lstsq(rotations, w_dir, rcond=None)
        w, v = rotations @ coefficients, translations @ coefficients
        skew = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        # w x (centre - p) = v  ->  skew @ (p - centre) = -v, free translations projected out
        rows.append(drop @ skew)
        rhs.append(drop @ -v)
    matrix, target = np.vstack(rows), np.concatenate(rhs)
    u, singular, vt = np.linalg.svd(matrix, full_matrices=False)
    keep = singular > PIVOT_TOLERANCE
    offset = vt[keep].T @ ((u[:, keep].T @ target) / singular[keep])
    return centre + offset


# -- from mates to joints --------------------------------------------------------------------


def usable(mate: Mate) -> bool:
    """Whether the mate constrains the relative position of its two parts (so it makes a joint)."""
    kind = mate.kind
    return kind is not None and (
        kind == "weld" or residuals(kind, mate.first, mate.second, 1.0) is not None
    )


def sphere_tangent(mate: Mate) -> bool:
    """A ``Tangent`` mate on a sphere (a ball rolling on a plane or in a groove): Simscape's import
    makes no joint from it (spheres and tangency are outside the mates it supports)."""
    return mate.kind == "tangent" and any(SPHERE in _shape(g) for g in (mate.first, mate.second))


def _shape(g: MateGeometry) -> str:
    return re.sub(r"[^a-z]", "", g.shape)


def infer_joints(
    mates: list[Mate],
    rigid_links: list[tuple[str, str]],
    names: dict[str, str],
    origins: frozenset[str] = frozenset(),
) -> Inferred:
    """Joints (and welds) between the units the ``mates`` join. ``rigid_links``: part pairs the
    instance tree already fixes together; ``names``: part key -> name for joint names and messages;
    ``origins``: keys that stand for an assembly's own origin (the world, a sub-assembly's frame)."""
    result = Inferred()
    units = UnionFind()
    for a, b in rigid_links:
        units.union(a, b)
    counts: dict[str, int] = {}
    for label in names.values():
        counts[label] = counts.get(label, 0) + 1

    def name(key: str) -> str:
        return names.get(key, key)

    def shown_name(key: str) -> str:
        """In messages: the key where several parts share the name."""
        return key if counts.get(name(key), 0) > 1 else name(key)

    usable_mates: list[Mate] = []
    unusable: dict[str, list[str]] = {}
    for mate in mates:
        if mate.first.part == mate.second.part:
            continue
        if sphere_tangent(mate):
            ball, other = (
                (mate.first, mate.second)
                if SPHERE in _shape(mate.first)
                else (mate.second, mate.first)
            )
            result.warnings.append(
                f"mate {mate.name} <{mate.tag}> between a sphere of {shown_name(ball.part)} and "
                f"{shown_name(other.part)}: no joint from it (Simscape's import makes none from a "
                f"sphere's tangency), so it does not hold {shown_name(ball.part)}"
            )
        elif usable(mate):
            usable_mates.append(mate)
        else:
            unusable.setdefault(mate.tag, []).append(mate.name)
    for tag, mate_names in unusable.items():
        shown = ", ".join(mate_names[:5]) + (
            f" and {len(mate_names) - 5} more" if len(mate_names) > 5 else ""
        )
        result.warnings.append(
            f"{len(mate_names)} <{tag}> mate(s) ({shown}) have no positional meaning for their "
            f"geometry or are not supported: ignored"
        )

    # each pair of units once, as Simscape's import does: no re-grouping after the welds are merged
    welded_pairs: list[tuple[list[Mate], Freedoms]] = []
    jointed_pairs: list[list[Mate]] = []
    for group in _pairs(usable_mates, units).values():
        found = _analyse(group, units)
        if found.kind == "weld":
            welded_pairs.append((group, found))
        else:
            jointed_pairs.append(group)

    for group, found in welded_pairs:
        base, follower = _ends(group)
        frame = Pose(np.eye(3), found.anchor)
        result.joints.append(
            Joint(
                name=f"{name(follower)} fixed to {name(base)} by mates",
                kind="weld",
                base=base,
                follower=follower,
                base_frame=frame,
                follower_frame=frame,
                synthetic=True,
                sources=[m.name for m in group],
            )
        )
    placed: list[
        tuple[str, int, list[str]]
    ] = []  # (part, freedoms, mates) placed against the origin
    for group in jointed_pairs:
        found = _analyse(group, units)
        base, follower = _ends(group)
        label = f"{name(base)}--{name(follower)}"
        listed_mates = ", ".join(m.name for m in group)
        if found.kind == "free":
            result.warnings.append(
                f"mates {listed_mates} between {name(base)} and {name(follower)} leave all six "
                f"freedoms: no joint"
            )
            continue
        if found.dof >= ORIGIN_PLACEMENT_DOF and all(
            {m.first.part, m.second.part} & origins for m in group
        ):
            placed.append(
                (
                    shown_name(follower if base in origins else base),
                    found.dof,
                    [m.name for m in group],
                )
            )
            continue
        frame = Pose(frame_with_z(found.main_axis), found.anchor)
        result.joints.append(
            Joint(
                name=label,
                kind=found.kind,
                base=base,
                follower=follower,
                base_frame=frame,
                follower_frame=frame,
                primitives=found.primitives,
                sources=[m.name for m in group],
            )
        )
    if placed:
        shown = "; ".join(
            f"{part} ({dof} freedoms, mates {', '.join(group)})" for part, dof, group in placed[:5]
        )
        more = f"; and {len(placed) - 5} more part(s)" if len(placed) > 5 else ""
        result.warnings.append(
            f"{len(placed)} part(s) are mated to the assembly origin only loosely, leaving "
            f"{ORIGIN_PLACEMENT_DOF} or more freedoms: {shown}{more}: those mates place the parts, "
            f"they make no joint to the world (as in Simscape's import)"
        )
    return result


def _pairs(mates: list[Mate], units: UnionFind) -> dict[tuple[str, str], list[Mate]]:
    pairs: dict[tuple[str, str], list[Mate]] = {}
    for mate in mates:
        a, b = units.find(mate.first.part), units.find(mate.second.part)
        if a != b:
            pairs.setdefault((min(a, b), max(a, b)), []).append(mate)
    return pairs


def _oriented(mate: Mate, base_unit: str, units: UnionFind) -> tuple[MateGeometry, MateGeometry]:
    if units.find(mate.first.part) == base_unit:
        return mate.first, mate.second
    return mate.second, mate.first


def _ends(group: list[Mate]) -> tuple[str, str]:
    """Base and follower parts: the first mate's first and second geometry (as ``smimport`` names them)."""
    return group[0].first.part, group[0].second.part


def _analyse(group: list[Mate], units: UnionFind) -> Freedoms:
    base_unit = units.find(group[0].first.part)
    oriented: list[tuple[str, MateGeometry, MateGeometry]] = []
    for mate in group:
        assert mate.kind is not None, "only usable() mates are grouped, and they have a kind"
        oriented.append((mate.kind, *_oriented(mate, base_unit, units)))
    return freedoms(oriented)
