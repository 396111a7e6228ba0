"""Reader for first-generation ``PhysicalModelingXMLFile`` exports (SimMechanics Link from
Pro/E and Creo, SolidWorks, Inventor).

What the format says, and how this reader takes it (checked against the LEGS export):

* ``<SimMechanics>`` (``<SimscapeMultibody>`` from Simscape Multibody Link 4.8 on) holds ``bodies``, ``joints``, ``grounds`` and nested ``subsystems``
  (sub-assemblies) with the same four lists. Joints may cross subsystems.
* A ``Body`` has ``mass``/``massUnits``, ``inertia`` (9 values, ``inertiaUnits``) and
  ``frames``: ``CG`` (the centre of mass; the inertia is expressed in this frame's axes),
  ``CS1`` (the part frame the geometry file is written in) and further ``CSn`` frames used
  by joints or added by the user (non-empty ``displayName``).
* Frame positions and orientations are relative to ``WORLD`` (or to another frame of the same
  body, by name). ``3x3 Transform`` orientations are written column by column: the first
  three numbers are the frame's x axis in the reference frame. (Verified on LEGS: the
  1 kg weights, stacked in pairs along x and along y, have their disc axis along the stacking
  direction only under this reading.)
* Frames that joints use carry a ``ref`` number; a joint side names its frame by that number.
  ``Ground`` frames belong to the world.
* A ``SimpleJoint`` lists ``primitives`` (``revolute``, ``prismatic``, ``spherical``,
  ``weld``) with axes in ``WORLD`` (or a named frame); several primitives make a compound
  joint (prismatic + revolute on one axis = cylindrical).
* Each subsystem has a massless ``RootPart`` welded to its first body, and the top level has
  ``RootGround--RootPart``: ordinary welds here.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import overload

import numpy as np

from mechanism.converters.assembly import (
    BALL,
    GROUND,
    HINGE,
    SLIDE,
    Assembly,
    Joint,
    NamedFrame,
    Part,
    Primitive,
)
from mechanism.converters.errors import ExportError
from mechanism.converters.pose import Pose, orthonormal
from mechanism.converters.safety import MAX_DEPTH, numbers, resolve_inside
from mechanism.converters.units import inertia_factor, length_factor, mass_factor, volume_factor

ROOT_TAG = "PhysicalModelingXMLFile"
FORMAT = "first-generation PhysicalModelingXMLFile"
# the model element: SimMechanics Link writes <SimMechanics>, Simscape Multibody Link 4.8 and later <SimscapeMultibody>
MODEL_TAGS = ("SimMechanics", "SimscapeMultibody")

PRIMITIVES = {
    "revolute": [HINGE],
    "prismatic": [SLIDE],
    "spherical": [BALL],
    "weld": [],
    "cylindrical": [SLIDE, HINGE],
}


@overload
def _text(element, tag: str, default: str) -> str: ...
@overload
def _text(element, tag: str, default: None = None) -> str | None: ...
def _text(element, tag: str, default: str | None = None) -> str | None:
    """The stripped text of ``element``'s child ``tag``, or ``default`` where it has none."""
    child = element.find(tag)
    if child is None or child.text is None:
        return default
    return child.text.strip().strip('"').strip()


def _floats(text: str | None, count: int, where: str) -> np.ndarray:
    return numbers(text, count, where)


def _number(text: str | None, where: str) -> float:
    return float(_floats(text, 1, where)[0])


