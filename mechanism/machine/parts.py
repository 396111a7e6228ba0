"""CAD parts in a compiled model: where a name's frame is and which geoms are its shape.

The converter (docs/architecture.md) keeps every CAD part addressable by its name:
a site ``<part>`` at the CAD part frame, geoms ``<part>``, ``<part>_2``, ... (class
``visual`` in group 1, class ``collision`` in group 3), and user-named CAD frames as
sites (``needle_tip``). Hand-written MJCF is accepted too: a name may also be a body or
a geom, whose own frame then serves as the part frame.

Every lookup failure is a :class:`~mechanism.errors.UserError` that lists close matches.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import mujoco
import numpy as np

from mechanism.errors import UserError, close_matches

VISUAL_GROUP = 1
COLLISION_GROUP = 3


def _names(model: mujoco.MjModel, objtype, count: int) -> list[str]:
    return [mujoco.mj_id2name(model, objtype, i) or "" for i in range(count)]


@dataclass(frozen=True)
class Frame:
    """A named frame fixed to a body: position [m] and quaternion (w, x, y, z) in the body frame."""

    name: str
    kind: str  # "site", "body" or "geom"
    body: int
    pos: np.ndarray
    quat: np.ndarray

    def point_in_body(self, point_m) -> np.ndarray:
        """A point given in this frame [m], expressed in the body frame [m]."""
        rotated = np.zeros(3)
        mujoco.mju_rotVecQuat(rotated, np.asarray(point_m, dtype=float), self.quat)
        return self.pos + rotated


def frame_names(model: mujoco.MjModel) -> list[str]:
    """Every name a probe can address: sites, bodies and geoms."""
    names = set(_names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite))
    names |= set(_names(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody))
    names |= set(part_names(model))
    names.discard("")
    return sorted(names)


def find_frame(model: mujoco.MjModel, name: str) -> Frame:
    """The frame of a part (its site), a user-named frame (site), a body or a geom."""
    for kind, objtype in (
        ("site", mujoco.mjtObj.mjOBJ_SITE),
        ("body", mujoco.mjtObj.mjOBJ_BODY),
        ("geom", mujoco.mjtObj.mjOBJ_GEOM),
    ):
        index = mujoco.mj_name2id(model, objtype, name)
        if index < 0:
            continue
        if kind == "site":
            return Frame(
                name,
                kind,
                int(model.site_bodyid[index]),
                model.site_pos[index].copy(),
                model.site_quat[index].copy(),
            )
        if kind == "body":
            return Frame(name, kind, index, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
        return Frame(
            name,
            kind,
            int(model.geom_bodyid[index]),
            model.geom_pos[index].copy(),
            model.geom_quat[index].copy(),
        )
    raise UserError(
        f"no part, frame or body named {name!r} in the model; close matches: {close_matches(name, frame_names(model))}"
    )


def part_names(model: mujoco.MjModel) -> list[str]:
    """Names of the parts that have a shape: geoms ``<part>``, ``<part>_visual`` (the
    converter's visual copy) or ``<part>_<n>`` (more geoms of one part)."""
    geoms = [name for name in _names(model, mujoco.mjtObj.mjOBJ_GEOM, model.ngeom) if name]
    sites = set(_names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite))
    known = set(geoms)
    parts = set()
    for name in geoms:
        match = re.fullmatch(r"(.+)_(\d+|visual)", name)
        if match and (match.group(1) in known or match.group(1) in sites) and name not in sites:
            parts.add(match.group(1))
        else:
            parts.add(name)
    return sorted(parts)


def part_geoms(model: mujoco.MjModel, part: str) -> list[int]:
    """All geoms of a part: ``<part>``, ``<part>_visual`` and ``<part>_<n>`` (unless that
    name is a part of its own, i.e. has its own site)."""
    sites = set(_names(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite))
    pattern = re.compile(rf"{re.escape(part)}_(\d+|visual)")
    found = []
    for index, name in enumerate(_names(model, mujoco.mjtObj.mjOBJ_GEOM, model.ngeom)):
        if name == part or (pattern.fullmatch(name) and name not in sites):
            found.append(index)
    if not found:
        raise UserError(
            f"no part named {part!r} with a shape in the model; close matches: {close_matches(part, part_names(model))}"
        )
    return found


def shape_geoms(model: mujoco.MjModel, part: str) -> list[int]:
    """The geoms that are the part's real shape for distance checks.

    Collision-class geoms (group 3) when the part has any, else all its geoms (hand-written
    models). Among collision geoms, those marked for exact mesh distance (contype 0 and
    conaffinity 0: the exact triangles of a non-convex part) win over any convex pieces
    the converter added for MuJoCo's contact dynamics.
    """
    geoms = part_geoms(model, part)
    collision = [g for g in geoms if model.geom_group[g] == COLLISION_GROUP]
    if not collision:
        return geoms
    exact = [g for g in collision if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0]
    return exact or collision


def joint_names(model: mujoco.MjModel) -> list[str]:
    return [name for name in _names(model, mujoco.mjtObj.mjOBJ_JOINT, model.njnt) if name]


def _loop_joint_of(name: str) -> str | None:
    """``loop:crank_pin``, ``loop:crank_pin_2`` or ``loop:crank_pin:a`` -> ``crank_pin``."""
    if not name.startswith("loop:"):
        return None
    return re.sub(r"(:[A-Za-z0-9]+|_\d+)$", "", name[5:])


def loop_equalities(model: mujoco.MjModel, joint: str) -> list[int]:
    """The ``connect``/``weld`` equalities that close a loop at ``joint`` (the converter names
    them ``loop:<joint>``; a revolute joint needs two, suffixed ``_<n>`` or ``:<tag>``)."""
    names = _names(model, mujoco.mjtObj.mjOBJ_EQUALITY, model.neq)
    return [
        i
        for i, name in enumerate(names)
        if name == f"loop:{joint}" or _loop_joint_of(name) == joint
    ]


def loop_joint_names(model: mujoco.MjModel) -> list[str]:
    names = _names(model, mujoco.mjtObj.mjOBJ_EQUALITY, model.neq)
    return sorted({joint for name in names if (joint := _loop_joint_of(name))})
