#!/usr/bin/env python3
"""Generate the shipped sewing machine's CAD export from one parameter file.

    python assets/cad/sapphire870/generate.py [--params FILE] [-o DIR]

writes, into DIR (default ``assets/cad/sapphire870/export``):

* ``sewing_machine.xml``: a first-generation SimMechanics ``PhysicalModelingXMLFile``
  (the format proe2sm / SimMechanics Link wrote from Pro/E), see ``firstgen.py``;
* one binary STL per part, in mm, in the part's own frame (``<part>_prt.stl``);
* ``sewing_machine.couplings.json``: the belts and the hook gear (docs/architecture.md).

Every solid is built with manifold3d booleans (watertight, positive volume); mass, centre
of mass and inertia come from the solid as written to its STL and the material density in
the parameter file. The output is deterministic byte for byte.

Assembly pose: arm angle 0 = needle bar at top dead centre (docs/architecture.md).
"""

from __future__ import annotations

import argparse
import json
import math
import struct
import sys
from dataclasses import dataclass, field
from pathlib import Path

import manifold3d as mf
import numpy as np
import trimesh
from scipy.optimize import brentq, minimize_scalar

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import firstgen  # noqa: E402

from mechanism.files.outputs import atomic_dir  # noqa: E402  (the project's own atomic folder replace)

DEFAULT_PARAMS = HERE / "sewing_machine.params.json"
DEFAULT_OUT = HERE / "export"
EXPORT_NAME = "sewing_machine"
PARAMS_FORMAT = "mechanism-cad-params/1"

SEGMENTS = 48  # round parts; small pins use fewer
SMALL = 20


class ParamError(Exception):
    """A parameter file problem, reported as one line."""


# --------------------------------------------------------------------------- parameters

ALLOWED_UNITS = {"mm", "deg", "kg/m^3", "kg*m^2", "1", "-", "NM"}


class Params:
    """The parameter file: ``section -> name -> {value, unit, source}``."""

    def __init__(self, data: dict, path: Path):
        if data.get("format") != PARAMS_FORMAT:
            raise ParamError(f"{path}: 'format' must be {PARAMS_FORMAT!r}")
        self.path = path
        self.sections = {k: v for k, v in data.items() if isinstance(v, dict)}
        for section, entries in self.sections.items():
            for name, entry in entries.items():
                where = f"{path}: {section}.{name}"
                if not isinstance(entry, dict) or not {"value", "unit", "source"} <= set(entry):
                    raise ParamError(f"{where}: needs value, unit and source")
                if entry["unit"] not in ALLOWED_UNITS:
                    raise ParamError(f"{where}: unit {entry['unit']!r} is not one of {sorted(ALLOWED_UNITS)}")
                if not str(entry["source"]).strip():
                    raise ParamError(f"{where}: empty source")

    @classmethod
    def load(cls, path: Path) -> "Params":
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ParamError(f"{path}: no such file") from None
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ParamError(f"{path}: not a JSON parameter file ({exc})") from None
        return cls(data, Path(path))

    def raw(self, section: str, name: str):
        try:
            return self.sections[section][name]["value"]
        except KeyError:
            raise ParamError(f"{self.path}: missing parameter {section}.{name}") from None

    def __call__(self, section: str, name: str) -> float:
        value = self.raw(section, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ParamError(f"{self.path}: {section}.{name} must be a finite number")
        return float(value)

    def positive(self, section: str, name: str) -> float:
        value = self(section, name)
        if value <= 0:
            raise ParamError(f"{self.path}: {section}.{name} must be positive (is {value})")
        return value

    def density(self, name: str) -> float:
        """g/mm^3 from kg/m^3."""
        return self.positive("materials", name) * 1e-6


# --------------------------------------------------------------------------- geometry

def cylinder(radius: float, z0: float, z1: float, segments: int = SEGMENTS) -> mf.Manifold:
    return mf.Manifold.cylinder(z1 - z0, radius, circular_segments=segments).translate((0.0, 0.0, z0))


def tube(outer: float, inner: float, z0: float, z1: float, segments: int = SEGMENTS) -> mf.Manifold:
    profile = [(inner, z0), (outer, z0), (outer, z1), (inner, z1)]
    return revolve(profile, segments)


def revolve(profile_rz, segments: int = SEGMENTS) -> mf.Manifold:
    """Solid of revolution about local z from an (r, z) polygon (counter-clockwise)."""
    section = mf.CrossSection([np.asarray(profile_rz, dtype=float)])
    return mf.Manifold.revolve(section, circular_segments=segments)


def box(x0, x1, y0, y1, z0, z1) -> mf.Manifold:
    return mf.Manifold.cube((x1 - x0, y1 - y0, z1 - z0)).translate((x0, y0, z0))


def circle(radius: float, center=(0.0, 0.0), segments: int = SEGMENTS) -> mf.CrossSection:
    return mf.CrossSection.circle(radius, segments).translate(tuple(float(c) for c in center))


def slab(section: mf.CrossSection, z0: float, z1: float) -> mf.Manifold:
    return mf.Manifold.extrude(section, z1 - z0).translate((0.0, 0.0, z0))


def sector(r_in: float, r_out: float, start_deg: float, end_deg: float, steps: int = 24) -> mf.CrossSection:
    angles = np.radians(np.linspace(start_deg, end_deg, steps + 1))
    outer = np.column_stack([r_out * np.cos(angles), r_out * np.sin(angles)])
    inner = np.column_stack([r_in * np.cos(angles[::-1]), r_in * np.sin(angles[::-1])])
    return mf.CrossSection([np.vstack([outer, inner])])


def union(*solids: mf.Manifold) -> mf.Manifold:
    return mf.Manifold.batch_boolean(list(solids), mf.OpType.Add)


def rot_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=float)


def rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=float)


# part z along world +x, part y along world +z (rotating parts on the x-parallel shafts)
ALONG_X = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def pose(rotation: np.ndarray, origin) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = origin
    return T


def in_plane(direction_yz) -> np.ndarray:
    """Rotation of a part drawn in its local x-y plane (z = world x) whose local +y points
    along ``direction_yz`` in the world y-z plane."""
    u = np.array([0.0, direction_yz[0], direction_yz[1]])
    u /= np.linalg.norm(u)
    z = np.array([1.0, 0.0, 0.0])
    x = np.cross(u, z)
    return np.column_stack([x, u, z])


# --------------------------------------------------------------------------- assembly model