class _Reader:
    def __init__(self, path: Path):
        self.path = Path(path)
        self.folder = self.path.parent
        self.assembly = Assembly(name=self.path.stem, source=self.path, format=FORMAT)
        self.frame_refs: dict[str, tuple[str, Pose]] = {}  # ref -> (part key or GROUND, pose)
        self.frame_names: dict[str, dict[str, Pose]] = {}  # part key -> frame name -> pose

    # -- structure ---------------------------------------------------------------------------
    def read(self, root) -> Assembly:
        if (
            str(root.tag).rsplit("}", 1)[-1] in MODEL_TAGS
        ):  # the model element written as the document's root
            model = root
        else:
            model = next((root.find(tag) for tag in MODEL_TAGS if root.find(tag) is not None), None)
        if model is None:
            raise ExportError(
                f"export {self.path}: <{ROOT_TAG}> has no <SimMechanics> (or <SimscapeMultibody>) element"
            )
        title = _text(root, "name") or _text(model, "name")
        if title:
            self.assembly.name = title
        levels = list(self._levels(model, ()))
        counts = Counter(
            _text(body, "name", "")
            for _, level in levels
            for body in _children(level, "bodies", "Body")
        )
        for path, level in levels:
            for body in _children(level, "bodies", "Body"):
                self._body(body, path, counts)
            for ground in _children(level, "grounds", "Ground"):
                self._ground(ground)
        for _, level in levels:
            joints = level.find("joints")
            for element in list(joints) if joints is not None else []:
                if element.tag == "SimpleJoint":
                    self._joint(element)
                else:
                    self.assembly.warn(
                        f"joint element <{element.tag}> is not supported by the first-generation reader: ignored"
                    )
        if not self.assembly.real_parts:
            raise ExportError(f"export {self.path}: contains no bodies")
        return self.assembly

    def _levels(self, level, path: tuple):
        if len(path) > MAX_DEPTH:
            raise ExportError(
                f"export {self.path}: subsystems nested more than {MAX_DEPTH} levels deep"
            )
        yield path, level
        for subsystem in _children(level, "subsystems", "Subsystem"):
            yield from self._levels(subsystem, path + (_text(subsystem, "name", "subsystem"),))

    # -- frames ------------------------------------------------------------------------------
    def _frame_poses(self, frames: list, where: str) -> dict[str, Pose]:
        """World poses of a body's frames (which may be placed relative to each other by name)."""
        by_name = {_frame_name(frame, i): frame for i, frame in enumerate(frames)}
        poses: dict[str, Pose] = {}

        def pose_of(name: str, stack: tuple) -> Pose:
            if name in poses:
                return poses[name]
            if name in stack:
                raise ExportError(
                    f"{where}: frames {' -> '.join(stack + (name,))} are placed relative to each other in a cycle"
                )
            frame = by_name[name]
            here = f"{where}, frame {name}"
            unit = length_factor(_text(frame, "positionUnits", "m"), here)
            position = _floats(_text(frame, "position"), 3, f"{here}: position") * unit
            kind = _text(frame, "orientationType", "3x3 Transform")
            if kind.lower().replace(" ", "") != "3x3transform":
                raise ExportError(
                    f"{here}: orientationType '{kind}' is not supported (expected '3x3 Transform')"
                )
            values = _floats(_text(frame, "orientation"), 9, f"{here}: orientation")
            local_rotation = orthonormal(values.reshape(3, 3).T, f"{here}: orientation")

            def reference(tag: str) -> Pose:
                ref = _text(frame, tag, "WORLD") or "WORLD"
                if ref.upper() == "WORLD":
                    return Pose()
                if ref in by_name:
                    return pose_of(ref, stack + (name,))
                raise ExportError(
                    f"{here}: {tag} '{ref}' is neither WORLD nor a frame of this body"
                )

            origin = reference("positionOrigin").position
            axes = reference("positionReferenceFrame").rotation
            rotation = reference("orientationReferenceFrame").rotation @ local_rotation
            poses[name] = Pose(rotation, origin + axes @ position)
            return poses[name]

        for name in by_name:
            pose_of(name, ())
        return poses

    def _register(self, frame, owner: str, pose: Pose) -> None:
        ref = frame.get("ref")
        if ref is not None:
            self.frame_refs[ref] = (owner, pose)

    # -- bodies ------------------------------------------------------------------------------
    def _body(self, body, path: tuple, counts: Counter) -> None:
        name = _text(body, "name", "") or "body"
        if counts[name] > 1 and path:
            name = "/".join(path + (name,))
        key = name
        while key in self.assembly.parts:
            key += "#"
        where = f"export {self.path.name}, body {name}"
        frames = _children(body, "frames", "Frame")
        poses = self._frame_poses(frames, where)
        self.frame_names[key] = poses
        for i, frame in enumerate(frames):
            self._register(frame, key, poses[_frame_name(frame, i)])

        mass = _number(_text(body, "mass", "0"), f"{where}: mass") * mass_factor(
            _text(body, "massUnits", "kg"), where
        )
        if mass < 0:
            raise ExportError(f"{where}: negative mass {mass:g} kg")
        inertia = _floats(
            _text(body, "inertia", "0,0,0,0,0,0,0,0,0"), 9, f"{where}: inertia"
        ).reshape(3, 3)
        inertia = inertia * inertia_factor(_text(body, "inertiaUnits", "kg*m^2"), where)
        cg = poses.get("CG")
        if cg is None:
            if mass > 0:
                raise ExportError(f"{where}: has mass but no CG frame")
            cg = Pose()
        inertia_world = cg.rotation @ inertia @ cg.rotation.T

        part_frame_name = "CS1" if "CS1" in poses else next((n for n in poses if n != "CG"), None)
        part_frame = poses[part_frame_name] if part_frame_name else cg
        unit_frame = next((f for f in frames if _text(f, "name") == part_frame_name), None)
        scale = (
            length_factor(_text(unit_frame, "positionUnits", "m"), where)
            if unit_frame is not None
            else 1.0
        )

        volume = None
        volume_text = _text(body, "volume")
        if volume_text:
            volume = _number(volume_text, f"{where}: volume") * volume_factor(
                _text(body, "volumeUnits", "m^3"), where
            )
            volume = volume if volume > 0 else None

        geometry_name = _text(body, "geometryFileName", "") or ""
        geometry = (
            resolve_inside(self.folder, geometry_name, f"{where}: geometryFileName")
            if geometry_name
            else None
        )

        color = (0.7, 0.7, 0.7, 1.0)
        material = body.find("MaterialProp")
        if material is not None and _text(material, "color"):
            rgb = np.clip(_floats(_text(material, "color"), 3, f"{where}: color"), 0, 1)
            transparency = float(
                np.clip(
                    _number(_text(material, "transparency", "0"), f"{where}: transparency"), 0, 1
                )
            )
            color = (*rgb.tolist(), 1.0 - transparency)

        named = [
            NamedFrame(display_name, poses[_frame_name(frame, i)])
            for i, frame in enumerate(frames)
            if (display_name := _text(frame, "displayName"))
        ]
        self.assembly.parts[key] = Part(
            key=key,
            name=name,
            mass=mass,
            com=cg.position,
            inertia=inertia_world,
            frame=part_frame,
            geometry=geometry,
            geometry_name=geometry_name,
            geometry_scale=scale,
            color=color,
            volume=volume,
            frames=named,
        )

    def _ground(self, ground) -> None:
        name = _text(ground, "name", "ground")
        frames = [f for f in ground.iter("Frame") if f.find("position") is not None]
        poses = self._frame_poses(frames, f"export {self.path.name}, ground {name}")
        for i, frame in enumerate(frames):
            self._register(frame, GROUND, poses[_frame_name(frame, i)])

    # -- joints ------------------------------------------------------------------------------
    def _side(self, joint, side: str, where: str) -> tuple[str, Pose]:
        frame = joint.find(f"{side}/JointSide/connection/Frame")
        if frame is None:
            raise ExportError(f"{where}: has no {side} frame")
        ref = frame.get("ref")
        if ref is None or ref not in self.frame_refs:
            raise ExportError(
                f"{where}: {side} frame ref {ref!r} is not a frame of any body or ground"
            )
        return self.frame_refs[ref]

    def _joint(self, element) -> None:
        name = _text(element, "name", "") or "joint"
        where = f"export {self.path.name}, joint {name}"
        base, base_pose = self._side(element, "base", where)
        follower, follower_pose = self._side(element, "follower", where)
        if base == follower:
            self.assembly.warn(f"joint {name} connects two frames of the same part {base}: ignored")
            return
        primitives, kinds = [], []
        for primitive in element.findall("primitives/Primitive"):
            kind = (_text(primitive, "name", "") or "").lower()
            if kind not in PRIMITIVES:
                self.assembly.warn(
                    f"joint {name}: primitive '{kind}' is not supported: ignored (the joint loses that freedom)"
                )
                continue
            kinds.append(kind)
            if not PRIMITIVES[kind]:
                continue
            axis = _floats(_text(primitive, "axis", "0,0,1"), 3, f"{where}: axis")
            axis = self._axis_in_world(
                axis, _text(primitive, "referenceFrame", "WORLD"), base, follower, where
            )
            primitives += [Primitive(k, axis) for k in PRIMITIVES[kind]]
        kind = "weld" if not primitives else "+".join(k for k in kinds if k != "weld")
        if kind in ("prismatic+revolute", "revolute+prismatic"):
            kind = "cylindrical"
        self.assembly.joints.append(
            Joint(
                name=name,
                kind=kind,
                base=base,
                follower=follower,
                base_frame=base_pose,
                follower_frame=follower_pose,
                primitives=primitives,
            )
        )

    def _axis_in_world(
        self, axis, reference: str, base: str, follower: str, where: str
    ) -> np.ndarray:
        norm = np.linalg.norm(axis)
        if norm < 1e-12:
            raise ExportError(f"{where}: primitive axis is zero")
        axis = axis / norm
        if reference.upper() == "WORLD":
            return axis
        for key in (base, follower):
            pose = self.frame_names.get(key, {}).get(reference)
            if pose is not None:
                return pose.rotation @ axis
        raise ExportError(
            f"{where}: axis referenceFrame '{reference}' is neither WORLD nor a frame of its bodies"
        )


def _frame_name(frame, index: int) -> str:
    return _text(frame, "name") or f"#{index}"


def _children(element, container: str, tag: str) -> list:
    holder = element.find(container)
    return [] if holder is None else holder.findall(tag)


def read(root, path: Path) -> Assembly:
    """The neutral assembly of a first-generation export (``root``: its parsed root element)."""
    return _Reader(path).read(root)
