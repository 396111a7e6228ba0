"""Small CAD exports written by hand for tests: first-generation (PhysicalModelingXMLFile) and
second-generation (SimscapeMultibodyImportXML) files with binary STL geometry.

Written from the formats' conventions, independently of the readers: gen-1 frames in WORLD,
orientations as 3x3 matrices flattened column by column, inertia in the CG frame's axes;
gen-2 rotations row by row mapping child to parent, inertia ``Ixx Iyy Izz Iyz Izx Ixy``.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def rotation(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def box_stl(path: Path, low, high) -> None:
    """A binary STL box between two corners (in whatever unit the caller uses)."""
    low, high = np.asarray(low, float), np.asarray(high, float)
    corners = np.array(
        [
            [
                low[0] if i & 1 == 0 else high[0],
                low[1] if i & 2 == 0 else high[1],
                low[2] if i & 4 == 0 else high[2],
            ]
            for i in range(8)
        ]
    )
    faces = [
        (0, 2, 1),
        (1, 2, 3),
        (4, 5, 6),
        (5, 7, 6),
        (0, 1, 4),
        (1, 5, 4),
        (2, 6, 3),
        (3, 6, 7),
        (0, 4, 2),
        (2, 4, 6),
        (1, 3, 5),
        (3, 7, 5),
    ]
    data = bytearray(b"test box".ljust(80, b" ") + struct.pack("<I", len(faces)))
    for a, b, c in faces:
        normal = np.cross(corners[b] - corners[a], corners[c] - corners[a])
        normal /= np.linalg.norm(normal)
        data += struct.pack("<12fH", *normal, *corners[a], *corners[b], *corners[c], 0)
    path.write_bytes(bytes(data))


def bar_inertia(mass: float, length: float, width: float, thickness: float) -> np.ndarray:
    """Uniform box about its centre, x along the length."""
    return (
        mass
        / 12
        * np.diag([width**2 + thickness**2, length**2 + thickness**2, length**2 + width**2])
    )


# -- first generation --------------------------------------------------------------------------


def _numbers(values) -> str:
    return ",".join(f"{v:.12g}" for v in np.asarray(values, dtype=float).ravel())


@dataclass
class Gen1Frame:
    name: str
    position_mm: np.ndarray  # in ``length_unit``
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    display_name: str = ""
    ref: int | None = None
    length_unit: str = "mm"

    def xml(self) -> str:
        ref = f' ref="{self.ref}"' if self.ref is not None else ""
        column_major = self.rotation.T.ravel()  # first three numbers: the frame's x axis
        return f"""<Frame{ref}>
  <name>"{self.name}"</name>
  <displayName>"{self.display_name}"</displayName>
  <nodeID>"{self.name}(AUTOGEN)"</nodeID>
  <position>{_numbers(self.position_mm)}</position>
  <positionOrigin>"WORLD"</positionOrigin>
  <positionReferenceFrame>"WORLD"</positionReferenceFrame>
  <positionUnits>"{self.length_unit}"</positionUnits>
  <orientation>{_numbers(column_major)}</orientation>
  <orientationType>"3x3 Transform"</orientationType>
  <orientationUnits>"rad"</orientationUnits>
  <orientationReferenceFrame>"WORLD"</orientationReferenceFrame>
</Frame>"""


@dataclass
class Gen1Body:
    name: str
    mass_g: float  # in ``mass_unit``
    cg: Gen1Frame  # the CG frame; inertia_g_mm2 is expressed in its axes
    inertia_g_mm2: np.ndarray  # in mass_unit * length_unit^2
    part_frame: Gen1Frame  # CS1, the geometry frame
    geometry: str = ""
    frames: list = field(default_factory=list)
    mass_unit: str = "g"
    length_unit: str = "mm"

    def xml(self) -> str:
        frames = "\n".join(f.xml() for f in [self.cg, self.part_frame, *self.frames])
        return f"""<Body>
