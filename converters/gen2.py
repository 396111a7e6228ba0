"""Reader for second-generation ``SimscapeMultibodyImportXML`` exports (Simscape Multibody
exporters for Onshape, SolidWorks, Creo, Inventor).

What the format says, and how this reader takes it:

* ``<DataUnits length= mass=>`` is the unit of every number in the file (``ModelUnits`` is
  only the CAD document's display unit).
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

from converters.assembly import BALL, GROUND, HINGE, SLIDE, Assembly, Joint, Part, Primitive
from converters.errors import ExportError
from converters.pose import Pose, orthonormal
from converters.safety import MAX_DEPTH, numbers, resolve_inside
from converters.units import length_factor, mass_factor

ROOT_TAG = "SimscapeMultibodyImportXML"
FORMAT = "second-generation SimscapeMultibodyImportXML"

_P = {"Px": (SLIDE, 0), "Py": (SLIDE, 1), "Pz": (SLIDE, 2), "Rx": (HINGE, 0), "Ry": (HINGE, 1), "Rz": (HINGE, 2),
      "S": (BALL, 2)}
JOINT_PRIMITIVES = {
    "revolute": ["Rz"], "prismatic": ["Pz"], "cylindrical": ["Pz", "Rz"], "spherical": ["S"],
    "weld": [], "rigid": [], "fixed": [],
    "planar": ["Px", "Py", "Rz"], "universal": ["Rx", "Ry"], "gimbal": ["Rx", "Ry", "Rz"],
    "sixdof": ["Px", "Py", "Pz", "S"], "6dof": ["Px", "Py", "Pz", "S"], "free": ["Px", "Py", "Pz", "S"],
    "rectangular": ["Px", "Py"], "cartesian": ["Px", "Py", "Pz"], "pinslot": ["Px", "Rz"],
    "telescoping": ["Pz", "S"], "bearing": ["Pz", "Rx", "Ry", "Rz"],
    "bushing": ["Px", "Py", "Pz", "Rx", "Ry", "Rz"], "leadscrew": ["Rz", "Pz"], "constantvelocity": ["Rx", "Ry"],
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
    def __init__(self, path: Path):
        self.path = Path(path)
        self.folder = self.path.parent
        self.assembly = Assembly(name=self.path.stem, source=self.path, format=FORMAT)
        self.nodes: dict[str, tuple] = {}  # instance key -> (parent node key, element, is_assembly, entity uid)

    def read(self, root) -> Assembly:
        units = _child(root, "DataUnits")
        where = f"export {self.path.name}"
        self.length = length_factor(units.get("length", "meter") if units is not None else "meter", f"{where}: DataUnits")
        self.mass = mass_factor(units.get("mass", "kilogram") if units is not None else "kilogram", f"{where}: DataUnits")
        top = _child(root, "RootAssembly")
        if top is None:
            raise ExportError(f"{where}: has no <RootAssembly>")
        self.assembly.name = top.get("name") or self.assembly.name
        self.part_entities = {p.get("uid"): p for p in _children(_child(root, "Parts"), "Part")}
        self.assembly_entities = {a.get("uid"): a for a in _children(_child(root, "Assemblies"), "Assembly")}
        self._instances(_child(top, "InstanceTree"), "", Pose(), 0)
        if not self.assembly.real_parts:
            raise ExportError(f"{where}: the instance tree contains no parts")
        scopes = [("", top)] + [(key, self.assembly_entities[entity]) for key, (_, _, is_asm, entity) in self.nodes.items()
                                if is_asm and entity in self.assembly_entities]
        referenced: set[str] = set()
        for prefix, scope in scopes:
            for element in list(_child(scope, "Joints") or []):
                joint = self._joint(element, prefix)
                if joint is not None:
                    self.assembly.joints.append(joint)
                    referenced.update(_ancestors(joint.base) | _ancestors(joint.follower))
            for element in list(_child(scope, "Constraints") or []):
                self.assembly.warn(f"constraint <{_local(element.tag)}> {element.get('name', '')} is not supported: "
                                   f"ignored (add gear or belt ratios to the couplings side-car)")
        self._fix_instances(referenced)
        return self.assembly

    # -- instance tree ----------------------------------------------------------------------
    def _instances(self, element, parent: str, parent_pose: Pose, depth: int) -> None:
        if depth > MAX_DEPTH:
            raise ExportError(f"export {self.path.name}: instances nested more than {MAX_DEPTH} levels deep")
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
                self.assembly.parts[key] = self._part(self.part_entities[entity], key, name, pose, where)
            elif nested or entity in self.assembly_entities:
                self.nodes[key] = (parent, instance, True, entity)
                self.assembly.parts[key] = Part(key=key, name=name, mass=0.0, com=pose.position, inertia=np.zeros((3, 3)),
                                                frame=pose, virtual=True)
                self._instances(instance, key, pose, depth + 1)
            else:
                self.assembly.warn(f"instance {instance.get('name', uid)} refers to entity {entity!r}, which is neither "
                                   f"a part nor an assembly of the export: ignored")

    def _transform(self, element, where: str) -> Pose:
        if element is None:
            return Pose()
        rotation = _numbers(_child(element, "Rotation"), 9, f"{where}: Rotation").reshape(3, 3)
        translation = _numbers(_child(element, "Translation"), 3, f"{where}: Translation") * self.length
        return Pose(orthonormal(rotation, f"{where}: Rotation"), translation)

    def _part(self, entity, key: str, name: str, pose: Pose, where: str) -> Part:
        where = f"{where} (part {entity.get('name', '')})"
        props = _child(entity, "MassProperties")
        mass = float(_numbers(_child(props, "Mass"), 1, f"{where}: Mass")[0]) * self.mass if props is not None else 0.0
        if mass < 0:
            raise ExportError(f"{where}: negative mass {mass:g} kg")
        com = _numbers(_child(props, "CenterOfMass"), 3, f"{where}: CenterOfMass") * self.length if props is not None else np.zeros(3)
        inertia_element = _child(props, "Inertia") if props is not None else None
        tensor = np.zeros((3, 3))
        resolution = 0.0
        if inertia_element is not None:
            ixx, iyy, izz, iyz, izx, ixy = _numbers(inertia_element, 6, f"{where}: Inertia")
            tensor = np.array([[ixx, ixy, izx], [ixy, iyy, iyz], [izx, iyz, izz]]) * self.mass * self.length**2
            decimals = _decimals(inertia_element)
            resolution = 0.5 * 10.0**-decimals * self.mass * self.length**2 if decimals else 0.0
        geometry_element = _child(entity, "GeometryFile")
        geometry_name = (geometry_element.get("name") or "") if geometry_element is not None else ""
        geometry = resolve_inside(self.folder, geometry_name, f"{where}: GeometryFile") if geometry_name else None
        color = (0.7, 0.7, 0.7, 1.0)
        diffuse = _child(_child(entity, "VisualProperties"), "Diffuse")
        if diffuse is not None:
            try:
                color = tuple(float(np.clip(float(diffuse.get(c, d)), 0, 1)) for c, d in zip("rgba", (0.7, 0.7, 0.7, 1)))
            except ValueError:
                self.assembly.warn(f"{where}: colour is not numeric: using grey")
        return Part(key=key, name=name, mass=mass, com=pose.apply(com),
                    inertia=pose.rotation @ tensor @ pose.rotation.T, frame=pose, geometry=geometry,
                    geometry_name=geometry_name, geometry_scale=self.length, color=color,
                    inertia_resolution=resolution)

    # -- joints ------------------------------------------------------------------------------
    def _frame(self, element, prefix: str, where: str) -> tuple[str, Pose]:
        if element is None:
            raise ExportError(f"{where}: frame missing")
        uids = [(u.text or "").strip() for u in _children(_child(element, "InstancePath"), "Uid")]
        key = "/".join(([prefix] if prefix else []) + uids)
        if not uids or key not in self.assembly.parts:
            raise ExportError(f"{where}: InstancePath {'/'.join(uids) or '(empty)'} is not an instance of the export")
        return key, self.assembly.parts[key].frame @ self._transform(_child(element, "Transform"), where)

    def _joint(self, element, prefix: str) -> Joint | None:
        tag = _local(element.tag)
        name = element.get("name") or tag
        where = f"export {self.path.name}, joint {name}"
        kind = re.sub(r"[^a-z0-9]", "", tag.lower()).removesuffix("joint") or tag.lower()
        base, base_frame = self._frame(_child(element, "BaseFrame"), prefix, f"{where}: BaseFrame")
        follower, follower_frame = self._frame(_child(element, "FollowerFrame"), prefix, f"{where}: FollowerFrame")
        if kind not in JOINT_PRIMITIVES:
            self.assembly.warn(f"joint {name}: type <{tag}> is not supported: treated as a weld")
            kind = "weld"
        elif kind in APPROXIMATED:
            self.assembly.warn(f"joint {name} ({tag}): {APPROXIMATED[kind]}")
        if base == follower:
            self.assembly.warn(f"joint {name} joins two frames of one part: ignored")
            return None
        primitives = [Primitive(_P[p][0], base_frame.rotation[:, _P[p][1]].copy()) for p in JOINT_PRIMITIVES[kind]]
        return Joint(name=name, kind=kind if primitives else "weld", base=base, follower=follower,
                     base_frame=base_frame, follower_frame=follower_frame, primitives=primitives)

    def _fix_instances(self, referenced: set[str]) -> None:
        """Grounded instances and rigid sub-assembly members become synthetic welds."""
        for key, (parent, element, _, _) in self.nodes.items():
            parent_entity = self.nodes[parent][3] if parent else None
            rigid_parent = bool(parent) and not self._has_joints(parent_entity)
            grounded = element.get("grounded", "").lower() == "true"
            if grounded or rigid_parent or (parent and key not in referenced):
                anchor = parent or GROUND
                frame = self.assembly.parts[key].frame
                reason = "grounded" if grounded else "rigid in"
                self.assembly.joints.append(Joint(
                    name=f"{self.assembly.parts[key].name} {reason} {self.assembly.parts[parent].name if parent else 'world'}",
                    kind="weld", base=anchor, follower=key, base_frame=frame, follower_frame=frame, synthetic=True))

    def _has_joints(self, entity: str | None) -> bool:
        definition = self.assembly_entities.get(entity)
        return definition is not None and bool(list(_child(definition, "Joints") or [])
                                               or list(_child(definition, "Constraints") or []))


def _ancestors(key: str) -> set[str]:
    """``a/b/c`` -> {``a``, ``a/b``, ``a/b/c``}: a joint on a nested part refers to its sub-assemblies too."""
    pieces = key.split("/")
    return {"/".join(pieces[: i + 1]) for i in range(len(pieces))}


def read(root, path: Path) -> Assembly:
    """The neutral assembly of a second-generation export (``root``: its parsed root element)."""
    return _Reader(path).read(root)