MATERIALS = {
    # key in the parameter file, colour (the CAD appearance the exporter writes)
    "steel": ("steel_density", (0.72, 0.73, 0.76)),
    "aluminium": ("aluminium_die_cast_density", (0.80, 0.81, 0.83)),
    "casting": ("aluminium_die_cast_density", (0.93, 0.92, 0.88)),
    "nylon": ("glass_filled_nylon_density", (0.12, 0.12, 0.13)),
    "abs": ("abs_density", (0.90, 0.89, 0.85)),
    "copper": ("copper_density", (0.78, 0.48, 0.25)),
    "armature": ("armature_effective_density", (0.35, 0.30, 0.28)),
}


@dataclass
class Part:
    name: str
    material: str
    solid: mf.Manifold
    pose: np.ndarray  # part -> world at the assembly pose (mm)
    frames: dict = field(default_factory=dict)  # user frame name -> point in part coordinates
    subsystem: str | None = None


@dataclass
class Joint:
    name: str
    kind: str  # revolute | prismatic | weld
    base: str
    follower: str
    point: np.ndarray  # world, mm
    axis: np.ndarray  # world


@dataclass
class Layout:
    """Derived positions of the assembly (world, mm) at arm angle 0 = needle TDC."""

    shaft: np.ndarray  # (y, z) of the arm-shaft axis
    crank_tdc_deg: float  # crank rotation about +x that puts the needle bar at TDC
    connector_tdc_z: float
    stroke: float
    tip_tdc_z: float
    tip_bdc_z: float
    bar_bottom_tdc_z: float
    passage_arm_deg: float
    hook_axis: np.ndarray  # (x, y)
    hook_rim_z: float
    hook_assembly_deg: float
    lower_gear_radius: float
    take_up_pin_link: np.ndarray  # (y, z) at assembly
    take_up_pivot: np.ndarray  # (y, z)


class SliderCrank:
    """Needle-bar slider-crank in the y-z plane: crank angle phi about +x from the local
    crank direction (0, 1) (up), needle-bar axis at y = 0."""

    def __init__(self, shaft_yz, r, L):
        self.y_s, self.z_s = shaft_yz
        self.r, self.L = r, L

    def pin(self, phi):
        return np.array([self.y_s - self.r * math.sin(phi), self.z_s + self.r * math.cos(phi)])

    def connector_z(self, phi):
        y_p, z_p = self.pin(phi)
        return z_p - math.sqrt(self.L**2 - y_p**2)


def four_bar_pin(P, O, lever, link, below: bool, previous=None):
    """The take-up lever/link pin Q with |PQ| = lever, |OQ| = link."""
    d = np.linalg.norm(O - P)
    if d > lever + link or d < abs(lever - link):
        return None
    a = (lever**2 - link**2 + d**2) / (2 * d)
    h = math.sqrt(max(lever**2 - a**2, 0.0))
    u = (O - P) / d
    n = np.array([-u[1], u[0]])
    candidates = [P + a * u + h * n, P + a * u - h * n]
    if previous is not None:
        return min(candidates, key=lambda q: np.linalg.norm(q - previous))
    return min(candidates, key=lambda q: q[1]) if below else max(candidates, key=lambda q: q[1])


def compute_layout(p: Params) -> Layout:
    r = p.positive("crank", "radius")
    L = p.positive("link", "length")
    offset = p("needle_bar", "offset_y")
    z_s = p.positive("arm_shaft", "height")
    if L <= r + abs(offset):
        raise ParamError("link.length must exceed crank.radius + |needle_bar.offset_y|")
    shaft = np.array([-offset, z_s])
    sc = SliderCrank(shaft, r, L)

    tdc = minimize_scalar(lambda phi: -sc.connector_z(phi), bounds=(-math.pi / 2, math.pi / 2), method="bounded",
                          options={"xatol": 1e-12})
    phi_tdc = float(tdc.x)
    bdc = minimize_scalar(sc.connector_z, bounds=(phi_tdc + math.pi / 2, phi_tdc + 3 * math.pi / 2),
                          method="bounded", options={"xatol": 1e-12})
    zc_tdc, zc_bdc = sc.connector_z(phi_tdc), sc.connector_z(float(bdc.x))
    stroke = zc_tdc - zc_bdc

    # hook timing: the point passes the scarf `point_above_eye` above the eye when the
    # needle has risen `needle_rise_at_passage` from bottom dead centre
    hook_point_z = -(p("hook", "rim_below_plate") + p("hook", "point_below_rim"))
    eye_top = p("needle", "eye_bottom_above_tip") + p("needle", "eye_length")
    rise = p.positive("hook", "needle_rise_at_passage")
    tip_at_passage = hook_point_z - eye_top - p("hook", "point_above_eye")
    tip_bdc = tip_at_passage - rise
    tip_tdc = tip_bdc + stroke
    bar_bottom_tdc = tip_tdc + p.positive("needle", "length")

    theta_bdc = float(bdc.x) - phi_tdc
    passage = brentq(lambda th: (sc.connector_z(th + phi_tdc) - zc_bdc) - rise, theta_bdc, theta_bdc + math.pi - 1e-9,
                     xtol=1e-14)

    # hook: axis in front of the needle so that the point path passes the scarf bottom
    # at `point_clearance`; the point turns counter-clockwise seen from above (+z)
    scarf_surface = p("needle", "blade_diameter") / 2 - p("needle", "scarf_depth")
    needle_radius_from_hook = p("hook", "point_radius") - p("hook", "point_clearance") - scarf_surface
    hook_axis = np.array([0.0, -needle_radius_from_hook])
    turns = p("hook", "turns_per_arm_turn")
    hook_assembly = 90.0 - turns * math.degrees(passage)
    lower_gear_r = needle_radius_from_hook - p("hook", "gear_pitch_diameter") / 2 - p("hook", "gear_backlash_gap")
    if lower_gear_r <= p("lower_shaft", "diameter") / 2:
        raise ParamError("the lower-shaft gear would be thinner than the lower shaft (hook.gear_pitch_diameter too large)")

    # take-up four-bar: crank pin P, lever pin Q, fixed pivot O
    O = shaft + np.array([p("take_up", "pivot_y"), p("take_up", "pivot_z")])
    lever, link = p.positive("take_up", "lever_length"), p.positive("take_up", "link_length")
    Q0 = four_bar_pin(sc.pin(phi_tdc), O, lever, link, bool(p.raw("take_up", "link_below_line")))
    if Q0 is None:
        raise ParamError("take-up four-bar cannot be assembled at arm angle 0")
    q = Q0
    for th in np.linspace(0, 2 * math.pi, 721)[1:]:
        q = four_bar_pin(sc.pin(th + phi_tdc), O, lever, link, True, previous=q)
        if q is None:
            raise ParamError("take-up four-bar locks before a full arm turn (not a crank-rocker)")

    return Layout(shaft=shaft, crank_tdc_deg=math.degrees(phi_tdc), connector_tdc_z=zc_tdc, stroke=stroke,
                  tip_tdc_z=tip_tdc, tip_bdc_z=tip_bdc, bar_bottom_tdc_z=bar_bottom_tdc,
                  passage_arm_deg=math.degrees(passage), hook_axis=hook_axis, hook_rim_z=-p("hook", "rim_below_plate"),
                  hook_assembly_deg=hook_assembly, lower_gear_radius=lower_gear_r, take_up_pin_link=Q0,
                  take_up_pivot=O)


