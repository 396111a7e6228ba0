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
    corners = np.array([[low[0] if i & 1 == 0 else high[0], low[1] if i & 2 == 0 else high[1],
                         low[2] if i & 4 == 0 else high[2]] for i in range(8)])
    faces = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
             (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]
    data = bytearray(b"test box".ljust(80, b" ") + struct.pack("<I", len(faces)))
    for a, b, c in faces:
        normal = np.cross(corners[b] - corners[a], corners[c] - corners[a])
        normal /= np.linalg.norm(normal)
        data += struct.pack("<12fH", *normal, *corners[a], *corners[b], *corners[c], 0)
    path.write_bytes(bytes(data))


def bar_inertia(mass: float, length: float, width: float, thickness: float) -> np.ndarray:
    """Uniform box about its centre, x along the length."""
    return mass / 12 * np.diag([width**2 + thickness**2, length**2 + thickness**2, length**2 + width**2])


# -- first generation --------------------------------------------------------------------------

def _numbers(values) -> str:
    return ",".join(f"{v:.12g}" for v in np.asarray(values, dtype=float).ravel())


@dataclass
class Gen1Frame:
    name: str
    position_mm: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    display_name: str = ""
    ref: int | None = None

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
  <positionUnits>"mm"</positionUnits>
  <orientation>{_numbers(column_major)}</orientation>
  <orientationType>"3x3 Transform"</orientationType>
  <orientationUnits>"rad"</orientationUnits>
  <orientationReferenceFrame>"WORLD"</orientationReferenceFrame>
</Frame>"""


@dataclass
class Gen1Body:
    name: str
    mass_g: float
    cg: Gen1Frame  # the CG frame; inertia_g_mm2 is expressed in its axes
    inertia_g_mm2: np.ndarray
    part_frame: Gen1Frame  # CS1, the geometry frame
    geometry: str = ""
    frames: list = field(default_factory=list)

    def xml(self) -> str:
        frames = "\n".join(f.xml() for f in [self.cg, self.part_frame, *self.frames])
        return f"""<Body>
<name>"{self.name}"</name>
<nodeID>"{self.name}"</nodeID>
<status>""</status>
<mass>{self.mass_g:.12g}</mass>
<massUnits>"g"</massUnits>
<inertia>{_numbers(self.inertia_g_mm2)}</inertia>
<inertiaUnits>"g*mm^2"</inertiaUnits>
<volume>0</volume>
<volumeUnits>"mm^3"</volumeUnits>
<frames>
{frames}
</frames>
<geometryFileName>"{self.geometry}"</geometryFileName>
<MaterialProp><color>0.8,0.3,0.2</color><transparency>0</transparency></MaterialProp>
</Body>"""


class Gen1Export:
    """Builds a first-generation export: bodies, ground, SimpleJoints with primitives."""

    def __init__(self):
        self.bodies: list[Gen1Body] = []
        self.joints: list[str] = []
        self.ground_frames: list[Gen1Frame] = []
        self._next_ref = 1
        self._owners: dict[str, Gen1Body | None] = {}

    def body(self, name, mass_g, cg_mm, inertia_cg_g_mm2, cg_rotation=None, part_origin_mm=(0, 0, 0),
             part_rotation=None, geometry="", named_frames=()) -> Gen1Body:
        cg = Gen1Frame("CG", np.asarray(cg_mm, float), np.eye(3) if cg_rotation is None else cg_rotation)
        part = Gen1Frame("CS1", np.asarray(part_origin_mm, float), np.eye(3) if part_rotation is None else part_rotation)
        frames = [Gen1Frame(f"CS{i + 2}", np.asarray(p, float), np.eye(3), display_name=n)
                  for i, (n, p) in enumerate(named_frames)]
        body = Gen1Body(name, mass_g, cg, np.asarray(inertia_cg_g_mm2, float), part, geometry, frames)
        self.bodies.append(body)
        return body

    def _frame_on(self, owner: Gen1Body | None, position_mm) -> int:
        ref = self._next_ref
        self._next_ref += 1
        frame = Gen1Frame(f"CS{100 + ref}", np.asarray(position_mm, float), np.eye(3), ref=ref)
        if owner is None:
            self.ground_frames.append(frame)
        else:
            owner.frames.append(frame)
        return ref

    def joint(self, name: str, base: Gen1Body | None, follower: Gen1Body, at_mm, primitives) -> None:
        """``primitives``: [(kind, axis_world)] with kind revolute/prismatic/spherical/weld; ``base=None`` is ground."""
        base_ref = self._frame_on(base, at_mm)
        follower_ref = self._frame_on(follower, at_mm)
        prims = "\n".join(f"""<Primitive><name>"{kind}"</name><nodeID>""</nodeID>
<referenceFrame>"WORLD"</referenceFrame><axis>{_numbers(axis)}</axis></Primitive>""" for kind, axis in primitives)
        self.joints.append(f"""<SimpleJoint>