<name>"{self.name}"</name>
<nodeID>"{self.name}"</nodeID>
<status>""</status>
<mass>{self.mass_g:.12g}</mass>
<massUnits>"{self.mass_unit}"</massUnits>
<inertia>{_numbers(self.inertia_g_mm2)}</inertia>
<inertiaUnits>"{self.mass_unit}*{self.length_unit}^2"</inertiaUnits>
<volume>0</volume>
<volumeUnits>"{self.length_unit}^3"</volumeUnits>
<frames>
{frames}
</frames>
<geometryFileName>"{self.geometry}"</geometryFileName>
<MaterialProp><color>0.8,0.3,0.2</color><transparency>0</transparency></MaterialProp>
</Body>"""


class Gen1Export:
    """Builds a first-generation export: bodies, ground, SimpleJoints with primitives. Numbers are
    in ``length_unit`` and ``mass_unit`` (the ``_mm``/``_g`` argument names are the default units)."""

    def __init__(self, length_unit: str = "mm", mass_unit: str = "g"):
        self.bodies: list[Gen1Body] = []
        self.joints: list[str] = []
        self.ground_frames: list[Gen1Frame] = []
        self.length_unit, self.mass_unit = length_unit, mass_unit
        self._next_ref = 1
        self._owners: dict[str, Gen1Body | None] = {}

    def _frame(self, name, position, rotation=None, **extra) -> Gen1Frame:
        return Gen1Frame(
            name,
            np.asarray(position, float),
            np.eye(3) if rotation is None else rotation,
            length_unit=self.length_unit,
            **extra,
        )

    def body(
        self,
        name,
        mass_g,
        cg_mm,
        inertia_cg_g_mm2,
        cg_rotation=None,
        part_origin_mm=(0, 0, 0),
        part_rotation=None,
        geometry="",
        named_frames=(),
    ) -> Gen1Body:
        frames = [
            self._frame(f"CS{i + 2}", p, display_name=n) for i, (n, p) in enumerate(named_frames)
        ]
        body = Gen1Body(
            name,
            mass_g,
            self._frame("CG", cg_mm, cg_rotation),
            np.asarray(inertia_cg_g_mm2, float),
            self._frame("CS1", part_origin_mm, part_rotation),
            geometry,
            frames,
            mass_unit=self.mass_unit,
            length_unit=self.length_unit,
        )
        self.bodies.append(body)
        return body

    def _frame_on(self, owner: Gen1Body | None, position_mm) -> int:
        ref = self._next_ref
        self._next_ref += 1
        frame = self._frame(f"CS{100 + ref}", position_mm, ref=ref)
        if owner is None:
            self.ground_frames.append(frame)
        else:
            owner.frames.append(frame)
        return ref

    def joint(
        self, name: str, base: Gen1Body | None, follower: Gen1Body, at_mm, primitives
    ) -> None:
        """``primitives``: [(kind, axis_world)] with kind revolute/prismatic/spherical/weld; ``base=None`` is ground."""
        base_ref = self._frame_on(base, at_mm)
        follower_ref = self._frame_on(follower, at_mm)
        prims = "\n".join(
            f"""<Primitive><name>"{kind}"</name><nodeID>""</nodeID>
<referenceFrame>"WORLD"</referenceFrame><axis>{_numbers(axis)}</axis></Primitive>"""
            for kind, axis in primitives
        )
        self.joints.append(f"""<SimpleJoint>
<name>"{name}"</name><nodeID>"{name}"</nodeID><status>""</status>
<base><JointSide><name>""</name><connection><Frame ref="{base_ref}"></Frame></connection></JointSide></base>
<follower><JointSide><name>""</name><connection><Frame ref="{follower_ref}"></Frame></connection></JointSide></follower>
<primitives>{prims}</primitives>
</SimpleJoint>""")

    def weld_to_ground(self, body: Gen1Body, at_mm=(0, 0, 0)) -> None:
        self.joint(
            f"RootGround--{body.name}", None, body, at_mm, [("weld", (0.57735, 0.57735, 0.57735))]
        )

    def root_part(self, body: Gen1Body, at_mm=(0, 0, 0)) -> Gen1Body:
        """Ground ``body`` as Pro/E's SimMechanics Link does: through a massless ``RootPart`` body
        welded to ``body`` and to the ground."""
        root = self.body("RootPart", 0.0, at_mm, np.zeros((3, 3)))
        self.joint(
            f"RootPart--{body.name}", root, body, at_mm, [("weld", (0.57735, 0.57735, 0.57735))]
        )
        self.weld_to_ground(root, at_mm)
        return root

    def xml(self) -> str:
        ground = "\n".join(f.xml() for f in self.ground_frames)
        return f"""<?xml version="1.0" encoding="UTF-8" standalone="no" ?>
