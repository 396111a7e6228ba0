"""Motion relations of second-generation exports: gears, rack-and-pinions, worms and screws.

Unlike mates they fix no position: they tie one joint's motion to another's. Each becomes a joint
coupling (``q_input = ratio * q_output``, the side-car's convention) between the 1-DOF joints that
carry its two parts, with a warning that says what was assumed. The ratio comes from the export
(an explicit ratio, the two radii or tooth counts, a lead or pitch); a relation without one, or
whose parts turn on no 1-DOF joint, is reported and left out (the couplings side-car can add it).
Relations with no joint-coupling equivalent (point on curve, cam, path) are reported and ignored.
"""

from __future__ import annotations

import math
import re

import numpy as np

from mechanism.converters.assembly import GROUND, HINGE, SLIDE, Assembly, Coupling
from mechanism.converters.graph import UnionFind

# (substring of the normalised element name, kind); the first match wins
KINDS = (
    ("rackandpinion", "rack_and_pinion"),
    ("rackpinion", "rack_and_pinion"),
    ("rack", "rack_and_pinion"),
    ("worm", "worm_gear"),
    ("bevel", "bevel_gear"),
    ("gear", "gear"),
    ("leadscrew", "screw"),
    ("screw", "screw"),
    ("belt", "belt"),
    ("pulley", "belt"),
    ("chain", "chain"),
    ("pointoncurve", None),
    ("curve", None),
    ("cam", None),
    ("path", None),
    ("slot", None),
)


def _normalised(tag: str) -> str:
    return re.sub(r"[^a-z]", "", tag.lower())


def kind_of(tag: str) -> str | None:
    name = _normalised(tag)
    for key, kind in KINDS:
        if key in name:
            return kind
    return None


def is_relation(tag: str) -> bool:
    name = _normalised(tag)
    return any(key in name for key, _ in KINDS)


def _values(element) -> dict[str, str]:
    """Every attribute and leaf text below ``element``, keyed by lower-case name (first wins)."""
    values: dict[str, str] = {}
    for node in element.iter():
        for key, value in node.attrib.items():
            values.setdefault(_normalised(key), value)
        local = node.tag.rsplit("}", 1)[-1] if isinstance(node.tag, str) else ""
        if len(node) == 0 and node.text and node.text.strip():
            values.setdefault(_normalised(local), node.text.strip())
    return values


def _number(values: dict[str, str], *names: str) -> float | None:
    """The first non-zero number whose key contains all ``+``-joined pieces of one of ``names``."""
    for name in names:
        for key, text in values.items():
            if all(piece in key for piece in name.split("+")):
                try:
                    value = float(text.split()[0])
                except (ValueError, IndexError):
                    continue
                if math.isfinite(value) and value != 0:
                    return value
    return None


def _ratio(kind: str, values: dict[str, str], length: float) -> tuple[float | None, str]:
    """The magnitude of the relation (base motion per follower motion) and where it came from."""
    explicit = _number(values, "ratio")
    if kind in ("gear", "bevel_gear", "worm_gear", "belt", "chain"):
        if explicit is not None:
            return abs(explicit), "the export's ratio"
        for measure in ("teeth", "radius", "diameter"):
            follower, base = (
                _number(values, f"follower+{measure}"),
                _number(values, f"base+{measure}"),
            )
            if follower is not None and base is not None:
                return abs(follower / base), f"the export's {measure}"
        return None, ""
    if kind == "rack_and_pinion":
        radius = _number(values, "pinion+radius", "radius")
        if radius is not None:
            return abs(radius) * length, "the export's pinion radius"
        return (abs(explicit), "the export's ratio") if explicit is not None else (None, "")
    if kind == "screw":
        lead = _number(values, "lead", "pitch")
        if lead is not None:
            return abs(lead) * length / (2 * math.pi), "the export's lead"
        return (abs(explicit), "the export's ratio") if explicit is not None else (None, "")
    return None, ""


def _welded(assembly: Assembly) -> UnionFind:
    """Which parts the assembly's welds fix together (joint endpoints may be any part of a body)."""
    sets = UnionFind()
    for joint in assembly.joints:
        if joint.is_weld:
            sets.union(joint.base, joint.follower)
    return sets


