"""Writer for first-generation SimMechanics ``PhysicalModelingXMLFile`` exports.

This is the format proe2sm / SimMechanics Link wrote from Pro/E (the path of the 2008
thesis). The layout follows real exports (see ``../shared/cad-exports/legs-creo-firstgen``):

* every value is a text node; strings are written in double quotes;
* every frame is given in WORLD (``positionOrigin``/``positionReferenceFrame`` WORLD);
* ``orientation`` is the 3x3 rotation from the frame to WORLD written column by column
  (MATLAB order: first the frame's x axis in WORLD, then its y axis, then its z axis);
* each body has a ``CG`` frame (centre of mass, axes of the part frame), a ``CS1`` frame
  (the part frame: the STL's coordinates) and then ``CSn`` frames: user frames (non-empty
  ``displayName``, nodeID ``n(USERADDED)``) and joint ports (``ref`` attribute);
* ``inertia`` is about the centre of mass in the ``CG`` frame's axes;
* joints are ``SimpleJoint`` elements whose base/follower refer to port frames by ``ref``,
  with one ``Primitive`` (revolute, prismatic or weld) whose axis is in WORLD;
* sub-assemblies are ``Subsystem`` elements with their own zero-mass ``RootPart``.

Numbers are written with six significant digits and three-digit exponents, as the
Windows exporters do, so a reader meets the same text it meets in the wild.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

_EXPONENT = re.compile(r"e([+-])(\d+)$")


def number(value: float) -> str:
    value = float(value)
    if value == 0.0:
        return "0"
    text = f"{value:.6g}"
    return _EXPONENT.sub(lambda m: f"e{m.group(1)}{int(m.group(2)):03d}", text)


def numbers(values) -> str:
    return ",".join(number(v) for v in np.asarray(values, dtype=float).ravel())


def column_major(rotation: np.ndarray) -> np.ndarray:
    return np.asarray(rotation, dtype=float).T.ravel()


@dataclass
class Frame:
    name: str
    node_id: str
    position: np.ndarray  # WORLD, mm
    rotation: np.ndarray  # frame -> WORLD
    display_name: str = ""
    ref: int | None = None


@dataclass
class Body:
    name: str
    node_id: str
    mass: float  # g
    inertia: np.ndarray  # g*mm^2 about the CG, CG-frame axes
    volume: float  # mm^3
    area: float  # mm^2
    frames: list[Frame] = field(default_factory=list)
    geometry_file: str = ""
    color: tuple[float, float, float] | None = None


@dataclass
class Joint:
    name: str
    node_id: str
    base_ref: int
    follower_ref: int
    primitive: str  # "revolute", "prismatic", "weld"
    axis: np.ndarray  # WORLD


@dataclass
class Ground:
    name: str
    frame: Frame


@dataclass
class Subsystem:
    name: str
    node_id: str
    bodies: list[Body] = field(default_factory=list)
    joints: list[Joint] = field(default_factory=list)


@dataclass
class Export:
    name: str
    created_using: str
    created_from: str
    created_on: str
    created_by: str
    bodies: list[Body]
    joints: list[Joint]
    grounds: list[Ground]
    subsystems: list[Subsystem]


WELD_AXIS = np.full(3, 1.0 / np.sqrt(3.0))


class _Writer:
    def __init__(self):
        self.lines: list[str] = []

    def line(self, depth: int, text: str) -> None:
        self.lines.append("  " * depth + text)

    def value(self, depth: int, tag: str, text: str) -> None:
        self.line(depth, f"<{tag}>{text}</{tag}>")

    def string(self, depth: int, tag: str, text: str) -> None:
        self.value(depth, tag, f'"{text}"')

    def frame(self, depth: int, frame: Frame) -> None:
        self.line(depth, f'<Frame ref="{frame.ref}">' if frame.ref is not None else "<Frame>")
        d = depth + 1
        self.string(d, "name", frame.name)
        self.string(d, "displayName", frame.display_name)
        self.string(d, "nodeID", frame.node_id)
        self.value(d, "position", numbers(frame.position))
        self.string(d, "positionOrigin", "WORLD")
        self.string(d, "positionReferenceFrame", "WORLD")
        self.string(d, "positionUnits", "mm")
        self.value(d, "orientation", numbers(column_major(frame.rotation)))
        self.string(d, "orientationType", "3x3 Transform")
        self.string(d, "orientationUnits", "rad")
        self.string(d, "orientationReferenceFrame", "WORLD")
        self.line(depth, "</Frame>")

    def body(self, depth: int, body: Body) -> None:
        self.line(depth, "<Body>")
        d = depth + 1
        self.string(d, "name", body.name)
        self.string(d, "nodeID", body.node_id)
        self.string(d, "status", "")
        self.value(d, "mass", number(body.mass))
        self.string(d, "massUnits", "g")
        self.value(d, "inertia", numbers(body.inertia))
        self.string(d, "inertiaUnits", "g*mm^2")
        self.value(d, "volume", number(body.volume))
        self.string(d, "volumeUnits", "mm^3")
        self.value(d, "surfaceArea", number(body.area))
        self.string(d, "surfaceAreaUnits", "mm^2")
        self.line(d, "<frames>")
        for frame in body.frames:
            self.frame(d + 1, frame)
        self.line(d, "</frames>")
        self.string(d, "geometryFileName", body.geometry_file)
        if body.color is not None:
            self.line(d, "<MaterialProp>")
            self.value(d + 1, "color", numbers(body.color))
            for tag, val in (("ambient", 0.4), ("diffuse", 0.85), ("specular", 0.9), ("shininess", 0.3),
                             ("transparency", 0.0), ("emission", 0.35)):
                self.value(d + 1, tag, number(val))
            self.line(d, "</MaterialProp>")
        self.line(depth, "</Body>")

    def joint(self, depth: int, joint: Joint) -> None:
        self.line(depth, "<SimpleJoint>")
        d = depth + 1
        self.string(d, "name", joint.name)
        self.string(d, "nodeID", joint.node_id)
        self.string(d, "status", "")
        for side, ref in (("base", joint.base_ref), ("follower", joint.follower_ref)):
            self.line(d, f"<{side}>")
            self.line(d + 1, "<JointSide>")
            self.string(d + 2, "name", "")
            self.line(d + 2, "<connection>")
            self.line(d + 3, f'<Frame ref="{ref}"></Frame>')
            self.line(d + 2, "</connection>")
            self.line(d + 1, "</JointSide>")
            self.line(d, f"</{side}>")
        self.line(d, "<primitives>")
        self.line(d + 1, "<Primitive>")
        self.string(d + 2, "name", joint.primitive)
        self.string(d + 2, "nodeID", "")
        self.string(d + 2, "referenceFrame", "WORLD")
        self.value(d + 2, "axis", numbers(joint.axis))
        self.line(d + 1, "</Primitive>")
        self.line(d, "</primitives>")
        self.line(depth, "</SimpleJoint>")

    def block(self, depth: int, tag: str, items, emit) -> None:
        if not items:
            self.line(depth, f"<{tag}></{tag}>")
            return
        self.line(depth, f"<{tag}>")
        for item in items:
            emit(depth + 1, item)
        self.line(depth, f"</{tag}>")

    def ground(self, depth: int, ground: Ground) -> None:
        self.line(depth, "<Ground>")
        self.string(depth + 1, "name", ground.name)
        self.string(depth + 1, "nodeID", ground.name)
        self.string(depth + 1, "status", "")
        self.line(depth + 1, "<frame>")
        self.frame(depth + 2, ground.frame)
        self.line(depth + 1, "</frame>")
        self.line(depth, "</Ground>")

    def subsystem(self, depth: int, sub: Subsystem) -> None:
        self.line(depth, "<Subsystem>")
        d = depth + 1
        self.string(d, "name", sub.name)
        self.string(d, "nodeID", sub.node_id)
        self.string(d, "status", "")
        self.block(d, "bodies", sub.bodies, self.body)
        self.block(d, "joints", sub.joints, self.joint)
        self.line(d, "<grounds></grounds>")
        self.line(d, "<subsystems></subsystems>")
        self.line(d, "<connectionPorts></connectionPorts>")
        self.value(d, "id", "0")
        self.line(depth, "</Subsystem>")


def render(export: Export) -> str:
    w = _Writer()
    w.lines.append('<?xml version="1.0" encoding="UTF-8" standalone="no" ?>')
    w.line(0, "<PhysicalModelingXMLFile>")
    for tag, text, quoted in (
        ("formatVersion", "1.0.4", True),
        ("internalVersion", "1", False),
        ("createdUsing", export.created_using, True),
        ("createdFrom", export.created_from, True),
        ("createdOn", export.created_on, True),
        ("createdBy", export.created_by, True),
        ("name", export.name, True),
    ):
        w.lines.append("")
        w.value(1, tag, f'"{text}"' if quoted else text)
    w.lines.append("")
    w.line(1, "<SimMechanics>")
    w.string(2, "name", export.name)
    w.string(2, "nodeID", export.name)
    w.block(2, "bodies", export.bodies, w.body)
    w.block(2, "joints", export.joints, w.joint)
    w.block(2, "grounds", export.grounds, w.ground)
    w.block(2, "subsystems", export.subsystems, w.subsystem)
    w.line(2, "<connectionPorts></connectionPorts>")
    w.value(2, "id", "0")
    w.line(1, "</SimMechanics>")
    w.lines.append("")
    w.line(0, "</PhysicalModelingXMLFile>")
    return "\n".join(w.lines) + "\n"