<PhysicalModelingXMLFile>
<formatVersion>"1.0.4"</formatVersion>
<createdUsing>"mechanism tests"</createdUsing>
<name>"TEST_MODEL"</name>
<SimMechanics>
<name>"TEST_MODEL"</name>
<bodies>
{chr(10).join(b.xml() for b in self.bodies)}
</bodies>
<joints>
{chr(10).join(self.joints)}
</joints>
<grounds><Ground><name>"RootGround"</name><nodeID>"RootGround"</nodeID><status>""</status><frame>
{ground}
</frame></Ground></grounds>
<subsystems></subsystems>
</SimMechanics>
</PhysicalModelingXMLFile>
"""

    def write(self, path: Path) -> Path:
        path.write_text(self.xml(), encoding="utf-8")
        return path


# -- a planar four-bar, plane rotated away from the world axes --------------------------------


@dataclass
class FourBar:
    """Crank-rocker four-bar in a tilted plane (lengths in mm)."""

    crank: float = 20.0
    coupler: float = 60.0
    rocker: float = 50.0
    ground: float = 55.0
    crank_angle0: float = math.radians(60.0)
    plane: np.ndarray = field(
        default_factory=lambda: rotation((0, 0, 1), 0.7) @ rotation((1, 0, 0), 1.1)
    )
    origin_mm: np.ndarray = field(default_factory=lambda: np.array([30.0, -20.0, 100.0]))

    def world(self, u: float, v: float, w: float = 0.0) -> np.ndarray:
        """Plane coordinates (mm) -> world (mm)."""
        return self.origin_mm + self.plane @ np.array([u, v, w])

    def plane_angle(self, vector_world) -> float:
        u, v, _ = self.plane.T @ np.asarray(vector_world, float)
        return math.atan2(v, u)

    def rocker_angle(self, crank_angle: float, branch: int = 1) -> float:
        """Freudenstein's closed form for the rocker angle (angles from the ground link O2->O4)."""
        a, b, c, d = self.crank, self.coupler, self.rocker, self.ground
        k1, k2, k3 = d / a, d / c, (a * a - b * b + c * c + d * d) / (2 * a * c)
        big_a = math.cos(crank_angle) - k1 - k2 * math.cos(crank_angle) + k3
        big_b = -2 * math.sin(crank_angle)
        big_c = k1 - (k2 + 1) * math.cos(crank_angle) + k3
        root = math.sqrt(big_b * big_b - 4 * big_a * big_c)
        return 2 * math.atan2(-big_b + branch * root, 2 * big_a)

    def points(self):
        """Ground pivots O2, O4 and pins A (crank/coupler), B (coupler/rocker) in plane coordinates."""
        theta4 = self.rocker_angle(self.crank_angle0)
        o2, o4 = np.zeros(2), np.array([self.ground, 0.0])
        a = o2 + self.crank * np.array([math.cos(self.crank_angle0), math.sin(self.crank_angle0)])
        b = o4 + self.rocker * np.array([math.cos(theta4), math.sin(theta4)])
        return o2, o4, a, b

    # mm, mm, g/mm^3, g (or the export's units)
    WIDTH, THICKNESS, DENSITY, FRAME_MASS = (
        6.0,
        3.0,
        7.85e-3,
        500.0,
    )

    def links(self):
        """(name, start pin, end pin, layer) of the moving links, in plane coordinates."""
        o2, o4, a, b = self.points()
        return [("crank", o2, a, 1), ("coupler", a, b, 2), ("rocker", o4, b, 1)]

    def masses(self) -> dict[str, float]:
        """Every body's mass as the export states it (g, or ``mass_unit``)."""
        bars = {
            name: self.DENSITY * float(np.linalg.norm(end - start)) * self.WIDTH * self.THICKNESS
            for name, start, end, _ in self.links()
        }
        return {"frame": self.FRAME_MASS, **bars}

    def export(
        self,
        folder: Path,
        with_geometry: bool = True,
        *,
        length_unit: str = "mm",
        mass_unit: str = "g",
        root_part: bool = False,
        write_meshes: bool = True,
    ) -> Path:
        """Write ``fourbar.xml`` and its STL links into ``folder``. Numbers are the same in any
        ``length_unit``/``mass_unit``; ``root_part``: grounded through a massless RootPart as Pro/E
        writes it; ``write_meshes=False`` names geometry files it does not write."""
        o2, o4, a, b = self.points()
        normal = self.plane[:, 2]
        doc = Gen1Export(length_unit, mass_unit)
        width, thickness, masses = self.WIDTH, self.THICKNESS, self.masses()
        write_meshes = with_geometry and write_meshes
        base = doc.body(
            "frame",
            masses["frame"],
            self.world(*(0.5 * (o2 + o4))),
            np.diag([2e5, 2e5, 2e5]),
            part_origin_mm=self.world(0, 0),
            part_rotation=self.plane,
            geometry="frame.stl" if with_geometry else "",
        )
        if write_meshes:
            box_stl(folder / "frame.stl", (-5, -5, -12), (self.ground + 5, 5, -9))
        if root_part:
            doc.root_part(base, self.world(0, 0))
        else:
            doc.weld_to_ground(base, self.world(0, 0))
        links = {}
        for name, start, end, layer in self.links():
            length = float(np.linalg.norm(end - start))
            angle = math.atan2(*(end - start)[::-1])
            # x along the link, z along the normal
            link_rotation = self.plane @ rotation((0, 0, 1), angle)
            mass = masses[name]
            mid = self.world(*(0.5 * (start + end)), layer * 4.0)
            named = [
                (f"{name}_start", self.world(*start, layer * 4.0)),
                (f"{name}_end", self.world(*end, layer * 4.0)),
            ]
            links[name] = doc.body(
                name,
                mass,
                mid,
                bar_inertia(mass, length, width, thickness),
                cg_rotation=link_rotation,
                part_origin_mm=self.world(*start, layer * 4.0),
                part_rotation=link_rotation,
                geometry=f"{name}.stl" if with_geometry else "",
                named_frames=named,
            )
            if write_meshes:
                box_stl(
                    folder / f"{name}.stl",
                    (0, -width / 2, -thickness / 2),
                    (length, width / 2, thickness / 2),
                )
        revolute = [("revolute", normal)]
        doc.joint("ground--crank", base, links["crank"], self.world(*o2), revolute)
        doc.joint("crank--coupler", links["crank"], links["coupler"], self.world(*a), revolute)
        doc.joint("coupler--rocker", links["coupler"], links["rocker"], self.world(*b), revolute)
        doc.joint("rocker--ground", links["rocker"], base, self.world(*o4), revolute)
        return doc.write(folder / "fourbar.xml")