<name>"{name}"</name><nodeID>"{name}"</nodeID><status>""</status>
<base><JointSide><name>""</name><connection><Frame ref="{base_ref}"></Frame></connection></JointSide></base>
<follower><JointSide><name>""</name><connection><Frame ref="{follower_ref}"></Frame></connection></JointSide></follower>
<primitives>{prims}</primitives>
</SimpleJoint>""")

    def weld_to_ground(self, body: Gen1Body, at_mm=(0, 0, 0)) -> None:
        self.joint(f"RootGround--{body.name}", None, body, at_mm, [("weld", (0.57735, 0.57735, 0.57735))])

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
    plane: np.ndarray = field(default_factory=lambda: rotation((0, 0, 1), 0.7) @ rotation((1, 0, 0), 1.1))
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

    def export(self, folder: Path, with_geometry: bool = True) -> Path:
        """Write ``fourbar.xml`` (mm, g) and its STL links into ``folder``."""
        o2, o4, a, b = self.points()
        normal = self.plane[:, 2]
        doc = Gen1Export()
        width, thickness, density = 6.0, 3.0, 7.85e-3  # mm, mm, g/mm^3
        base = doc.body("frame", 500.0, self.world(*(0.5 * (o2 + o4))), np.diag([2e5, 2e5, 2e5]),
                        part_origin_mm=self.world(0, 0), part_rotation=self.plane,
                        geometry="frame.stl" if with_geometry else "")
        if with_geometry:
            box_stl(folder / "frame.stl", (-5, -5, -12), (self.ground + 5, 5, -9))
        doc.weld_to_ground(base, self.world(0, 0))
        links = {}
        for i, (name, start, end, layer) in enumerate(
                [("crank", o2, a, 1), ("coupler", a, b, 2), ("rocker", o4, b, 1)]):
            length = float(np.linalg.norm(end - start))
            angle = math.atan2(*(end - start)[::-1])
            link_rotation = self.plane @ rotation((0, 0, 1), angle)  # x along the link, z along the normal
            mass = density * length * width * thickness
            mid = self.world(*(0.5 * (start + end)), layer * 4.0)
            named = [(f"{name}_start", self.world(*start, layer * 4.0)), (f"{name}_end", self.world(*end, layer * 4.0))]
            links[name] = doc.body(name, mass, mid, bar_inertia(mass, length, width, thickness), cg_rotation=link_rotation,
                                   part_origin_mm=self.world(*start, layer * 4.0), part_rotation=link_rotation,
                                   geometry=f"{name}.stl" if with_geometry else "", named_frames=named)
            if with_geometry:
                box_stl(folder / f"{name}.stl", (0, -width / 2, -thickness / 2), (length, width / 2, thickness / 2))
        revolute = [("revolute", normal)]
        doc.joint("ground--crank", base, links["crank"], self.world(*o2), revolute)
        doc.joint("crank--coupler", links["crank"], links["coupler"], self.world(*a), revolute)
        doc.joint("coupler--rocker", links["coupler"], links["rocker"], self.world(*b), revolute)
        doc.joint("rocker--ground", links["rocker"], base, self.world(*o4), revolute)
        return doc.write(folder / "fourbar.xml")


# -- second generation -------------------------------------------------------------------------

def gen2_transform(rotation_matrix=None, translation=(0, 0, 0)) -> str:
    r = np.eye(3) if rotation_matrix is None else np.asarray(rotation_matrix)
    return (f"<Transform><Rotation>{' '.join(f'{v:.12g}' for v in r.ravel())}</Rotation>"
            f"<Translation>{' '.join(f'{v:.12g}' for v in translation)}</Translation></Transform>")


def gen2_part(name: str, uid: str, mass: float, com, inertia_xx_yy_zz_yz_zx_xy, geometry: str = "") -> str:
    geometry_xml = f'<GeometryFile name="{geometry}" type="{"STL" if geometry.lower().endswith("stl") else "STEP"}"/>' if geometry else ""
    return (f'<Part name="{name}" uid="{uid}"><MassProperties><Mass>{mass:.12g}</Mass>'
            f"<CenterOfMass>{' '.join(f'{v:.12g}' for v in com)}</CenterOfMass>"
            f"<Inertia>{' '.join(f'{v:.12g}' for v in inertia_xx_yy_zz_yz_zx_xy)}</Inertia></MassProperties>"
            f'{geometry_xml}<VisualProperties><Diffuse a="1" b="0.5" g="0.5" r="0.5"/></VisualProperties></Part>')


def gen2_joint(kind: str, name: str, base_path, base_transform: str, follower_path, follower_transform: str) -> str:
    def frame(tag, path, transform):
        uids = "".join(f"<Uid>{u}</Uid>" for u in path)
        return f"<{tag}><InstancePath>{uids}</InstancePath>{transform}</{tag}>"
    return (f'<{kind} name="{name}">{frame("BaseFrame", base_path, base_transform)}'
            f'{frame("FollowerFrame", follower_path, follower_transform)}</{kind}>')


def gen2_export(instances: str, joints: str, parts: str, assemblies: str = "", length="meter", mass="kilogram",
                constraints: str = "") -> str:
    return f"""<?xml version="1.0" encoding="utf-8"?>
<SimscapeMultibodyImportXML xmlns="urn:mathworks:SimscapeMultibody:import" version="2.0">
<ModelUnits length="{length}" mass="{mass}"/>
<DataUnits length="{length}" mass="{mass}"/>
<RootAssembly name="test" uid="root"><InstanceTree>{instances}</InstanceTree>
<Constraints>{constraints}</Constraints><Joints>{joints}</Joints></RootAssembly>
<Assemblies>{assemblies}</Assemblies>
<Parts>{parts}</Parts>
</SimscapeMultibodyImportXML>
"""