def take_up_eye_path(p: Params, lay: Layout, samples: int = 361) -> np.ndarray:
    """(y, z) of the take-up lever's thread eye over one arm turn (for the face slot)."""
    sc = SliderCrank(lay.shaft, p("crank", "radius"), p("link", "length"))
    lever, link, ratio = p("take_up", "lever_length"), p("take_up", "link_length"), p("take_up", "eye_ratio")
    q, pts = lay.take_up_pin_link, []
    for th in np.linspace(0, 2 * math.pi, samples):
        P = sc.pin(th + math.radians(lay.crank_tdc_deg))
        q = four_bar_pin(P, lay.take_up_pivot, lever, link, True, previous=q)
        pts.append((P, P + ratio * (q - P)))
    return np.array(pts)


# --------------------------------------------------------------------------- parts

def build_parts(p: Params, lay: Layout) -> tuple[list[Part], list[Joint]]:
    parts: list[Part] = []
    joints: list[Joint] = []
    X, Z = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    y_s, z_s = lay.shaft
    wall = p.positive("casting", "wall")

    def add(part: Part) -> Part:
        parts.append(part)
        return part

    def weld(base: str, follower: str, point) -> None:
        joints.append(Joint(f"{base}--{follower}", "weld", base, follower, np.asarray(point, float), firstgen.WELD_AXIS))

    # ---- needle plate (fixed) and the casting around it
    t_plate = p.positive("needle_plate", "thickness")
    px0, px1 = p("needle_plate", "x_min"), p("needle_plate", "x_max")
    py0, py1 = p("needle_plate", "y_min"), p("needle_plate", "y_max")
    plate = box(px0, px1, py0, py1, -t_plate, 0.0)
    sw, sd = p.positive("needle_plate", "needle_slot_width"), p.positive("needle_plate", "needle_slot_depth")
    fw, fl, fo = (p.positive("needle_plate", k) for k in ("feed_slot_width", "feed_slot_length", "feed_slot_offset"))
    plate = plate - union(
        box(-sw / 2, sw / 2, -sd / 2, sd / 2, -t_plate - 1, 1),
        box(-fo - fw / 2 - sw / 2, -fo + fw / 2 - sw / 2, -fl * 0.7, fl * 0.3, -t_plate - 1, 1),
        box(fo - fw / 2 + sw / 2, fo + fw / 2 + sw / 2, -fl * 0.7, fl * 0.3, -t_plate - 1, 1),
    )
    add(Part("needle_plate", "steel", plate, pose(np.eye(3), (0, 0, 0)), {"needle_plate_top": (0.0, 0.0, 0.0)}))

    c = {k: p("casting", k) for k in p.sections["casting"]}
    depth = p.positive("casting", "bed_depth")
    arm_z0, arm_z1 = z_s - c["arm_bottom_below_shaft"], z_s + c["arm_top_above_shaft"]
    head_z1 = z_s + c["head_top_above_shaft"]
    outer = union(
        box(c["bed_x_min"], c["bed_x_max"], c["bed_y_min"], c["bed_y_max"], -depth, 0),
        box(c["pillar_x_min"], c["pillar_x_max"], c["pillar_y_min"], c["pillar_y_max"], -depth, arm_z1),
        box(c["head_x_min"], c["pillar_x_max"], c["arm_y_min"], c["arm_y_max"], arm_z0, arm_z1),
        box(c["head_x_min"], c["head_x_max"], c["head_y_min"], c["head_y_max"], c["head_bottom_z"], head_z1),
    )
    inner = union(
        box(c["bed_x_min"] + wall, c["bed_x_max"] - wall, c["bed_y_min"] + wall, c["bed_y_max"] - wall, -depth - 1, -wall),
        box(c["pillar_x_min"] + wall, c["pillar_x_max"] - wall, c["pillar_y_min"] + wall, c["pillar_y_max"] - wall,
            -depth - 1, arm_z1 - wall),
        box(c["head_x_min"] + wall, c["pillar_x_max"] - wall, c["arm_y_min"] + wall, c["arm_y_max"] - wall,
            arm_z0 + wall, arm_z1 - wall),
        box(c["head_x_min"] + wall, c["head_x_max"] - wall, c["head_y_min"] + wall, c["head_y_max"] - wall,
            c["head_bottom_z"] + wall, head_z1 - wall),
    )
    bar_r = p.positive("needle_bar", "diameter") / 2
    shaft_r = p.positive("arm_shaft", "diameter") / 2
    ledge = 4.0
    # take-up lever slot in the face: where the lever crosses the front wall, with margin
    lever_x, lever_t = p("take_up", "lever_x"), p.positive("take_up", "lever_thickness")
    lever_w = p.positive("take_up", "lever_width")
    path = take_up_eye_path(p, lay)
    if path[:, 1, 0].max() > c["head_y_min"] - 1.0:
        raise ParamError("the take-up lever eye does not leave the head face over the whole turn")
    slot_z = []  # where the lever (its half width plus 1 mm, measured along z) crosses the face wall
    for P_pt, E_pt in path:
        u = (E_pt - P_pt) / np.linalg.norm(E_pt - P_pt)
        half = (lever_w / 2 + 1.0) / max(abs(u[0]), 0.2)
        for y_face in (c["head_y_min"], c["head_y_min"] + wall):
            s = (y_face - P_pt[0]) / (E_pt[0] - P_pt[0])
            slot_z += [P_pt[1] + s * (E_pt[1] - P_pt[1]) - half, P_pt[1] + s * (E_pt[1] - P_pt[1]) + half]
    tu_x, tu_t = p("take_up", "link_x"), p.positive("take_up", "link_thickness")
    O = lay.take_up_pivot
    pivot_pin_r = 2.0
    bracket_x0 = tu_x + tu_t + 0.5
    casting = outer - union(
        inner,
        box(px0, px1, py0, py1, -t_plate, 1.0),  # needle-plate pocket
        box(px0 + ledge, px1 - ledge, py0 + ledge, py1 - ledge, -wall - 1, 1.0),  # opening under the plate
        cylinder(bar_r + 0.3, c["head_bottom_z"] - 1, c["head_bottom_z"] + wall + 1, SMALL),  # needle-bar bushing bore
        box(c["pillar_x_max"] - wall - 1, c["pillar_x_max"] + 1, y_s - shaft_r - 1.5, y_s + shaft_r + 1.5,
            z_s - shaft_r - 1.5, z_s + shaft_r + 1.5),  # handwheel-side shaft bore
        box(lever_x - 1.5, lever_x + lever_t + 1.5, c["head_y_min"] - 1, c["head_y_min"] + wall + 1,
            min(slot_z), max(slot_z)),  # take-up lever slot
    )
    # take-up link pivot: a pin on a bracket hanging from the head top
    pivot = union(
        cylinder(pivot_pin_r, 0.0, bracket_x0 + 3.0 - (tu_x - 0.2), SMALL).transform(
            pose(ALONG_X, (tu_x - 0.2, O[0], O[1]))[:3]),
        box(bracket_x0, bracket_x0 + 3.0, O[0] - 4, O[0] + 4, O[1] - 4, head_z1 - wall + 0.5),
    )
    casting = casting + pivot
    add(Part("bed_casting", "casting", casting, pose(np.eye(3), (0, 0, 0))))
    weld("bed_casting", "needle_plate", (0, 0, -t_plate / 2))

    # ---- motor (fixed housing, rotor sub-assembly)
    m_y, m_z = p("motor", "axis_y"), p("motor", "axis_z")
    hx0, hl, hd = p("motor", "housing_x_min"), p.positive("motor", "housing_length"), p.positive("motor", "housing_diameter")
    housing = tube(hd / 2, hd / 2 - 1.5, 0, hl) + tube(hd / 2 - 1.0, 4.0, 0, 2.0) + tube(hd / 2 - 1.0, 4.0, hl - 2.0, hl)
    add(Part("motor_housing", "steel", housing, pose(ALONG_X, (hx0, m_y, m_z))))
    weld("bed_casting", "motor_housing", (hx0, m_y, m_z))

    arm_pulley_x, pulley_w = p("arm_shaft", "pulley_x"), p.positive("arm_shaft", "pulley_width")
    ms_x0, ms_r = p("motor", "shaft_x_min"), p.positive("motor", "shaft_diameter") / 2
    ms_len = arm_pulley_x + pulley_w + 1.0 - ms_x0
    motor_pose = pose(ALONG_X, (ms_x0, m_y, m_z))
    add(Part("motor_shaft", "steel", cylinder(ms_r, 0, ms_len, SMALL), motor_pose, subsystem="MOTOR_ROTOR"))
    a_x0, a_len, a_r = p("motor", "armature_x_min"), p.positive("motor", "armature_length"), p.positive("motor", "armature_diameter") / 2
    if not (hx0 + 2.0 < a_x0 and a_x0 + a_len + 1.0 + p("motor", "commutator_length") < hx0 + hl - 2.0 and a_r < hd / 2 - 2.0):
        raise ParamError("motor armature and commutator must fit inside the housing")
    z_a = a_x0 - ms_x0
    add(Part("motor_armature", "armature", tube(a_r, ms_r, z_a, z_a + a_len), motor_pose, subsystem="MOTOR_ROTOR"))
    z_c = z_a + a_len + 1.0
    add(Part("motor_commutator", "copper",
             tube(p.positive("motor", "commutator_diameter") / 2, ms_r, z_c, z_c + p.positive("motor", "commutator_length")),
             motor_pose, subsystem="MOTOR_ROTOR"))
    mp_r = p.positive("motor", "pulley_pitch_diameter") / 2
    z_p = arm_pulley_x - ms_x0
    add(Part("motor_pulley", "aluminium", flanged_pulley(mp_r, ms_r, z_p, pulley_w), motor_pose, subsystem="MOTOR_ROTOR"))
    for name in ("motor_armature", "motor_commutator", "motor_pulley"):
        weld("motor_shaft", name, (ms_x0, m_y, m_z))
    joints.append(Joint("motor", "revolute", "bed_casting", "motor_shaft", np.array([ms_x0, m_y, m_z]), X))

    # ---- arm shaft with pulleys, handwheel and the needle-bar crank
    disc_x, disc_t = p("crank", "disc_x"), p.positive("crank", "disc_thickness")
    r = p.positive("crank", "radius")
    crank_rot = rot_x(lay.crank_tdc_deg) @ ALONG_X
    shaft_end = p("arm_shaft", "handwheel_end_x")
    shaft_x0 = disc_x + 1.0
    arm_axis = np.array([0.0, y_s, z_s])
    add(Part("arm_shaft", "steel", cylinder(shaft_r, 0, shaft_end - shaft_x0), pose(ALONG_X, (shaft_x0, y_s, z_s))))

    pd = p.positive("arm_shaft", "pulley_pitch_diameter")
    big = revolve([(shaft_r, 0), (shaft_r + 5, 0), (shaft_r + 5, (pulley_w - 3) / 2), (pd / 2 - 4, (pulley_w - 3) / 2),
                   (pd / 2 - 4, 0), (pd / 2, 0), (pd / 2, pulley_w), (pd / 2 - 4, pulley_w),
                   (pd / 2 - 4, (pulley_w + 3) / 2), (shaft_r + 5, (pulley_w + 3) / 2), (shaft_r + 5, pulley_w),
                   (shaft_r, pulley_w)], SEGMENTS)
    add(Part("arm_pulley", "nylon", big, pose(ALONG_X, (arm_pulley_x, y_s, z_s))))
    tp_x = p("arm_shaft", "timing_pulley_x")
    tp_r = p.positive("arm_shaft", "timing_pulley_pitch_diameter") / 2
    add(Part("arm_timing_pulley", "aluminium", flanged_pulley(tp_r, shaft_r, 0.0, 8.0), pose(ALONG_X, (tp_x, y_s, z_s))))
    hw_x, hw_d, hw_w = p("arm_shaft", "handwheel_x"), p.positive("arm_shaft", "handwheel_diameter"), p.positive("arm_shaft", "handwheel_width")
    wheel = revolve([(shaft_r, 0), (shaft_r + 4, 0), (shaft_r + 4, hw_w - 3), (hw_d / 2 - 5, hw_w - 3), (hw_d / 2 - 5, 0),
                     (hw_d / 2, 0), (hw_d / 2, hw_w), (shaft_r, hw_w)], SEGMENTS)
    add(Part("handwheel", "abs", wheel, pose(ALONG_X, (hw_x, y_s, z_s))))
    if hw_x + hw_w < shaft_end:
        raise ParamError("arm_shaft.handwheel_end_x lies beyond the handwheel")

    link_x, link_t = p("link", "x"), p.positive("link", "thickness")
    pin_r = p.positive("crank", "pin_diameter") / 2
    disc_r = p.positive("crank", "disc_radius")
    cw_r, cw_angle = p.positive("crank", "counterweight_outer_radius"), p.positive("crank", "counterweight_angle")
    web = mf.CrossSection.batch_hull([circle(disc_r), circle(6.0, (0.0, r))])
    counterweight = sector(disc_r - 3.0, cw_r, -90 - cw_angle / 2, -90 + cw_angle / 2)
    pin_z0 = link_x - 0.5 - disc_x
    crank = union(
        slab(web + counterweight, 0.0, disc_t),
        cylinder(7.0, disc_t, disc_t + 8.0),
        cylinder(pin_r, pin_z0, 0.5, SMALL).translate((0.0, r, 0.0)),
    ) - cylinder(shaft_r, 1.0, disc_t + 9.0)
    pin_center_local = (0.0, r, link_x + link_t / 2 - disc_x)
    add(Part("needle_bar_crank", "steel", crank, pose(crank_rot, (disc_x, y_s, z_s)), {"crank_pin_center": pin_center_local}))
    for name in ("arm_pulley", "arm_timing_pulley", "handwheel", "needle_bar_crank"):
        weld("arm_shaft", name, (shaft_x0, y_s, z_s))
    joints.append(Joint("arm_shaft", "revolute", "bed_casting", "arm_shaft", np.array([shaft_x0, y_s, z_s]), X))

    # ---- crank link and the needle-bar assembly (at top dead centre)
    pin_tdc = arm_axis + crank_rot @ np.array([0.0, r, 0.0])
    small_end = np.array([link_x + link_t / 2, 0.0, lay.connector_tdc_z])
    big_end = np.array([link_x + link_t / 2, pin_tdc[1], pin_tdc[2]])
    L = p.positive("link", "length")
    sp_r = p.positive("link", "small_pin_diameter") / 2
    outline = union_2d(
        circle(p.positive("link", "big_end_diameter") / 2),
        circle(p.positive("link", "small_end_diameter") / 2, (0.0, L)),
        mf.CrossSection.square((p.positive("link", "web_width"), L)).translate((-p("link", "web_width") / 2, 0.0)),
    ) - circle(pin_r + 0.05, segments=SMALL) - circle(sp_r + 0.05, (0.0, L), SMALL)
    add(Part("crank_link", "steel", slab(outline, -link_t / 2, link_t / 2),
             pose(in_plane((small_end - big_end)[1:]), big_end)))
    joints.append(Joint("crank_pin", "revolute", "needle_bar_crank", "crank_link", big_end, X))

    bar_len = p.positive("needle_bar", "length")
    z_bb = lay.bar_bottom_tdc_z
    head_bottom = c["head_bottom_z"]
    clamp_h, clamp_ov = p.positive("needle_bar", "clamp_height"), p.positive("needle_bar", "clamp_overlap")
    con_h = p.positive("needle_bar", "connector_height")
    checks = {
        "the needle clamp at top dead centre must stay below the head": z_bb + clamp_ov < head_bottom - 0.5,
        "the needle-bar connector at bottom dead centre must stay inside the head":
            lay.connector_tdc_z - lay.stroke - con_h / 2 > head_bottom + wall + 0.5,
        "the needle-bar connector must lie on the needle bar":
            clamp_ov + con_h / 2 < lay.connector_tdc_z - z_bb < bar_len - con_h / 2,
        "the needle bar at top dead centre must stay below the head top": z_bb + bar_len < head_z1 - wall - 0.5,
    }
    for message, ok in checks.items():
        if not ok:
            raise ParamError(message)
    add(Part("needle_bar", "steel", cylinder(bar_r, 0.0, bar_len, SMALL), pose(np.eye(3), (0, 0, z_bb)), subsystem="NEEDLE_BAR"))
    con_r = p.positive("needle_bar", "connector_diameter") / 2
    stud_end = link_x + link_t + 0.3
    connector = union(
        tube(con_r, bar_r, -con_h / 2, con_h / 2, SMALL),
        cylinder(sp_r, 0.0, stud_end - (con_r - 0.5), SMALL).transform(pose(ALONG_X, (con_r - 0.5, 0.0, 0.0))[:3]),
    )
    add(Part("needle_bar_connector", "steel", connector, pose(np.eye(3), (0, 0, lay.connector_tdc_z)), subsystem="NEEDLE_BAR"))
    shank_r = p.positive("needle", "shank_diameter") / 2
    cw, cd = p.positive("needle_bar", "clamp_width"), p.positive("needle_bar", "clamp_depth")
    clamp = (box(-cw / 2, cw / 2, -cd / 2, cd / 2, clamp_ov - clamp_h, clamp_ov)
             - cylinder(bar_r, 0.0, clamp_ov + 1, SMALL)
             - cylinder(shank_r + 0.01, clamp_ov - clamp_h - 1, 0.0, SMALL)) \
        + cylinder(2.0, 0.0, 3.0, SMALL).transform(pose(ALONG_X, (-cw / 2 - 2.5, 0.0, (clamp_ov - clamp_h) / 2))[:3])
    add(Part("needle_clamp", "steel", clamp, pose(np.eye(3), (0, 0, z_bb)), subsystem="NEEDLE_BAR"))
    needle, needle_frames = build_needle(p)
    add(Part("needle", "steel", needle, pose(np.eye(3), (0, 0, lay.tip_tdc_z)), needle_frames, subsystem="NEEDLE_BAR"))
    for name in ("needle_bar_connector", "needle_clamp"):
        weld("needle_bar", name, (0, 0, z_bb))
    weld("needle_clamp", "needle", (0, 0, z_bb))
    joints.append(Joint("needle_bar_pin", "revolute", "crank_link", "needle_bar_connector", small_end, X))
    joints.append(Joint("needle_bar", "prismatic", "bed_casting", "needle_bar", np.array([0.0, 0.0, head_bottom]), Z))

    # ---- take-up lever and its link (four-bar on the same crank pin)
    P0 = pin_tdc[1:]
    Q0 = lay.take_up_pin_link
    lever_len, ratio = p("take_up", "lever_length"), p.positive("take_up", "eye_ratio")
    eye_local = (0.0, ratio * lever_len, 0.0)
    lever = union_2d(
        mf.CrossSection.batch_hull([circle(lever_w / 2 + 2.0, segments=SMALL), circle(lever_w / 2 + 1.0, (0, lever_len), SMALL)]),
        mf.CrossSection.batch_hull([circle(lever_w / 2 + 1.0, (0, lever_len), SMALL), circle(lever_w / 2, (0, ratio * lever_len), SMALL)]),
    ) - circle(pin_r + 0.05, segments=SMALL) - circle(1.55, (0, lever_len), SMALL) - circle(1.0, (0, ratio * lever_len), SMALL)
    lever_center_x = lever_x + lever_t / 2
    add(Part("take_up_lever", "steel", slab(lever, -lever_t / 2, lever_t / 2),
             pose(in_plane(Q0 - P0), (lever_center_x, P0[0], P0[1])), {"take_up_eye": eye_local}))
    link_w = p.positive("take_up", "link_width")
    link_len = p.positive("take_up", "link_length")
    tu_link = slab(mf.CrossSection.batch_hull([circle(link_w / 2 + 1.0, segments=SMALL), circle(link_w / 2 + 1.0, (0, link_len), SMALL)])
                   - circle(pivot_pin_r + 0.05, segments=SMALL), -tu_t / 2, tu_t / 2)
    tu_link = tu_link + cylinder(1.5, lever_x - 0.3 - (tu_x + tu_t / 2), 0.0, SMALL).translate((0.0, link_len, 0.0))
    add(Part("take_up_link", "steel", tu_link, pose(in_plane(Q0 - O), (tu_x + tu_t / 2, O[0], O[1]))))
    joints.append(Joint("take_up_crank_pin", "revolute", "needle_bar_crank", "take_up_lever",
                        np.array([lever_center_x, P0[0], P0[1]]), X))
    joints.append(Joint("take_up_pivot", "revolute", "bed_casting", "take_up_link", np.array([tu_x + tu_t / 2, O[0], O[1]]), X))
    joints.append(Joint("take_up_link_pin", "revolute", "take_up_link", "take_up_lever",
                        np.array([lever_center_x, Q0[0], Q0[1]]), X))

    # ---- lower shaft with its timing pulley and the hook-drive gear
    ls_z, ls_r = p("lower_shaft", "height"), p.positive("lower_shaft", "diameter") / 2
    ls_x0, ls_x1 = p("lower_shaft", "x_min"), p("lower_shaft", "x_max")
    ls_pose = pose(ALONG_X, (ls_x0, y_s, ls_z))
    add(Part("lower_shaft", "steel", cylinder(ls_r, 0.0, ls_x1 - ls_x0, SMALL), pose(ALONG_X, (ls_x0, y_s, ls_z))))
    g_len = p.positive("lower_shaft", "gear_length")
    add(Part("lower_shaft_gear", "steel", tube(lay.lower_gear_radius, ls_r, 0.0, g_len, SMALL),
             pose(ALONG_X, (lay.hook_axis[0] - g_len / 2, y_s, ls_z))))
    add(Part("lower_timing_pulley", "aluminium", flanged_pulley(tp_r, ls_r, 0.0, 8.0), pose(ALONG_X, (tp_x, y_s, ls_z))))
    for name in ("lower_shaft_gear", "lower_timing_pulley"):
        weld("lower_shaft", name, ls_pose[:3, 3])
    joints.append(Joint("lower_shaft", "revolute", "bed_casting", "lower_shaft", ls_pose[:3, 3].copy(), X))
    if abs(ls_z - lay.hook_rim_z) < p("hook", "height") + 6:
        raise ParamError("lower_shaft.height leaves no room for the hook gear under the hook")

    # ---- rotary hook (vertical axis) and its gear
    hook, hook_frames = build_hook(p, lay, ls_z)
    hook_origin = (lay.hook_axis[0], lay.hook_axis[1], lay.hook_rim_z)
    add(Part("hook", "steel", hook, pose(rot_z(lay.hook_assembly_deg), hook_origin), hook_frames))
    hg_r = p.positive("hook", "gear_pitch_diameter") / 2
    add(Part("hook_gear", "nylon", tube(hg_r, p("hook", "shaft_diameter") / 2, -3.0, 3.0, SMALL),
             pose(np.eye(3), (lay.hook_axis[0], lay.hook_axis[1], ls_z))))
    weld("hook", "hook_gear", hook_origin)
    joints.append(Joint("hook", "revolute", "bed_casting", "hook", np.array(hook_origin), Z))
    return parts, joints