# -- second generation -------------------------------------------------------------------------


def gen2_transform(rotation_matrix=None, translation=(0, 0, 0)) -> str:
    r = np.eye(3) if rotation_matrix is None else np.asarray(rotation_matrix)
    return (
        f"<Transform><Rotation>{' '.join(f'{v:.12g}' for v in r.ravel())}</Rotation>"
        f"<Translation>{' '.join(f'{v:.12g}' for v in translation)}</Translation></Transform>"
    )


def gen2_part(
    name: str,
    uid: str,
    mass: float,
    com,
    inertia_xx_yy_zz_yz_zx_xy,
    geometry: str = "",
    extra: str = "",
) -> str:
    """``extra``: XML written before the mass properties (e.g. the part's own ``<ModelUnits>``)."""
    geometry_xml = (
        f'<GeometryFile name="{geometry}" type="{"STL" if geometry.lower().endswith("stl") else "STEP"}"/>'
        if geometry
        else ""
    )
    return (
        f'<Part name="{name}" uid="{uid}">{extra}<MassProperties><Mass>{mass:.12g}</Mass>'
        f"<CenterOfMass>{' '.join(f'{v:.12g}' for v in com)}</CenterOfMass>"
        f"<Inertia>{' '.join(f'{v:.12g}' for v in inertia_xx_yy_zz_yz_zx_xy)}</Inertia></MassProperties>"
        f'{geometry_xml}<VisualProperties><Diffuse a="1" b="0.5" g="0.5" r="0.5"/></VisualProperties></Part>'
    )


