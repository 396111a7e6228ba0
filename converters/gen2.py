"""Reader for second-generation ``SimscapeMultibodyImportXML`` exports (Simscape Multibody
exporters for Onshape, SolidWorks, Creo, Inventor).

What the format says, and how this reader takes it:

* ``<DataUnits length= mass=>`` is the unit of every number in the file (``ModelUnits`` is
  only the CAD document's display unit, except in exports without ``DataUnits``: Creo's
  Simscape Multibody Link 6 writes its numbers in ``ModelUnits``, e.g. ``mm``).
* ``<RootAssembly>/<InstanceTree>`` nests ``<Instance>`` elements: an instance of a part
  (``entityUid`` names a ``<Part>``) or of a sub-assembly (names an ``<Assembly>``; its
  children are nested instances). Each ``<Transform>`` places the instance in its parent:
  ``Rotation`` is written row by row and maps child to parent coordinates.
* ``grounded="true"`` fixes an instance to its parent assembly (to the world at the top level).
* ``<Joints>`` of the root assembly and of every ``<Assembly>`` (applied to each instance of
  it) join two frames: ``InstancePath`` is the chain of instance uids below that assembly,
  ``Transform`` the joint frame in that instance's frame. Simscape joints move along/about
  the base frame's axes: revolute ``Rz``, prismatic ``Pz``, cylindrical ``Pz Rz``, planar
  ``Px Py Rz``, universal ``Rx Ry``, spherical ``S``, 6-DOF ``Px Py Pz S``...
* A sub-assembly with no joints is rigid: its parts become one body. In a sub-assembly with
  joints, parts no joint refers to are fixed to the sub-assembly.
* ``<Part>`` mass properties: ``CenterOfMass`` in the part frame; ``Inertia`` about the
  centre of mass in part-frame axes, ordered ``Ixx Iyy Izz Iyz Izx Ixy`` with the products
  as tensor entries (Simscape's negated convention), printed to a fixed number of decimals.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from mechanism.converters import mates, relations
from mechanism.converters.assembly import (
    BALL,
    GROUND,
    HINGE,
    SLIDE,
    Assembly,
    Joint,
    Part,
    Primitive,
)
from mechanism.converters.errors import ExportError
from mechanism.converters.mates import Mate, MateGeometry
from mechanism.converters.pose import Pose, orthonormal
from mechanism.converters.safety import MAX_DEPTH, numbers, resolve_inside
from mechanism.converters.units import length_factor, mass_factor

ROOT_TAG = "SimscapeMultibodyImportXML"
# the same format as SimMechanics Link 4.x (2013-2016) wrote it
LEGACY_ROOT_TAG = "SimMechanicsImportXML"

_P = {
    "Px": (SLIDE, 0),
    "Py": (SLIDE, 1),
    "Pz": (SLIDE, 2),
    "Rx": (HINGE, 0),
    "Ry": (HINGE, 1),
    "Rz": (HINGE, 2),
    "S": (BALL, 2),
}
JOINT_PRIMITIVES = {
    "revolute": ["Rz"],
    "prismatic": ["Pz"],
    "cylindrical": ["Pz", "Rz"],
    "spherical": ["S"],
    "weld": [],
    "rigid": [],
    "fixed": [],
    "planar": ["Px", "Py", "Rz"],
    "universal": ["Rx", "Ry"],
    "gimbal": ["Rx", "Ry", "Rz"],
    "sixdof": ["Px", "Py", "Pz", "S"],
    "6dof": ["Px", "Py", "Pz", "S"],
    "free": ["Px", "Py", "Pz", "S"],
    "rectangular": ["Px", "Py"],
    "cartesian": ["Px", "Py", "Pz"],
    "pinslot": ["Px", "Rz"],
    "telescoping": ["Pz", "S"],
    "bearing": ["Pz", "Rx", "Ry", "Rz"],
    "bushing": ["Px", "Py", "Pz", "Rx", "Ry", "Rz"],
    "leadscrew": ["Rz", "Pz"],
    "constantvelocity": ["Rx", "Ry"],
    # names CAD tools use for the same joints (Onshape mate types, SolidWorks/Inventor wording)
    "fastened": [],
    "slider": ["Pz"],
    "ball": ["S"],
    "pin": ["Rz"],
    "hinge": ["Rz"],
    "slot": ["Px", "Rz"],
}
APPROXIMATED = {
    "bushing": "its stiffness and damping are not modelled: it becomes 3 slides and 3 hinges",
    "leadscrew": "its lead is not modelled: it becomes a free cylindrical joint",
    "constantvelocity": "it becomes a universal joint (two hinges)",
}
_INSTANCE_SUFFIX = re.compile(r"\s*<\d+>\s*$")


def _local(tag) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _children(element, name: str) -> list:
    return [] if element is None else [child for child in element if _local(child.tag) == name]


def _child(element, name: str):
    found = _children(element, name)
    return found[0] if found else None


def _numbers(element, count: int, where: str) -> np.ndarray:
    return numbers(element.text if element is not None else None, count, where)


def _decimals(element) -> int:
    """Digits after the decimal point the exporter printed (0 when it used exponents)."""
    pieces = ((element.text or "") if element is not None else "").split()
    if any("e" in piece.lower() for piece in pieces):
        return 0
    return max((len(piece.split(".")[1]) for piece in pieces if "." in piece), default=0)


class _Reader:
    def __init__(self, path: Path, root_tag: str):
        self.path = Path(path)
        self.folder = self.path.parent
        self.assembly = Assembly(
            name=self.path.stem, source=self.path, format=f"second-generation {root_tag}"
        )
        self.nodes: dict[
            str, tuple
        ] = {}  # instance key -> (parent node key, element, is_assembly, entity uid)
        self.scope_uids: dict[
            str, str | None
        ] = {}  # assembly instance key ("" for the root) -> its own uid

    def read(self, root) -> Assembly:
        # numbers are in DataUnits; exports without it (Creo's Simscape Multibody Link 6) write them in ModelUnits
        units = _child(root, "DataUnits")
        if units is None:
            units = _child(root, "ModelUnits")
        where = f"export {self.path.name}"
        self.length = length_factor(
            units.get("length", "meter") if units is not None else "meter", f"{where}: DataUnits"
        )
        self.mass = mass_factor(
            units.get("mass", "kilogram") if units is not None else "kilogram",
            f"{where}: DataUnits",
        )
        self.assembly.gravity = _gravity(root)
        top = _child(root, "RootAssembly")
        if top is None:
            raise ExportError(f"{where}: has no <RootAssembly>")
        self.assembly.name = top.get("name") or self.assembly.name
        self.part_entities = {p.get("uid"): p for p in _children(_child(root, "Parts"), "Part")}
        self.assembly_entities = {
            a.get("uid"): a for a in _children(_child(root, "Assemblies"), "Assembly")
        }
        self._instances(_child(top, "InstanceTree"), "", Pose(), 0)
        if not self.assembly.real_parts:
            raise ExportError(f"{where}: the instance tree contains no parts")
        scopes = [("", top)] + [
            (key, self.assembly_entities[entity])
            for key, (_, _, is_asm, entity) in self.nodes.items()
            if is_asm and entity in self.assembly_entities
        ]
        # a path naming the assembly itself is its origin (SolidWorks writes mates to the origin so)
        self.scope_uids = {prefix: scope.get("uid") for prefix, scope in scopes}
        referenced: set[str] = set()
        mate_list: list[Mate] = []
        related: list = []  # (prefix, element): gears, rack-and-pinions, screws...
        for prefix, scope in scopes:
            for element in list(_child(scope, "Joints") or []):
                joint = self._joint(element, prefix)
                if joint is not None:
                    self.assembly.joints.append(joint)
                    referenced.update(_ancestors(joint.base) | _ancestors(joint.follower))
            for element in list(_child(scope, "Constraints") or []):
                if relations.is_relation(_local(element.tag)):
                    related.append((prefix, element))
                    continue
                mate = self._mate(element, prefix)
                if mate is not None:
                    mate_list.append(mate)
        for mate in mate_list:
            if mates.usable(mate):
                referenced.update(_ancestors(mate.first.part) | _ancestors(mate.second.part))
        self.assembly.joints.extend(self._fix_instances(referenced))
        names = {key: part.name for key, part in self.assembly.parts.items()}
        welded = [(j.base, j.follower) for j in self.assembly.joints if j.is_weld]
        origins = frozenset(
            {GROUND} | {key for key, (_, _, is_asm, _) in self.nodes.items() if is_asm}
        )
        inferred = mates.infer_joints(mate_list, welded, names, origins)
        self.assembly.joints.extend(inferred.joints)
        for message in inferred.warnings:
            self.assembly.warn(message)
        for prefix, element in related:
            relations.add_relation(self.assembly, element, self._relation_side(prefix), self.length)
        return self.assembly

    # -- instance tree ----------------------------------------------------------------------
    def _instances(self, element, parent: str, parent_pose: Pose, depth: int) -> None:
        if depth > MAX_DEPTH:
            raise ExportError(
                f"export {self.path.name}: instances nested more than {MAX_DEPTH} levels deep"
            )
        for instance in _children(element, "Instance"):
            uid = instance.get("uid") or f"#{len(self.nodes)}"
            key = f"{parent}/{uid}" if parent else uid
            name = _INSTANCE_SUFFIX.sub("", instance.get("name") or uid) or uid
            where = f"export {self.path.name}, instance {instance.get('name', uid)}"
            pose = parent_pose @ self._transform(_child(instance, "Transform"), where)
            entity = instance.get("entityUid")
            nested = _children(instance, "Instance")
            if entity in self.part_entities and not nested:
                self.nodes[key] = (parent, instance, False, entity)
                self.assembly.parts[key] = self._part(
                    self.part_entities[entity], key, name, pose, where
                )
            elif nested or entity in self.assembly_entities:
                self.nodes[key] = (parent, instance, True, entity)
                self.assembly.parts[key] = Part(
                    key=key,
                    name=name,
                    mass=0.0,
                    com=pose.position,
                    inertia=np.zeros((3, 3)),
                    frame=pose,
                    virtual=True,
                )
                self._instances(instance, key, pose, depth + 1)
            else:
                self.assembly.warn(
                    f"instance {instance.get('name', uid)} refers to entity {entity!r}, which is neither "
                    f"a part nor an assembly of the export: ignored"
                )

    def _transform(self, element, where: str) -> Pose:
        if element is None:
            return Pose()
        rotation = _numbers(_child(element, "Rotation"), 9, f"{where}: Rotation").reshape(3, 3)
        translation = (
            _numbers(_child(element, "Translation"), 3, f"{where}: Translation") * self.length
        )
        return Pose(orthonormal(rotation, f"{where}: Rotation"), translation)

    def _part(self, entity, key: str, name: str, pose: Pose, where: str) -> Part:
        where = f"{where} (part {entity.get('name', '')})"
        props = _child(entity, "MassProperties")
        mass = (
            float(_numbers(_child(props, "Mass"), 1, f"{where}: Mass")[0]) * self.mass
            if props is not None
            else 0.0
        )
        if mass < 0:
            raise ExportError(f"{where}: negative mass {mass:g} kg")
        com = (
            _numbers(_child(props, "CenterOfMass"), 3, f"{where}: CenterOfMass") * self.length
            if props is not None
            else np.zeros(3)
        )
        inertia_element = _child(props, "Inertia") if props is not None else None
        tensor = np.zeros((3, 3))
        resolution = 0.0
        if inertia_element is not None:
            ixx, iyy, izz, iyz, izx, ixy = _numbers(inertia_element, 6, f"{where}: Inertia")
            tensor = (
                np.array([[ixx, ixy, izx], [ixy, iyy, iyz], [izx, iyz, izz]])
                * self.mass
                * self.length**2
            )
            decimals = _decimals(inertia_element)
            resolution = 0.5 * 10.0**-decimals * self.mass * self.length**2 if decimals else 0.0
        geometry_element = _child(entity, "GeometryFile")
        geometry_name = (geometry_element.get("name") or "") if geometry_element is not None else ""
        geometry = (
            resolve_inside(self.folder, geometry_name, f"{where}: GeometryFile")
            if geometry_name
            else None
        )
        color: tuple[float, ...] = (0.7, 0.7, 0.7, 1.0)  # RGBA
        diffuse = _child(_child(entity, "VisualProperties"), "Diffuse")
        if diffuse is not None:
            try:
                color = tuple(
                    float(np.clip(float(diffuse.get(c, d)), 0, 1))
                    for c, d in zip("rgba", (0.7, 0.7, 0.7, 1))
                )
            except ValueError:
                self.assembly.warn(f"{where}: colour is not numeric: using grey")
        return Part(
            key=key,
            name=name,
            mass=mass,
            com=pose.apply(com),
            inertia=pose.rotation @ tensor @ pose.rotation.T,
            frame=pose,
            geometry=geometry,
            geometry_name=geometry_name,
            geometry_scale=self.length,
            color=color,
            inertia_resolution=resolution,
        )

    # -- joints and mates --------------------------------------------------------------------
    def _instance_key(self, element, prefix: str, where: str) -> str:
        """The instance the ``InstancePath`` of ``element`` names below the assembly ``prefix``; an empty
        path, or one naming the assembly's own uid, is that assembly itself (the world at the top level:
        Onshape writes mates to the origin with an empty path, SolidWorks with the assembly's uid)."""
        return self._path_key(_child(element, "InstancePath"), prefix, where)

    def _path_key(self, path, prefix: str, where: str) -> str:
        """The instance key of an ``InstancePath`` element (see :meth:`_instance_key`)."""
        uids = [(u.text or "").strip() for u in _children(path, "Uid")]
        if not uids or uids == [self.scope_uids.get(prefix)]:
            return prefix or GROUND
        key = "/".join(([prefix] if prefix else []) + uids)
        if key not in self.assembly.parts:
            raise ExportError(
                f"{where}: InstancePath {'/'.join(uids)} is not an instance of the export"
            )
        return key

    def _pose_of(self, key: str) -> Pose:
        return Pose() if key == GROUND else self.assembly.parts[key].frame

    def _frame(self, element, prefix: str, where: str) -> tuple[str, Pose]:
        if element is None:
            raise ExportError(f"{where}: frame missing")
        key = self._instance_key(element, prefix, where)
        return key, self._pose_of(key) @ self._transform(_child(element, "Transform"), where)

    def _joint(self, element, prefix: str) -> Joint | None:
        tag = _local(element.tag)
        name = element.get("name") or tag
        where = f"export {self.path.name}, joint {name}"
        kind = re.sub(r"[^a-z0-9]", "", tag.lower()).removesuffix("joint") or tag.lower()
        try:
            base, base_frame = self._frame(
                _child(element, "BaseFrame"), prefix, f"{where}: BaseFrame"
            )
            follower, follower_frame = self._frame(
                _child(element, "FollowerFrame"), prefix, f"{where}: FollowerFrame"
            )
        except ExportError as exc:
            if "InstancePath" not in str(exc):
                raise
            self.assembly.warn(
                f"joint {name} is ignored: {str(exc).split(': ', 2)[-1]} (a suppressed or deleted part?)"
            )
            return None
        if kind not in JOINT_PRIMITIVES:
            self.assembly.warn(f"joint {name}: type <{tag}> is not supported: treated as a weld")
            kind = "weld"
        elif kind in APPROXIMATED:
            self.assembly.warn(f"joint {name} ({tag}): {APPROXIMATED[kind]}")
        if base == follower:
            self.assembly.warn(f"joint {name} joins two frames of one part: ignored")
            return None
        primitives = [
            Primitive(_P[p][0], base_frame.rotation[:, _P[p][1]].copy())
            for p in JOINT_PRIMITIVES[kind]
        ]
        return Joint(
            name=name,
            kind=kind if primitives else "weld",
            base=base,
            follower=follower,
            base_frame=base_frame,
            follower_frame=follower_frame,
            primitives=primitives,
        )

    def _mate(self, element, prefix: str) -> Mate | None:
        """A CAD mate: two ``ConstraintGeometry`` (geomType, InstancePath, Position and Axis in the
        instance's frame) or, as Simscape constraint blocks write it, ``BaseFrame``/``FollowerFrame``."""
        tag = _local(element.tag)
        name = element.get("name") or tag
        where = f"export {self.path.name}, constraint {name}"
        sides = _children(element, "ConstraintGeometry")
        try:
            if len(sides) == 2:
                first, second = (self._mate_geometry(side, prefix, where) for side in sides)
            elif (
                _child(element, "BaseFrame") is not None
                and _child(element, "FollowerFrame") is not None
            ):
                first, second = (
                    self._frame_geometry(_child(element, side), prefix, where, tag)
                    for side in ("BaseFrame", "FollowerFrame")
                )
            else:
                first = second = None
        except ExportError as exc:
            self.assembly.warn(
                f"constraint {name} <{tag}> is ignored: {str(exc).split(': ', 1)[-1]}"
            )
            return None
        if first is not None and second is not None:
            return Mate(name=name, tag=tag, first=first, second=second)
        if mates.mate_kind(tag) == "weld":
            return self._weld_mate(element, name, tag, prefix, where)
        self.assembly.warn(f"constraint {name} <{tag}> carries no usable geometry: ignored")
        return None

    def _weld_mate(self, element, name: str, tag: str, prefix: str, where: str) -> Mate | None:
        """A weld-like constraint (Creo's ``<Rigid>``, ``Lock``, ``Fixed``) written without constraint
        geometry: a weld needs none, only its two instances. Creo writes their two ``InstancePath``
        elements directly in the constraint; other exporters put each in a geometry-less side."""
        paths = _children(element, "InstancePath")
        if len(paths) != 2:
            paths = [
                _child(side, "InstancePath")
                for side in element
                if _child(side, "InstancePath") is not None
            ]
        if len(paths) != 2:
            self.assembly.warn(
                f"constraint {name} <{tag}> names {len(paths)} instance(s), not two: ignored"
            )
            return None
        try:
            keys = [self._path_key(path, prefix, where) for path in paths]
        except ExportError as exc:
            self.assembly.warn(
                f"constraint {name} <{tag}> is ignored: {str(exc).split(': ', 1)[-1]}"
            )
            return None
        first, second = (
            MateGeometry(part=key, shape="origin", position=self._pose_of(key).position, axis=None)
            for key in keys
        )
        if tag.lower() == "unknownconstraint":
            self.assembly.warn(
                f"constraint {name} <{tag}> could not be described by the exporter: it fixes "
                f"{' and '.join('the world' if key == GROUND else self.assembly.parts[key].name for key in keys)} together, "
                "as Simscape's import does"
            )
        return Mate(name=name, tag=tag, first=first, second=second)

    def _mate_geometry(self, element, prefix: str, where: str) -> MateGeometry | None:
        key = self._instance_key(element, prefix, where)
        position_element = _child(element, "Position")
        if position_element is None or not (position_element.text or "").strip():
            return None
        pose = self._pose_of(key)
        position = pose.apply(_numbers(position_element, 3, f"{where}: Position") * self.length)
        axis_element = _child(element, "Axis")
        axis = None
        if axis_element is not None and (axis_element.text or "").strip():
            local = _numbers(axis_element, 3, f"{where}: Axis")
            if np.linalg.norm(local) > 1e-12:
                axis = pose.rotation @ (local / np.linalg.norm(local))
        return MateGeometry(
            part=key, shape=(element.get("geomType") or "").lower(), position=position, axis=axis
        )

    def _frame_geometry(self, element, prefix: str, where: str, tag: str) -> MateGeometry:
        """A Simscape constraint block's frame as mate geometry: its origin (distance constraints)
        or its z axis through the origin (angle constraints)."""
        key, pose = self._frame(element, prefix, where)
        shape = "line" if "angle" in tag.lower() else "point"
        return MateGeometry(
            part=key, shape=shape, position=pose.position, axis=pose.rotation[:, 2].copy()
        )

    def _relation_side(self, prefix: str):
        """For gear-like constraints: (element, where) -> (instance key, world pose) of one side."""

        def side(element, where):
            if _child(element, "Transform") is not None:
                return self._frame(element, prefix, where)
            geometry = self._mate_geometry(element, prefix, where)
            if geometry is None:
                key = self._instance_key(element, prefix, where)
                return key, self._pose_of(key)
            axis = geometry.axis if geometry.axis is not None else np.array([0, 0, 1.0])
            return geometry.part, Pose(mates.frame_with_z(axis), geometry.position)

        return side

    def _fix_instances(self, referenced: set[str]) -> list[Joint]:
        """Synthetic welds from the instance tree: grounded instances, members of rigid
        sub-assemblies (``rigid="true"`` or no joints and no mates inside) and of rigid groups,
        and instances of a flexible sub-assembly that no joint or mate refers to."""
        welds = []

        def weld(anchor: str, key: str, reason: str) -> None:
            frame = self.assembly.parts[key].frame
            anchor_name = self.assembly.parts[anchor].name if anchor != GROUND else "world"
            welds.append(
                Joint(
                    name=f"{self.assembly.parts[key].name} {reason} {anchor_name}",
                    kind="weld",
                    base=anchor,
                    follower=key,
                    base_frame=frame,
                    follower_frame=frame,
                    synthetic=True,
                )
            )

        groups: dict[tuple[str, str], str] = {}
        for key, (parent, element, _, _) in self.nodes.items():
            grounded = element.get("grounded", "").lower() == "true"
            rigid_parent = bool(parent) and self._is_rigid(parent)
            if grounded or rigid_parent or (parent and key not in referenced):
                weld(parent or GROUND, key, "grounded in" if grounded else "rigid in")
            group = element.get("rigidGroup") or ""
            if group:  # Onshape groups: members are fixed to each other
                first = groups.setdefault((parent, group), key)
                if first != key:
                    weld(first, key, "grouped with")
        return welds

    def _is_rigid(self, key: str) -> bool:
        _, element, _, entity = self.nodes[key]
        if element.get("rigid", "").lower() == "true":
            return True
        definition = self.assembly_entities.get(entity)
        return definition is None or not (
            list(_child(definition, "Joints") or [])
            or list(_child(definition, "Constraints") or [])
        )