def union_2d(*sections: mf.CrossSection) -> mf.CrossSection:
    return mf.CrossSection.batch_boolean(list(sections), mf.OpType.Add)


def flanged_pulley(pitch_r: float, bore_r: float, z0: float, width: float) -> mf.Manifold:
    f = 0.8
    return revolve([(bore_r, z0), (pitch_r + 1.5, z0), (pitch_r + 1.5, z0 + f), (pitch_r, z0 + f), (pitch_r, z0 + width - f),
                    (pitch_r + 1.5, z0 + width - f), (pitch_r + 1.5, z0 + width), (bore_r, z0 + width)], SEGMENTS)


def build_needle(p: Params) -> tuple[mf.Manifold, dict]:
    """Needle in its own frame: origin at the point, +z toward the butt, scarf and shank
    flat on the +y side (the back of the machine, where the hook point passes)."""
    n = {k: p("needle", k) for k in p.sections["needle"] if k not in ("system",)}
    length, r_b, r_s = n["length"], n["blade_diameter"] / 2, n["shank_diameter"] / 2
    if abs(n["size"] / 100 - n["blade_diameter"]) > 1e-9:
        raise ParamError("needle.blade_diameter must be needle.size / 100 mm (NM size)")
    z_shank = length - n["shank_length"]
    z_blade_top = z_shank - n["shoulder_length"]
    if not 0 < n["point_length"] < n["eye_bottom_above_tip"] < z_blade_top - 3:
        raise ParamError("needle: point, eye and blade lengths do not fit the needle length")
    body = revolve([(0.0, 0.0), (r_b, n["point_length"]), (r_b, z_blade_top), (r_s, z_shank), (r_s, length - 0.4),
                    (r_s - 0.4, length), (0.0, length)], 16)
    eye0, eye1 = n["eye_bottom_above_tip"], n["eye_bottom_above_tip"] + n["eye_length"]
    scarf0 = eye1 + n["scarf_start_above_eye"]
    body = body - union(
        box(-n["eye_width"] / 2, n["eye_width"] / 2, -1.0, 1.0, eye0, eye1),
        box(-1.0, 1.0, r_b - n["scarf_depth"], 1.0, scarf0, scarf0 + n["scarf_length"]),
        box(-2.0, 2.0, r_s - n["shank_flat_depth"], 2.0, z_shank + 1.0, length + 1.0),
    )
    return body, {"needle_tip": (0.0, 0.0, 0.0), "needle_eye": (0.0, 0.0, (eye0 + eye1) / 2)}