def gen2_joint(
    kind: str, name: str, base_path, base_transform: str, follower_path, follower_transform: str
) -> str:
    def frame(tag, path, transform):
        uids = "".join(f"<Uid>{u}</Uid>" for u in path)
        return f"<{tag}><InstancePath>{uids}</InstancePath>{transform}</{tag}>"

    return (
        f'<{kind} name="{name}">{frame("BaseFrame", base_path, base_transform)}'
        f"{frame('FollowerFrame', follower_path, follower_transform)}</{kind}>"
    )


def gen2_export(
    instances: str,
    joints: str,
    parts: str,
    assemblies: str = "",
    length="meter",
    mass="kilogram",
    constraints: str = "",
    *,
    model_units=None,
    data_units: bool = True,
    legacy: bool = False,
) -> str:
    """Numbers in ``length``/``mass`` (the ``DataUnits``). ``model_units``: (length, mass) of the CAD
    document, default the same; ``data_units=False`` leaves ``DataUnits`` out and writes ``length``/
    ``mass`` as the ``ModelUnits`` (Creo); ``legacy``: SimMechanics Link 4.x's ``SimMechanicsImportXML`` 1.0."""
    root, namespace, version = (
        ("SimMechanicsImportXML", "urn:mathworks:simmechanics:import", "1.0")
        if legacy
        else ("SimscapeMultibodyImportXML", "urn:mathworks:SimscapeMultibody:import", "2.0")
    )
    model_length, model_mass = model_units or (length, mass)
    data = f'<DataUnits length="{length}" mass="{mass}"/>' if data_units else ""
    return f"""<?xml version="1.0" encoding="utf-8"?>
<{root} xmlns="{namespace}" version="{version}">
<ModelUnits length="{model_length}" mass="{model_mass}"/>
{data}
<RootAssembly name="test" uid="root"><InstanceTree>{instances}</InstanceTree>
<Constraints>{constraints}</Constraints><Joints>{joints}</Joints></RootAssembly>
<Assemblies>{assemblies}</Assemblies>
<Parts>{parts}</Parts>
</{root}>
"""


def gen2_assembly(uid: str, constraints: str = "", joints: str = "") -> str:
    """A sub-assembly definition with its own mates and joints (paths below its instances)."""
    return f'<Assembly name="{uid}" uid="{uid}"><Constraints>{constraints}</Constraints><Joints>{joints}</Joints></Assembly>'


def gen2_mate(tag: str, name: str, first, second) -> str:
    """A CAD mate as SolidWorks writes it: ``first``/``second`` = (geomType, [instance uids],
    position in that instance's frame, axis or None), numbers in the export's length unit."""

    def geometry(shape, path, position, axis):
        uids = "".join(f"<Uid>{u}</Uid>" for u in path)
        axis_xml = "" if axis is None else f"<Axis>{' '.join(f'{v:.12g}' for v in axis)}</Axis>"
        return (
            f'<ConstraintGeometry geomType="{shape}"><InstancePath>{uids}</InstancePath>'
            f"<Position>{' '.join(f'{v:.12g}' for v in position)}</Position>{axis_xml}</ConstraintGeometry>"
        )

    return f'<{tag} name="{name}">{geometry(*first)}{geometry(*second)}</{tag}>'