def _ancestors(key: str) -> set[str]:
    """``a/b/c`` -> {``a``, ``a/b``, ``a/b/c``}: a joint on a nested part refers to its sub-assemblies too."""
    pieces = key.split("/")
    return {"/".join(pieces[: i + 1]) for i in range(len(pieces))}


def _gravity(root) -> np.ndarray | None:
    """The export's gravity vector where it carries one: a ``<Gravity>`` (or ``<GravityVector>``)
    element with three numbers as its text or as ``x``/``y``/``z`` (or ``value``) attributes."""
    for element in root.iter():
        if not isinstance(element.tag, str) or _local(element.tag).lower() not in (
            "gravity",
            "gravityvector",
        ):
            continue
        texts = [element.get(k) for k in ("x", "y", "z")]
        text = (
            " ".join(texts) if None not in texts else (element.get("value") or element.text or "")
        )
        try:
            values = np.array(
                [
                    float(v)
                    for v in text.replace(",", " ").replace("[", " ").replace("]", " ").split()
                ]
            )
        except ValueError:
            continue
        if values.shape == (3,) and np.all(np.isfinite(values)) and np.linalg.norm(values) > 0:
            return values
    return None


def read(root, path: Path) -> Assembly:
    """The neutral assembly of a second-generation export (``root``: its parsed root element)."""
    return _Reader(path, _local(root.tag)).read(root)