def build_hook(p: Params, lay: Layout, lower_shaft_z: float) -> tuple[mf.Manifold, dict]:
    """Rotary hook in its own frame: origin on the axis at the rim top, the point at local
    angle 0 leading a counter-clockwise rotation (seen from above)."""
    h = {k: p("hook", k) for k in ("outer_diameter", "height", "floor_thickness", "point_radius", "point_below_rim",
                                   "shaft_diameter")}
    R_o, R_p = h["outer_diameter"] / 2, h["point_radius"]
    R_i = R_p + 0.6
    if not R_i < R_o - 0.5:
        raise ParamError("hook.point_radius leaves no wall inside hook.outer_diameter")
    H, t = h["height"], h["floor_thickness"]
    shaft_r = h["shaft_diameter"] / 2
    shaft_bottom = lower_shaft_z - 4.0 - lay.hook_rim_z
    cup = revolve([(0.0, shaft_bottom), (shaft_r, shaft_bottom), (shaft_r, -H - 3.0), (4.0, -H - 3.0), (4.0, -H),
                   (R_o, -H), (R_o, 0.0), (R_i, 0.0), (R_i, -H + t), (4.0, -H + t), (4.0, -H + t + 2.0), (0.0, -H + t + 2.0)],
                  SEGMENTS)
    throat = slab(sector(R_i - 1.0, R_o + 1.0, 0.0, 50.0, 12), -4.0, 1.0)
    z_tip = -h["point_below_rim"]
    # the beak: its inner edge spirals out from the point (radius R_p) to the wall, so
    # that only the point itself comes close to the needle
    inner = [(R_p + (R_i - R_p) * math.sqrt(a / -20.0), a) for a in np.linspace(0.0, -20.0, 11)]
    outer = [(R_i + 0.2, a) for a in np.linspace(-20.0, -6.0, 8)]
    outline = np.array([(r * math.cos(math.radians(a)), r * math.sin(math.radians(a))) for r, a in inner + outer])
    beak = slab(mf.CrossSection([outline]), z_tip - 0.4, z_tip + 0.4)
    return (cup - throat) + beak, {"hook_point": (R_p, 0.0, z_tip)}


