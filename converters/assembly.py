"""The neutral, in-memory assembly every reader produces and the MJCF writer consumes.

Everything is SI and expressed in the export's world frame at the assembly pose:
positions in metres, masses in kg, inertias in kg*m^2 about the part's centre of mass
with world axes. Readers know their XML dialect; nothing downstream does.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mechanism.converters.pose import Pose

GROUND = "<ground>"
"""Key of the world (ground) node in :attr:`Joint.base` / :attr:`Joint.follower`."""

HINGE, SLIDE, BALL = "hinge", "slide", "ball"


@dataclass
class NamedFrame:
    """A user-named CAD frame (becomes an MJCF site in the body of its part)."""

    name: str
    pose: Pose


@dataclass
class Part:
    """One rigid CAD part (or a massless helper node such as a sub-assembly origin)."""

    key: str  # unique id inside the assembly (reader-specific)
    name: str  # CAD name as written in the export
    mass: float  # kg
    com: np.ndarray  # centre of mass, world, m
    inertia: np.ndarray  # 3x3 about the centre of mass, world axes, kg*m^2
    frame: Pose  # the part frame (the frame its geometry file is written in), world
    geometry: Path | None = None  # resolved geometry file inside the export folder
    geometry_name: str = ""  # the file name as written in the export
    geometry_scale: float = 1.0  # metres per STL unit (STEP carries its own units)
    color: tuple = (0.7, 0.7, 0.7, 1.0)
    volume: float | None = None  # m^3 when the export states it
    frames: list[NamedFrame] = field(default_factory=list)
    virtual: bool = False  # a helper node (sub-assembly origin): no geoms, no site
    # kg*m^2 the export rounds inertias to (0: relative precision only)
    inertia_resolution: float = 0.0


@dataclass
class Primitive:
    """One degree-of-freedom group of a joint: a hinge or slide along ``axis`` (world), or a ball."""

    kind: str  # HINGE | SLIDE | BALL
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))


@dataclass
class Joint:
    """A CAD joint between two parts (or a part and :data:`GROUND`).

    ``primitives`` are ordered from base to follower; an empty list is a weld. Positive
    motion is the follower's motion relative to the base about/along each axis.
    """

    name: str
    kind: str  # the export's joint type, for messages ("revolute", "cylindrical", "weld", ...)
    base: str
    follower: str
    base_frame: Pose  # the joint frame on the base part, world, at the assembly pose
    follower_frame: Pose  # the joint frame on the follower part, world, at the assembly pose
    primitives: list[Primitive] = field(default_factory=list)
    synthetic: bool = False  # made by a reader (grounding, rigid sub-assembly), not a CAD joint
    # the CAD mates it was found from (mate inference)
    sources: list[str] = field(default_factory=list)

    @property
    def is_weld(self) -> bool:
        return not self.primitives

    @property
    def dof(self) -> int:
        return sum(3 if p.kind == BALL else 1 for p in self.primitives)


@dataclass
class Coupling:
    """A joint coupling from the side-car: ``q_input = ratio * q_output + offset``."""

    name: str
    kind: str
    input: str  # joint name as written in the export
    output: str
    ratio: float
    offset: float = 0.0  # rad (hinges) or m (slides)


@dataclass
class Assembly:
    """What a reader found in an export: parts, joints, couplings and the warnings it raised."""

    name: str
    source: Path
    format: str
    parts: dict[str, Part] = field(default_factory=dict)
    joints: list[Joint] = field(default_factory=list)
    couplings: list[Coupling] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    gravity: np.ndarray | None = None  # the export's gravity vector (any unit) where it carries one

    def warn(self, message: str) -> None:
        if message not in self.warnings:
            self.warnings.append(message)

    @property
    def real_parts(self) -> list[Part]:
        return [part for part in self.parts.values() if not part.virtual]

    @property
    def total_mass(self) -> float:
        return float(sum(part.mass for part in self.parts.values()))

    def joint(self, name: str) -> Joint | None:
        for joint in self.joints:
            if joint.name == name:
                return joint
        return None