def _carrier_joint(assembly: Assembly, welded: UnionFind, part: str, axis: np.ndarray, want: str):
    """The 1-DOF joint (of kind ``want``) that moves ``part``, preferring one along ``axis``;
    returns (joint, +1 if the part is on its follower side else -1), or (None, 0)."""
    group = welded.find(part)
    best = None
    for joint in assembly.joints:
        if joint.dof != 1 or joint.primitives[0].kind != want:
            continue
        sides = [
            s for s, end in ((1, joint.follower), (-1, joint.base)) if welded.find(end) == group
        ]
        other = joint.base if sides and sides[0] == 1 else joint.follower
        if not sides or welded.find(other) == group:
            continue
        score = abs(float(joint.primitives[0].axis @ axis))
        if best is None or score > best[0] + 1e-9:
            best = (score, joint, sides[0])
    return (best[1], best[2]) if best else (None, 0)


def add_relation(assembly: Assembly, element, side, length: float) -> None:
    """Turn one gear-like constraint element into a coupling on ``assembly`` (or a warning).
    ``side(element, where) -> (part key, world pose)`` resolves one side; ``length``: m per export unit."""
    tag = element.tag.rsplit("}", 1)[-1]
    name = element.get("name") or tag
    where = f"export {assembly.source.name}, constraint {name}"
    kind = kind_of(tag)
    if kind is None:
        assembly.warn(
            f"constraint {name} <{tag}> has no joint-coupling equivalent: ignored "
            f"(the mechanism may move where the CAD constraint would not let it)"
        )
        return
    children = [
        c
        for c in element
        if c.tag.rsplit("}", 1)[-1] in ("ConstraintGeometry", "BaseFrame", "FollowerFrame")
    ]
    if len(children) != 2:
        assembly.warn(f"constraint {name} <{tag}> does not name two parts: ignored")
        return
    try:
        (base_part, base_pose), (follower_part, follower_pose) = (side(c, where) for c in children)
    except Exception as exc:  # noqa: BLE001 - an unresolvable side only loses this relation
        assembly.warn(f"constraint {name} <{tag}> is ignored: {str(exc).split(': ', 1)[-1]}")
        return
    magnitude, source = _ratio(kind, _values(element), length)
    welded = _welded(assembly)
    want_base = SLIDE if kind == "rack_and_pinion" else HINGE
    base_joint, base_sign = _carrier_joint(
        assembly, welded, base_part, base_pose.rotation[:, 2], want_base
    )
    follower_joint, follower_sign = _carrier_joint(
        assembly, welded, follower_part, follower_pose.rotation[:, 2], HINGE
    )
    names = {
        k: assembly.parts[k].name if k != GROUND else "world" for k in (base_part, follower_part)
    }
    between = f"between {names[base_part]} and {names[follower_part]}"
    if base_joint is None or follower_joint is None or base_joint is follower_joint:
        assembly.warn(
            f"{kind.replace('_', ' ')} constraint {name} {between}: no 1-DOF joint carries each part, "
            f"so it is not modelled (add a coupling to the side-car, see docs/architecture.md)"
        )
        return
    repeated = [
        j.name
        for j in (base_joint, follower_joint)
        if sum(1 for o in assembly.joints if o.name == j.name) > 1
    ]
    if repeated:
        assembly.warn(
            f"{kind.replace('_', ' ')} constraint {name} {between}: joint name {repeated[0]} repeats in the "
            f"export, so the coupling cannot name it: not modelled"
        )
        return
    if magnitude is None:
        assembly.warn(
            f"{kind.replace('_', ' ')} constraint {name} {between}: the export states no ratio, so it is "
            f"not modelled; add it to the couplings side-car (input {base_joint.name}, output "
            f"{follower_joint.name})"
        )
        return
    alignment = float(base_joint.primitives[0].axis @ follower_joint.primitives[0].axis)
    internal = "internal" in _normalised(tag) or "ring" in _normalised(tag)
    if kind in ("gear", "belt", "chain") and abs(alignment) > 0.999:
        # external gears turn opposite ways, internal gears, belts and chains the same way
        same_way = internal or kind in ("belt", "chain")
        sign = (
            (1.0 if same_way else -1.0) * base_sign * follower_sign * math.copysign(1.0, alignment)
        )
        assumption = (
            "internal gear" if internal else ("belt or chain" if same_way else "external gear")
        )
    else:
        sign = 1.0
        assumption = "direction not determined by the export: check the sign"
    ratio = sign * magnitude
    assembly.couplings.append(
        Coupling(
            name=name, kind=kind, input=base_joint.name, output=follower_joint.name, ratio=ratio
        )
    )
    assembly.warn(
        f"{kind.replace('_', ' ')} constraint {name} {between} becomes the joint coupling "
        f"{base_joint.name} = {ratio:.6g} x {follower_joint.name} ({assumption}; ratio from {source})"
    )