# --------------------------------------------------------------------------- export

@dataclass
class MassProperties:
    mass: float  # g
    com: np.ndarray  # part frame, mm
    inertia: np.ndarray  # g*mm^2 about the com, part axes
    volume: float
    area: float


def stl_mesh(solid: mf.Manifold) -> trimesh.Trimesh:
    """The solid as it is stored in its STL (float32 vertices)."""
    mesh = solid.to_mesh64()
    vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3].astype(np.float32).astype(np.float64)
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def mass_properties(mesh: trimesh.Trimesh, density_g_mm3: float, name: str) -> MassProperties:
    if not (mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0):
        raise ParamError(f"part {name}: the solid is not a closed, consistently oriented volume")
    props = mesh.mass_properties
    mass = props["volume"] * density_g_mm3
    return MassProperties(mass=float(mass), com=np.asarray(props["center_mass"], float),
                          inertia=np.asarray(props["inertia"], float) * density_g_mm3, volume=float(props["volume"]),
                          area=float(mesh.area))


def binary_stl(mesh: trimesh.Trimesh, title: str) -> bytes:
    triangles = mesh.vertices[mesh.faces].astype(np.float32)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]).astype(np.float64)
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = (normals / np.where(lengths > 0, lengths, 1.0)).astype(np.float32)
    record = np.zeros(len(triangles), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    record["n"], record["v"] = normals, triangles
    header = title.encode("ascii")[:80].ljust(80, b" ")
    return header + struct.pack("<I", len(triangles)) + record.tobytes()


def build_export(p: Params):
    """Everything the export contains: (firstgen.Export, {file: bytes}, couplings, parts, joints, layout)."""
    lay = compute_layout(p)
    parts, joints = build_parts(p, lay)
    files: dict[str, bytes] = {}
    by_name = {part.name: part for part in parts}
    bodies: dict[str, firstgen.Body] = {}
    next_ref = iter(range(1, 10_000))
    user_id = iter(range(5001, 10_000))
    node_ids = {}
    top_index, sub_index = 100, {"MOTOR_ROTOR": 300, "NEEDLE_BAR": 400}
    for part in parts:
        if part.subsystem:
            sub_index[part.subsystem] += 1
            node_ids[part.name] = f"{sub_index[part.subsystem] // 100 * 100}/{sub_index[part.subsystem]}"
        else:
            top_index += 1
            node_ids[part.name] = str(top_index)

    masses = {}
    for part in parts:
        density_key, color = MATERIALS[part.material]
        mesh = stl_mesh(part.solid)
        props = mass_properties(mesh, p.density(density_key), part.name)
        masses[part.name] = props
        stl_name = f"{part.name}_prt.stl"
        files[stl_name] = binary_stl(mesh, f"{part.name} mm mechanism assets/cad/sapphire870/generate.py")
        R, t = part.pose[:3, :3], part.pose[:3, 3]
        nid = node_ids[part.name]
        frames = [firstgen.Frame("CG", f"{nid}::CG(AUTOGEN)", R @ props.com + t, R),
                  firstgen.Frame("CS1", f"{nid}::CS1(AUTOGEN)", t, R)]
        for frame_name, local in part.frames.items():
            frames.append(firstgen.Frame(f"CS{len(frames)}", f"{next(user_id)}(USERADDED)", R @ np.asarray(local, float) + t,
                                         R, display_name=frame_name))
        bodies[part.name] = firstgen.Body(part.name, nid, props.mass, props.inertia, props.volume, props.area, frames,
                                          stl_name, color)

    def port(body: firstgen.Body, point, joint_node: str) -> int:
        ref = next(next_ref)
        body.frames.append(firstgen.Frame(f"CS{len(body.frames)}", f"{joint_node}::{body.node_id}(AUTOGEN)",
                                          np.asarray(point, float), np.eye(3), ref=ref))
        return ref

    top_joints, sub_joints = [], {name: [] for name in sub_index}
    for joint in joints:
        base, follower = bodies[joint.base], bodies[joint.follower]
        node = f"{follower.node_id}:-:{base.node_id}"
        fj = firstgen.Joint(joint.name, node, port(base, joint.point, node), port(follower, joint.point, node),
                            joint.kind, joint.axis)
        sb, sf = by_name[joint.base].subsystem, by_name[joint.follower].subsystem
        (sub_joints[sb] if sb and sb == sf else top_joints).append(fj)

    # zero-mass RootParts as the exporter writes them: one for the assembly (welded to the
    # ground and to the bed casting) and one per sub-assembly (welded to its first part)
    total_mass = sum(m.mass for m in masses.values())
    assembly_cg = sum(m.mass * (by_name[n].pose[:3, :3] @ m.com + by_name[n].pose[:3, 3]) for n, m in masses.items()) / total_mass

    def root_part(prefix: str, first: firstgen.Body, cg) -> tuple[firstgen.Body, firstgen.Joint]:
        root = firstgen.Body("RootPart", f"{prefix}RootPart", 0.0, np.zeros(9), 0.0, 0.0,
                             [firstgen.Frame("CG", f"{prefix}RootPart::CG(AUTOGEN)", cg, np.eye(3)),
                              firstgen.Frame("CS1", f"{prefix}RootPart::CS1(AUTOGEN)", np.zeros(3), np.eye(3))])
        node = f"{first.node_id}:-:{prefix}RootPart"
        point = first.frames[0].position
        joint = firstgen.Joint(f"RootPart--{first.name}", node, port(root, point, node), port(first, point, node), "weld",
                               firstgen.WELD_AXIS)
        return root, joint

    ground_ref = next(next_ref)
    top_root, top_root_joint = root_part(f"{EXPORT_NAME.upper()}/", bodies["bed_casting"], assembly_cg)
    root_ground_ref = port(top_root, assembly_cg, f"{EXPORT_NAME.upper()}/RootPart:-:RootGround")
    ground = firstgen.Ground("RootGround", firstgen.Frame(
        "CS1", f"{EXPORT_NAME.upper()}/RootPart:-:RootGround::RootGround(AUTOGEN)", assembly_cg, np.eye(3), ref=ground_ref))
    top_joints = [top_root_joint] + top_joints + [firstgen.Joint(
        "RootGround--RootPart", f"{EXPORT_NAME.upper()}/RootPart:-:RootGround", ground_ref, root_ground_ref, "weld",
        firstgen.WELD_AXIS)]

    subsystems = []
    for name, base in sub_index.items():
        members = [bodies[part.name] for part in parts if part.subsystem == name]
        sub_mass = sum(masses[b.name].mass for b in members)
        sub_cg = sum(masses[b.name].mass * b.frames[0].position for b in members) / sub_mass
        prefix = f"{base}/"
        root, root_joint = root_part(prefix, members[0], sub_cg)
        subsystems.append(firstgen.Subsystem(name, str(base), [root] + members, [root_joint] + sub_joints[name]))

    export = firstgen.Export(
        name=EXPORT_NAME.upper(),
        created_using="mechanism assets/cad/sapphire870/generate.py (first-generation SimMechanics XML writer)",
        created_from=p.path.name,
        created_on=str(p.raw("export", "created_on")),
        created_by=str(p.raw("export", "created_by")),
        bodies=[top_root] + [bodies[part.name] for part in parts if not part.subsystem],
        joints=top_joints,
        grounds=[ground],
        subsystems=subsystems,
    )
    couplings = {
        "format": "mechanism-couplings/1",
        "couplings": [
            {"name": "motor_belt", "kind": "belt", "input": "motor", "output": "arm_shaft",
             "ratio": p("arm_shaft", "pulley_pitch_diameter") / p("motor", "pulley_pitch_diameter")},
            {"name": "lower_belt", "kind": "belt", "input": "arm_shaft", "output": "lower_shaft",
             "ratio": p("arm_shaft", "timing_pulley_pitch_diameter") / p("arm_shaft", "timing_pulley_pitch_diameter")},
            {"name": "hook_worm_gear", "kind": "worm_gear", "input": "lower_shaft", "output": "hook",
             "ratio": p("hook", "gear_teeth") / p("hook", "lower_gear_teeth")},
        ],
    }
    if abs(couplings["couplings"][2]["ratio"] * p("hook", "turns_per_arm_turn") - 1.0) > 1e-12:
        raise ParamError("hook.gear_teeth / hook.lower_gear_teeth must equal 1 / hook.turns_per_arm_turn")
    return export, files, couplings, parts, joints, lay, masses


def write_export(p: Params, out_dir: Path) -> dict:
    export, files, couplings, parts, joints, lay, masses = build_export(p)
    files[f"{EXPORT_NAME}.xml"] = firstgen.render(export).encode("ascii")
    files[f"{EXPORT_NAME}.couplings.json"] = (json.dumps(couplings, indent=2) + "\n").encode("ascii")
    with atomic_dir(out_dir) as tmp:
        for name, data in sorted(files.items()):
            (tmp / name).write_bytes(data)
    return {"layout": lay, "masses": masses, "parts": parts, "files": sorted(files)}


def summary(p: Params, result: dict) -> list[str]:
    lay, masses = result["layout"], result["masses"]
    fixed = {"bed_casting", "needle_plate", "motor_housing"}
    moving = sum(m.mass for n, m in masses.items() if n not in fixed)
    rotor = [n for n in masses if n.startswith("motor_") and n != "motor_housing"]
    rotor_inertia = 0.0
    for name in rotor:
        props = masses[name]
        rotor_inertia += (props.inertia[2, 2] + props.mass * (props.com[0] ** 2 + props.com[1] ** 2)) * 1e-9
    return [
        f"stroke {lay.stroke:.3f} mm, needle point {lay.tip_tdc_z:.3f} mm above the plate at TDC, {lay.tip_bdc_z:.3f} mm at BDC",
        f"hook point passes the needle at arm angle {lay.passage_arm_deg:.2f} deg (needle {p('hook', 'needle_rise_at_passage'):g} mm above BDC)",
        f"moving mass {moving:.1f} g; motor rotor inertia {rotor_inertia:.3e} kg m^2 (thesis {p('motor', 'inertia_target'):.2e})",
        f"{len(result['parts'])} parts, {len(result['files'])} files",
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--params", type=Path, default=DEFAULT_PARAMS, help="parameter file (JSON, see assets/cad/sapphire870/README.md)")
    parser.add_argument("-o", "--out", type=Path, default=DEFAULT_OUT, help="output folder for the export (replaced atomically)")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    args = parser.parse_args(argv)
    try:
        params = Params.load(args.params)
        result = write_export(params, args.out)
    except ParamError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    if not args.quiet:
        print(f"wrote {args.out}")
        for line in summary(params, result):
            print(f"  {line}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