def gen2_instance(
    name: str,
    entity: str,
    rotation_matrix=None,
    translation=(0, 0, 0),
    grounded=False,
    extra="",
    children="",
    uid: str | None = None,
) -> str:
    flag = ' grounded="true"' if grounded else ""
    return (
        f'<Instance name="{name}" uid="{uid or name}"{flag}{extra} entityUid="{entity}">'
        f"{gen2_transform(rotation_matrix, translation)}{children}</Instance>"
    )


def gen2_unknown(name: str, first_path, second_path) -> str:
    """A mate the exporter could not describe (SolidWorks lock, width, symmetric): no positions."""
    sides = "".join(
        f'<ConstraintGeometry geomType="Unknown"><InstancePath>{"".join(f"<Uid>{u}</Uid>" for u in path)}'
        f"</InstancePath></ConstraintGeometry>"
        for path in (first_path, second_path)
    )
    return f'<UnknownConstraint name="{name}">{sides}</UnknownConstraint>'


# -- mates written from world geometry ---------------------------------------------------------


def in_frame(pose, point=None, axis=None) -> np.ndarray:
    """A world point (or axis) in the frame of an instance at ``pose`` = (rotation, origin)."""
    rot, origin = pose
    if axis is not None:
        return rot.T @ np.asarray(axis, float)
    return rot.T @ (np.asarray(point, float) - origin)


SLASH = "\u2215"  # stands for a "/" inside a uid (Onshape writes them) in the keys below


def instance_path(key: str, within: str = "") -> list[str]:
    """The ``InstancePath`` uids of the instance ``key`` (``sub/part`` for nested ones), below the
    sub-assembly ``within`` for that sub-assembly's own mates and joints."""
    key = key.removeprefix(f"{within}/") if within else key
    return [uid.replace(SLASH, "/") for uid in key.split("/")] if key else []


def mate_side(shape: str, key: str, pose, point, axis=None, within: str = ""):
    """One side of a mate for ``gen2_mate``: world ``point``/``axis`` written in the frame of the
    instance ``key`` at ``pose``."""
    return (
        shape,
        instance_path(key, within),
        in_frame(pose, point),
        None if axis is None else in_frame(pose, axis=axis),
    )


def pin_mates(name: str, a: str, b: str, poses: dict, point, normal, within: str = "") -> list[str]:
    """Concentric bores and touching faces: a revolute about ``normal`` through ``point``."""
    normal = np.asarray(normal, float)
    return [
        gen2_mate(
            "Concentric",
            f"{name}_bore",
            mate_side("cylinder", a, poses[a], point, normal, within),
            mate_side("cylinder", b, poses[b], point, -normal, within),
        ),
        gen2_mate(
            "Coincident",
            f"{name}_face",
            mate_side("plane", a, poses[a], point, normal, within),
            mate_side("plane", b, poses[b], point, -normal, within),
        ),
    ]


@dataclass
class Inst:
    """An instance of a part or sub-assembly placed by its world pose (the export's length unit)."""

    uid: str
    entity: str
    rotation: np.ndarray | None = None  # world; None: identity
    origin: tuple = (0, 0, 0)  # world
    attrs: str = ""  # extra XML attributes: ' grounded="true"', ' rigid="true"', ' visible="false"'
    children: tuple = ()
    name: str | None = None  # default: the uid


def instance_tree(instances, poses: dict, parent=None, prefix: str = "") -> str:
    """The ``<Instance>`` elements, each ``Transform`` relative to its parent as exporters write
    them; ``poses`` gets every instance's world pose under its key (``sub/part``)."""
    parent_rotation, parent_origin = parent or (np.eye(3), np.zeros(3))
    xml = []
    for inst in instances:
        key = "/".join(filter(None, (prefix, inst.uid.replace("/", SLASH))))
        world = (
            np.eye(3) if inst.rotation is None else np.asarray(inst.rotation, float),
            np.asarray(inst.origin, float),
        )
        poses[key] = world
        children = instance_tree(inst.children, poses, world, key)
        xml.append(
            gen2_instance(
                inst.name or inst.uid,
                inst.entity,
                parent_rotation.T @ world[0],
                in_frame((parent_rotation, parent_origin), world[1]),
                extra=inst.attrs,
                children=children,
                uid=inst.uid,
            )
        )
    return "".join(xml)
