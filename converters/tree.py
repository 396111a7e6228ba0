"""From an assembly's joint graph to MuJoCo's kinematic tree: rigid bodies, tree joints, loop closures.

* Parts joined by welds (CAD weld joints, grounding, rigid sub-assemblies) form one body.
* The tree is a spanning tree of the joint graph rooted at the ground, chosen greedily
  (Kruskal) so that the joints a user drives and the joints that are costly or inexact to
  close stay real tree joints: the named drivers first (``convert --driver``, a machine
  description's motor and shaft joints), joints named by couplings, then joints that would
  need a carrier body to close (prismatic, cylindrical, planar, universal, ...), spherical
  joints, revolute joints in a bearing on the frame (a crank a user turns), and pins between
  moving parts last (a revolute closes exactly with two ``connect`` constraints on its axis).
* A real joint locked by a chain of welds (its two parts are also welded together) is kept
  as a tree joint and the weld that closes that cycle becomes the loop closure instead.
* Every joint left out of the tree closes a loop. Welds between parts that ended in one
  body are redundant and dropped.
* A group of parts not connected to the ground is fixed to the world at its heaviest part,
  with a warning: nothing floats.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from mechanism.converters.assembly import BALL, GROUND, HINGE, Assembly, Joint
from mechanism.converters.graph import UnionFind
from mechanism.converters.names import sanitize


@dataclass
class Body:
    index: int
    parts: list[str]  # part keys, root-most first (may include GROUND and virtual nodes)
    parent: int | None = None  # index of the parent body; None: a child of the world body
    joint: Joint | None = None  # the tree joint from the parent body
    reversed: bool = False  # the joint's base part is in this body (motion measured the other way)
    children: list[int] = field(default_factory=list)

    @property
    def is_ground(self) -> bool:
        return GROUND in self.parts


@dataclass
class Closure:
    joint: Joint
    base_body: int
    follower_body: int


@dataclass
class Plan:
    bodies: list[Body]
    closures: list[Closure]
    body_of: dict[str, int]
    warnings: list[str] = field(default_factory=list)

    @property
    def ground(self) -> Body:
        return self.bodies[0]

    def depth_first(self):
        """Bodies parents-first, children in joint order (the MJCF nesting order)."""
        order = []
        pending = [b.index for b in self.bodies if b.parent is None]
        pending.reverse()
        while pending:
            index = pending.pop()
            order.append(self.bodies[index])
            pending.extend(reversed(self.bodies[index].children))
        return order


def tree_rank(
    joint: Joint,
    coupled: set[str],
    drivers: frozenset[str] | set[str] = frozenset(),
    on_frame: bool = False,
) -> tuple:
    """Sort key: lower ranks are taken into the tree first (closing them would cost most)."""
    kinds = [p.kind for p in joint.primitives]
    if joint.name in drivers or sanitize(joint.name) in drivers:
        rank = -1
    elif joint.name in coupled:
        rank = 0
    elif kinds == [HINGE]:
        rank = 3 if on_frame else 4
    elif kinds == [BALL]:
        rank = 2
    else:
        rank = 1
    return (rank,)


def plan(assembly: Assembly, drivers: frozenset[str] | set[str] = frozenset()) -> Plan:
    """Choose bodies, tree joints and loop closures for ``assembly``; the joints named in
    ``drivers`` (export or sanitised names) stay joints of the tree whenever a tree can hold them."""
    order = {id(joint): i for i, joint in enumerate(assembly.joints)}
    welds = [j for j in assembly.joints if j.is_weld]
    reals = [j for j in assembly.joints if not j.is_weld]
    coupled = {name for c in assembly.couplings for name in (c.input, c.output)}

    weld_only = UnionFind()
    for joint in welds:
        weld_only.union(joint.base, joint.follower)
    locked = [j for j in reals if weld_only.find(j.base) == weld_only.find(j.follower)]
    frame = weld_only.find(GROUND)

    def on_frame(joint: Joint) -> bool:
        return frame in (weld_only.find(joint.base), weld_only.find(joint.follower))

    free = sorted(
        (j for j in reals if j not in locked),
        key=lambda j: (tree_rank(j, coupled, drivers, on_frame(j)), order[id(j)]),
    )

    spanning = UnionFind()
    tree_joints: list[Joint] = []
    left_out: list[Joint] = []
    for joint in locked + welds + free:
        (tree_joints if spanning.union(joint.base, joint.follower) else left_out).append(joint)
    warnings = [
        f"joint {j.name} ({j.kind}) is locked by welds between its parts: kept as a joint, "
        f"the weld closing that cycle becomes a loop constraint"
        for j in locked
        if j in tree_joints
    ]

    # bodies: parts joined by tree welds
    rigid = UnionFind()
    keys = [GROUND] + list(assembly.parts)
    for key in keys:
        rigid.find(key)
    for joint in tree_joints:
        if joint.is_weld:
            rigid.union(joint.base, joint.follower)
    groups: dict[str, list[str]] = {}
    for key in keys:
        groups.setdefault(rigid.find(key), []).append(key)

    def real(key: str) -> bool:
        return key != GROUND and not assembly.parts[key].virtual

    moving_joints = [j for j in tree_joints if not j.is_weld]
    linked = {rigid.find(k) for j in moving_joints for k in (j.base, j.follower)}
    ground_root = rigid.find(GROUND)
    roots = [ground_root] + [
        r for r in groups if r != ground_root and (any(real(k) for k in groups[r]) or r in linked)
    ]

    adjacency: dict[str, list[Joint]] = {r: [] for r in roots}
    for joint in moving_joints:
        adjacency[rigid.find(joint.base)].append(joint)
        adjacency[rigid.find(joint.follower)].append(joint)

    bodies: list[Body] = []
    body_of: dict[str, int] = {}
    weld_links = [j for j in tree_joints if j.is_weld]

    def add_body(
        root: str, entry: str, parent: int | None, joint: Joint | None, reversed_: bool
    ) -> int:
        body = Body(
            index=len(bodies),
            parts=_ordered(groups[root], entry, weld_links, keys),
            parent=parent,
            joint=joint,
            reversed=reversed_,
        )
        bodies.append(body)
        for key in groups[root]:
            body_of[key] = body.index
        if parent is not None:
            bodies[parent].children.append(body.index)
        return body.index

    def grow(start: int) -> None:
        queue = [start]
        while queue:
            index = queue.pop(0)
            root = rigid.find(bodies[index].parts[0])
            for joint in sorted(adjacency[root], key=lambda j: order[id(j)]):
                base_root, follower_root = rigid.find(joint.base), rigid.find(joint.follower)
                other, entry, rev = (
                    (follower_root, joint.follower, False)
                    if base_root == root
                    else (base_root, joint.base, True)
                )
                if groups[other][0] in body_of:
                    continue
                queue.append(add_body(other, entry, index, joint, rev))

    grow(add_body(ground_root, GROUND, None, None, False))
    for root in roots:
        if groups[root][0] in body_of:
            continue
        members = _component(root, adjacency, rigid)
        parts = sorted((k for r in members for k in groups[r] if real(k)), key=keys.index)
        if not parts:
            continue
        heaviest = max(parts, key=lambda k: (assembly.parts[k].mass, -keys.index(k)))
        anchor = rigid.find(heaviest)
        names = ", ".join(assembly.parts[k].name for k in parts[:6]) + (
            f" and {len(parts) - 6} more" if len(parts) > 6 else ""
        )
        if len(members) == 1:
            warnings.append(
                f"part(s) {names} are connected to nothing (no joint, not grounded): fixed to the world"
            )
        else:
            warnings.append(
                f"parts {names} ({len(members)} bodies joined by joints) are not connected to the ground: "
                f"{assembly.parts[heaviest].name} (the heaviest) is fixed to the world"
            )
        grow(add_body(anchor, heaviest, None, None, False))

    closures = []
    for joint in left_out:
        base_body, follower_body = body_of.get(joint.base), body_of.get(joint.follower)
        if base_body is None or follower_body is None:
            continue
        if base_body == follower_body:
            if not joint.is_weld:
                warnings.append(
                    f"joint {joint.name} ({joint.kind}) connects parts of one rigid body: ignored"
                )
            continue
        closures.append(Closure(joint, base_body, follower_body))
    return Plan(bodies=bodies, closures=closures, body_of=body_of, warnings=warnings)


def _ordered(members: list[str], entry: str, welds: list[Joint], keys: list[str]) -> list[str]:
    """Members root-most first: breadth-first over welds from the entry part, ties in export order."""
    member_set = set(members)
    neighbours: dict[str, list[str]] = {m: [] for m in members}
    for joint in welds:
        if joint.base in member_set and joint.follower in member_set:
            neighbours[joint.base].append(joint.follower)
            neighbours[joint.follower].append(joint.base)
    seen, queue, result = {entry}, [entry], []
    while queue:
        key = queue.pop(0)
        result.append(key)
        for other in sorted(neighbours[key], key=keys.index):
            if other not in seen:
                seen.add(other)
                queue.append(other)
    return result + [m for m in members if m not in seen]


def _component(root: str, adjacency: dict, rigid: UnionFind) -> list[str]:
    seen, queue = {root}, [root]
    while queue:
        current = queue.pop()
        for joint in adjacency[current]:
            for key in (joint.base, joint.follower):
                other = rigid.find(key)
                if other not in seen:
                    seen.add(other)
                    queue.append(other)
    return sorted(seen)
