#!/usr/bin/env python3
"""Generate the bench punch press's CAD export from one parameter file.

    python assets/cad/press/generate.py [--params FILE] [-o DIR]

writes, into DIR (default ``assets/cad/press/export``):

* ``press.xml``: a second-generation ``SimscapeMultibodyImportXML`` 2.0 export as Simscape
  Multibody Link writes it from a SolidWorks assembly: no joints, the assembly's mates
  (``Concentric``, ``Coincident``) between part geometry, and the worm-gear mate as a
  ``WormAndGearConstraint`` with the tooth counts; instances named as SolidWorks names
  components (``CRANKSHAFT-1``), numbers in inches and pounds (``DataUnits``);
* one binary STL per part, in inches, in the part's own frame (``<PART>.STL``).

The converter finds the joints from the mates (named ``<base>--<follower>``, e.g.
``BASE_FRAME-1--CRANKSHAFT-1``) and turns the worm gear into a 20:1 joint coupling.

Solids are manifold3d booleans; mass, centre of mass and inertia come from the solid as
stored in its STL and the material density. The output is deterministic byte for byte.
Assembly pose: crank angle 0 = crank pin straight up = ram at top dead centre.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import manifold3d as mf
import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent.parent
sys.path.insert(0, str(REPO))
from mechanism.files.outputs import atomic_dir  # noqa: E402  (the project's own atomic folder replace)


def _sewing_generator():
    """The sewing machine's generator: its solid, STL and mass-property helpers are shared."""
    spec = importlib.util.spec_from_file_location("sewing_machine_generator", HERE.parent / "sapphire870" / "generate.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


shapes = _sewing_generator()
ParamError = shapes.ParamError
box, cylinder, union = shapes.box, shapes.cylinder, shapes.union

DEFAULT_PARAMS = HERE / "press.params.json"
DEFAULT_OUT = HERE / "export"
EXPORT_NAME = "press"
PARAMS_FORMAT = "mechanism-cad-params/1"
INCH = 0.0254  # m
POUND = 0.45359237  # kg
SEGMENTS = 48

# unit -> what the value must be (numbers in the design unit; strings for the header)
UNITS = {"in": "length", "kg/m^3": "density", "1": "count", "-": "text", "V": "datasheet", "ohm": "datasheet",
         "N*m/A": "datasheet", "V*s/rad": "datasheet", "N*m": "datasheet", "N*m*s/rad": "datasheet"}


# --------------------------------------------------------------------------- parameters

class Params(shapes.Params):
    """``section -> name -> {value, unit, source}``; lengths in inches (the CAD document's unit).
    ``Params.load(path)`` reads the file as the sewing machine's parameters are read."""

    def __init__(self, data: dict, path: Path):  # the press's own units and keys
        if not isinstance(data, dict) or data.get("format") != PARAMS_FORMAT:
            raise ParamError(f"{path}: 'format' must be {PARAMS_FORMAT!r}")
        self.path = Path(path)
        self.entries = {f"{s}.{n}": e for s, v in data.items() if isinstance(v, dict) for n, e in v.items()}
        for key, entry in self.entries.items():
            if not isinstance(entry, dict) or not {"value", "unit", "source"} <= set(entry) or not str(entry["source"]).strip():
                raise ParamError(f"{path}: {key} needs a value, a unit and a source")
            if entry["unit"] not in UNITS:
                raise ParamError(f"{path}: {key}: unit {entry['unit']!r} is not one of {sorted(UNITS)}")

    def text(self, key: str) -> str:
        return str(self._entry(key)["value"])

    def _entry(self, key: str) -> dict:
        if key not in self.entries:
            raise ParamError(f"{self.path}: missing parameter {key}")
        return self.entries[key]

    def __call__(self, key: str) -> float:
        value = self._entry(key)["value"]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ParamError(f"{self.path}: {key} must be a finite number")
        return float(value)

    def positive(self, key: str) -> float:
        value = self(key)
        if value <= 0:
            raise ParamError(f"{self.path}: {key} must be positive (is {value:g})")
        return value


# --------------------------------------------------------------------------- geometry

# part z along world +x (parts turning on the crankshaft), part y along world +z
ALONG_X = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
# part z along world +y (the motor rotor and housing), part x along world +x
ALONG_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
# the rod: part z along world +x, part y from the big eye to the small eye (world -z at TDC)
ROD_AXES = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
TURN_Z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 deg about z (the die plate)
X, Y, Z = np.eye(3)
GROUNDED = ' grounded="true"'


def cylinder_x(radius: float, x0: float, x1: float, y: float = 0.0, z: float = 0.0) -> mf.Manifold:
    """A cylinder along world x (for the frame's bores)."""
    return cylinder(radius, x0, x1, SEGMENTS).rotate((0.0, 90.0, 0.0)).translate((0.0, y, z))


@dataclass
class Part:
    name: str  # the part document (``CRANKSHAFT``); its instance is ``CRANKSHAFT-1``
    material: str
    solid: mf.Manifold  # in the part frame, inches
    rotation: np.ndarray  # part -> world at the assembly pose
    origin: np.ndarray  # world, inches
    grounded: bool = False
    color: tuple = (0.7, 0.7, 0.7)

    @property
    def instance(self) -> str:
        return f"{self.name}-1"

    def local(self, point) -> np.ndarray:
        return self.rotation.T @ (np.asarray(point, float) - self.origin)


@dataclass
class Layout:
    """Derived dimensions (inches)."""

    crank_z: float  # crank axis height above the die-plate top
    tip_tdc_z: float
    tip_bdc_z: float
    worm_z: float
    worm_x: float
    ratio: float  # motor turns per crank turn


def layout(p: Params) -> Layout:
    r, l = p.positive("crank.radius"), p.positive("rod.length")
    if l <= r:
        raise ParamError(f"{p.path}: rod.length must exceed crank.radius (the crank could not turn)")
    crank_z = p("ram.tip_clearance") + r + l + p.positive("ram.pin_height")
    wheel = p.positive("worm_gear.wheel_pitch_radius")
    teeth, starts = p.positive("worm_gear.wheel_teeth"), p.positive("worm_gear.worm_starts")
    if teeth != round(teeth) or starts != round(starts):
        raise ParamError(f"{p.path}: worm_gear.wheel_teeth and worm_gear.worm_starts must be whole numbers")
    return Layout(crank_z=crank_z, tip_tdc_z=crank_z + r - l - p("ram.pin_height"),
                  tip_bdc_z=crank_z - r - l - p("ram.pin_height"),
                  worm_z=crank_z + wheel + p.positive("worm_gear.worm_pitch_radius") + p.positive("fits.running_clearance"),
                  worm_x=p("worm_gear.wheel_x0") + 0.5 * p.positive("worm_gear.wheel_width"), ratio=teeth / starts)


def frame_solid(p: Params, lay: Layout) -> mf.Manifold:
    """The C-frame in world coordinates: bed, column, bearing housing with its arm, ram guide."""
    zc, head = lay.crank_z, p.positive("frame.head_half_height")
    bx, top = p.positive("frame.bed_x"), zc + head
    c = p.positive("fits.running_clearance")
    x_disc, x_bearing = p("crank.disc_x1") + c, p("frame.bearing_x1")
    cx0, cx1, cy0 = p("frame.column_x0"), p("frame.column_x1"), p("frame.column_y0")
    g0, g1, gw = p("frame.guide_z0"), p("frame.guide_z1"), p.positive("frame.guide_half_width")
    ram_r, flat_y = p.positive("ram.radius"), p("ram.flat_y")
    plate = p.positive("die_plate.thickness")
    bed = box(-bx, bx, p("frame.bed_y0"), p("frame.bed_y1"), -plate - p.positive("frame.bed_thickness"), -plate)
    column = box(cx0, cx1, cy0, p("frame.bed_y1"), -plate, top)
    bearing = box(x_disc, x_bearing, -head, head, zc - head, top)
    bearing_arm = box(x_disc, cx1, head, cy0, zc - head, top)
    guide = box(-gw, gw, -gw, gw, g0, g1)
    guide_arm = box(-0.75 * gw, 0.75 * gw, gw, cy0, g0, g1)
    key = box(-0.6 * ram_r, 0.6 * ram_r, flat_y + c, ram_r + c, g0, g1)  # fills the ram's flat: no turning
    bore = cylinder_x(p.positive("crank.shaft_radius") + c, x_disc - 0.1, x_bearing + 0.1, z=zc)
    ram_bore = cylinder(ram_r + c, g0 - 0.1, g1 + 0.1, SEGMENTS)
    dowel_r, dowel = p.positive("frame.dowel_radius"), p.positive("frame.dowel_offset")
    dowels = union(*(cylinder(dowel_r, -plate - 0.5, -plate + 0.1, 24).translate((0.0, s * dowel, 0.0)) for s in (-1, 1)))
    return union(bed, column, bearing, bearing_arm, guide - ram_bore, guide_arm) + key - bore - dowels


def build_parts(p: Params, lay: Layout) -> list[Part]:
    zc = lay.crank_z
    r, l = p("crank.radius"), p("rod.length")
    shaft_r = p.positive("crank.shaft_radius")
    disc0, disc1 = p("crank.disc_x0"), p("crank.disc_x1")
    crankshaft = union(
        cylinder(p.positive("crank.disc_radius"), disc0, disc1, SEGMENTS),
        cylinder(shaft_r, disc1, p("crank.shaft_x1"), SEGMENTS),
        cylinder(p.positive("crank.collar_radius"), p("crank.collar_x0"), p("worm_gear.wheel_x0"), SEGMENTS),
        cylinder(p.positive("crank.pin_radius"), p("crank.pin_x0"), disc0, 32).translate((0.0, r, 0.0)))
    wheel_w = p.positive("worm_gear.wheel_width")
    wheel = shapes.tube(p.positive("worm_gear.wheel_pitch_radius"), p.positive("worm_gear.wheel_bore_radius"), 0.0, wheel_w,
                        SEGMENTS)
    half = 0.5 * p.positive("rod.thickness")
    big, small = p.positive("rod.big_eye_radius"), p.positive("rod.small_eye_radius")
    web_w, web_t = 0.5 * p.positive("rod.web_width"), 0.5 * p.positive("rod.web_thickness")
    c = p.positive("fits.running_clearance")  # bores, faces and the worm mesh run with this gap
    rod = union(shapes.tube(big, p("crank.pin_radius") + c, c - half, half - c, SEGMENTS),
                shapes.tube(small, p("ram.pin_radius") + c, c - half, half - c, 32).translate((0.0, l, 0.0)),
                box(-web_w, web_w, 0.8 * big, l - 0.8 * small, -web_t, web_t)
                - cylinder(p("crank.pin_radius") + c, -1, 1, SEGMENTS) - cylinder(p("ram.pin_radius") + c, -1, 1, 32).translate((0.0, l, 0.0)))
    ram_r, ram_len, pin_h = p.positive("ram.radius"), p.positive("ram.length"), p.positive("ram.pin_height")
    nose = p.positive("ram.nose_length")
    ram = (union(cylinder(p.positive("ram.nose_radius"), 0.0, nose, 32), cylinder(ram_r, nose, ram_len, SEGMENTS))
           - box(-half, half, -ram_r - 0.1, ram_r + 0.1, p("ram.slot_bottom"), ram_len + 0.1)
           - box(-ram_r - 0.1, ram_r + 0.1, p("ram.flat_y"), ram_r + 0.1, nose, ram_len + 0.1))
    ram = ram + cylinder_x(p.positive("ram.pin_radius"), -0.9 * ram_r, 0.9 * ram_r, z=pin_h)
    plate = box(-p.positive("die_plate.half_length"), p("die_plate.half_length"), -p.positive("die_plate.half_width"),
                p("die_plate.half_width"), 0.0, p.positive("die_plate.thickness"))
    dowel = p("frame.dowel_offset")
    plate = plate - union(*(cylinder(p("frame.dowel_radius"), -0.1, 1.0, 24).translate((s * dowel, 0.0, 0.0)) for s in (-1, 1)))
    shaft = union(cylinder(p.positive("motor.shaft_radius"), p("motor.shaft_y0"), p("motor.shaft_y1"), 32),
                  cylinder(p.positive("worm_gear.worm_pitch_radius"), -p.positive("worm_gear.worm_half_length"),
                           p("worm_gear.worm_half_length"), 32),
                  cylinder(p.positive("motor.collar_radius"), p("motor.housing_y0") + p("motor.cap_thickness") + c,
                           p("motor.housing_y0") + p("motor.cap_thickness") + c + p.positive("motor.collar_length"), 32),
                  cylinder(p.positive("motor.armature_radius"), p("motor.armature_y0"),
                           p("motor.armature_y0") + p.positive("motor.armature_length"), SEGMENTS))
    y0, y1, cap = p("motor.housing_y0"), p("motor.housing_y1"), p.positive("motor.cap_thickness")
    housing = (cylinder(p.positive("motor.housing_outer_radius"), y0, y1, SEGMENTS)
               - cylinder(p.positive("motor.housing_inner_radius"), y0 + cap, y1 - cap, SEGMENTS)
               - cylinder(p("motor.shaft_radius") + c, y0 - 0.1, y1 + 0.1, 32))
    worm_axis = np.array([lay.worm_x, 0.0, lay.worm_z])
    tdc_tip = np.array([0.0, 0.0, lay.tip_tdc_z])
    return [
        Part("BASE_FRAME", "cast_iron", frame_solid(p, lay), np.eye(3), np.zeros(3), grounded=True, color=(0.25, 0.4, 0.3)),
        Part("DIE_PLATE", "steel", plate, TURN_Z, np.array([0.0, 0.0, -p("die_plate.thickness")]), color=(0.5, 0.5, 0.55)),
        Part("MOTOR_HOUSING", "aluminium", housing, ALONG_Y, worm_axis, grounded=True, color=(0.15, 0.15, 0.2)),
        Part("MOTOR_ROTOR", "steel", shaft, ALONG_Y, worm_axis, color=(0.75, 0.55, 0.3)),
        Part("CRANKSHAFT", "steel", crankshaft, ALONG_X, np.array([0.0, 0.0, zc]), color=(0.7, 0.7, 0.72)),
        Part("WORM_WHEEL", "bronze", wheel, ALONG_X, np.array([p("worm_gear.wheel_x0"), 0.0, zc]), color=(0.8, 0.6, 0.25)),
        Part("CONNECTING_ROD", "steel", rod, ROD_AXES, np.array([0.0, 0.0, zc + r]), color=(0.6, 0.62, 0.65)),
        Part("RAM", "steel", ram, np.eye(3), tdc_tip, color=(0.78, 0.78, 0.8)),
    ]


# --------------------------------------------------------------------------- mates

@dataclass
class Side:
    shape: str  # geomType: plane, cylinder
    part: Part
    point: np.ndarray  # world, inches
    axis: np.ndarray  # world: plane normal or cylinder axis


def mates(p: Params, lay: Layout, parts: dict[str, Part]) -> list[tuple[str, str, Side, Side]]:
    """The assembly's mates as SolidWorks numbers them: (tag, name, first side, second side)."""
    zc, r, l = lay.crank_z, p("crank.radius"), p("rod.length")
    frame, plate, housing, rotor = parts["BASE_FRAME"], parts["DIE_PLATE"], parts["MOTOR_HOUSING"], parts["MOTOR_ROTOR"]
    crank, wheel, rod, ram = parts["CRANKSHAFT"], parts["WORM_WHEEL"], parts["CONNECTING_ROD"], parts["RAM"]
    axis = np.array([0.0, 0.0, zc])
    pin = np.array([0.0, 0.0, zc + r])
    wrist = np.array([0.0, 0.0, zc + r - l])
    worm = np.array([lay.worm_x, 0.0, lay.worm_z])
    bed_top = -p("die_plate.thickness")
    dowel = p("frame.dowel_offset")
    half = 0.5 * p("rod.thickness")
    cap_face = worm + (p("motor.housing_y0") + p("motor.cap_thickness")) * Y
    flat = np.array([0.0, p("ram.flat_y"), lay.tip_tdc_z + 1.0])
    return [
        ("Coincident", "Coincident1", Side("plane", frame, [0, 0, bed_top], Z), Side("plane", plate, [0, 0, bed_top], -Z)),
        ("Concentric", "Concentric1", Side("cylinder", frame, [0, -dowel, bed_top], Z), Side("cylinder", plate, [0, -dowel, bed_top], Z)),
        ("Concentric", "Concentric2", Side("cylinder", frame, [0, dowel, bed_top], Z), Side("cylinder", plate, [0, dowel, bed_top], Z)),
        ("Concentric", "Concentric3", Side("cylinder", housing, cap_face, Y), Side("cylinder", rotor, cap_face, Y)),
        ("Coincident", "Coincident2", Side("plane", housing, cap_face, Y), Side("plane", rotor, cap_face, -Y)),
        ("Concentric", "Concentric4", Side("cylinder", frame, axis + p("crank.disc_x1") * X, X),
         Side("cylinder", crank, axis + p("crank.disc_x1") * X, X)),
        ("Coincident", "Coincident3", Side("plane", frame, axis + p("crank.disc_x1") * X, -X),
         Side("plane", crank, axis + p("crank.disc_x1") * X, X)),
        ("Concentric", "Concentric5", Side("cylinder", crank, axis + p("worm_gear.wheel_x0") * X, X),
         Side("cylinder", wheel, axis + p("worm_gear.wheel_x0") * X, X)),
        ("Coincident", "Coincident4", Side("plane", crank, axis + p("worm_gear.wheel_x0") * X, X),
         Side("plane", wheel, axis + p("worm_gear.wheel_x0") * X, -X)),
        ("Coincident", "Coincident5", Side("plane", crank, axis + p("worm_gear.wheel_x0") * X, Y),  # the key
         Side("plane", wheel, axis + p("worm_gear.wheel_x0") * X, Y)),
        ("Concentric", "Concentric6", Side("cylinder", crank, pin, X), Side("cylinder", rod, pin, X)),
        ("Coincident", "Coincident6", Side("plane", crank, pin + half * X, -X), Side("plane", rod, pin + half * X, X)),
        ("Concentric", "Concentric7", Side("cylinder", rod, wrist, X), Side("cylinder", ram, wrist, X)),
        ("Coincident", "Coincident7", Side("plane", rod, wrist - half * X, -X), Side("plane", ram, wrist - half * X, X)),
        ("Concentric", "Concentric8", Side("cylinder", frame, [0, 0, p("frame.guide_z0")], Z),
         Side("cylinder", ram, [0, 0, p("frame.guide_z0")], Z)),
        ("Coincident", "Coincident8", Side("plane", frame, flat, -Y), Side("plane", ram, flat, Y)),
    ]


# --------------------------------------------------------------------------- XML

def numbers(values, decimals: int = 9) -> str:
    """Fixed decimals as Simscape Multibody Link prints them (no negative zero)."""
    return " ".join(f"{0.0 if abs(v) < 0.5 * 10.0**-decimals else v:.{decimals}f}" for v in np.ravel(values))


def transform_xml(rotation: np.ndarray, origin: np.ndarray, indent: str) -> str:
    return (f"{indent}<Transform>\n{indent}   <Rotation>{numbers(rotation)}</Rotation>\n"  # row by row: child -> parent
            f"{indent}   <Translation>{numbers(origin)}</Translation>\n{indent}</Transform>\n")


def geometry_xml(side: Side, indent: str) -> str:
    part = side.part
    return (f'{indent}<ConstraintGeometry geomType="{side.shape}">\n'
            f"{indent}   <InstancePath>\n{indent}      <Uid>{part.instance}</Uid>\n{indent}   </InstancePath>\n"
            f"{indent}   <Position>{numbers(part.local(side.point))}</Position>\n"
            f"{indent}   <Axis>{numbers(part.rotation.T @ np.asarray(side.axis, float))}</Axis>\n"
            f"{indent}</ConstraintGeometry>\n")


def part_xml(part: Part, props, stl: str) -> str:
    t = props.inertia  # lbm*in^2 about the centre of mass, part axes (tensor entries)
    inertia = [t[0, 0], t[1, 1], t[2, 2], t[1, 2], t[2, 0], t[0, 1]]
    r, g, b = part.color
    colour = f'a="1.000000000" b="{b:.9f}" g="{g:.9f}" r="{r:.9f}"'
    return (f'      <Part name="{part.name}" uid="{part.name}.SLDPRT">\n'
            f'         <ModelUnits length="inch" mass="pound"/>\n'
            f"         <MassProperties>\n            <Mass>{numbers([props.mass])}</Mass>\n"
            f"            <CenterOfMass>{numbers(props.com)}</CenterOfMass>\n"
            f"            <Inertia>{numbers(inertia)}</Inertia>\n         </MassProperties>\n"
            f'         <GeometryFile name="{stl}" type="STL"/>\n'
            f"         <VisualProperties>\n            <Ambient {colour}/>\n            <Diffuse {colour}/>\n"
            f'            <Specular a="1" b="0.2" g="0.2" r="0.2"/>\n            <Emissive a="1" b="0" g="0" r="0"/>\n'
            f"         </VisualProperties>\n      </Part>\n")


def export_xml(p: Params, lay: Layout, parts: list[Part], masses: dict, stls: dict) -> str:
    by_name = {part.name: part for part in parts}
    instances = "".join(
        f'         <Instance entityUid="{part.name}.SLDPRT" name="{part.instance}" uid="{part.instance}"'
        f'{GROUNDED if part.grounded else ""}>\n'
        f"{transform_xml(part.rotation, part.origin, ' ' * 12)}         </Instance>\n" for part in parts)
    constraints = "".join(f'         <{tag} name="{name}">\n{geometry_xml(a, " " * 12)}{geometry_xml(b, " " * 12)}         </{tag}>\n'
                          for tag, name, a, b in mates(p, lay, by_name))
    worm = Side("cylinder", by_name["MOTOR_ROTOR"], [lay.worm_x, 0.0, lay.worm_z], Y)
    wheel = Side("cylinder", by_name["WORM_WHEEL"], [p("worm_gear.wheel_x0"), 0.0, lay.crank_z], X)
    # the worm is the base (input): motor turns = teeth / starts x crank turns
    constraints += (f'         <WormAndGearConstraint name="WormGear1">\n{geometry_xml(worm, " " * 12)}'
                    f'{geometry_xml(wheel, " " * 12)}'
                    f"            <BaseTeeth>{int(p('worm_gear.worm_starts'))}</BaseTeeth>\n"
                    f"            <FollowerTeeth>{int(p('worm_gear.wheel_teeth'))}</FollowerTeeth>\n"
                    f"         </WormAndGearConstraint>\n")
    parts_xml = "".join(part_xml(part, masses[part.name], stls[part.name]) for part in parts)
    return (f'<?xml version="1.0" encoding="utf-8"?>\n'
            f'<SimscapeMultibodyImportXML xmlns="urn:mathworks:SimscapeMultibody:import" '
            f'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" version="2.0">\n'
            f'   <Created by="{p.text("export.created_by")}" from="SolidWorks" on="{p.text("export.created_on")}" '
            f'using="mechanism assets/cad/press/generate.py (second-generation writer)"/>\n'
            f'   <ModelUnits length="inch" mass="pound"/>\n'
            f'   <DataUnits length="inch" mass="pound"/>\n'
            f'   <RootAssembly name="PRESS" uid="PRESS.SLDASM" version="{p.path.name}">\n'
            f"      <InstanceTree>\n{instances}      </InstanceTree>\n"
            f"      <Constraints>\n{constraints}      </Constraints>\n"
            f"   </RootAssembly>\n   <Assemblies/>\n   <Parts>\n{parts_xml}   </Parts>\n"
            f"</SimscapeMultibodyImportXML>\n")


def build_export(p: Params) -> tuple[dict[str, bytes], Layout, list[Part], dict]:
    lay = layout(p)
    parts = build_parts(p, lay)
    files, masses, stls = {}, {}, {}
    for part in parts:
        mesh = shapes.stl_mesh(part.solid)
        density_lbm_in3 = p.positive(f"materials.{part.material}") * INCH**3 / POUND
        masses[part.name] = shapes.mass_properties(mesh, density_lbm_in3, part.name)
        stls[part.name] = f"{part.name}.STL"
        files[stls[part.name]] = shapes.binary_stl(mesh, f"{part.name} inch mechanism assets/cad/press/generate.py")
    files[f"{EXPORT_NAME}.xml"] = export_xml(p, lay, parts, masses, stls).encode("ascii")
    return files, lay, parts, masses


def write_export(p: Params, out_dir: Path) -> dict:
    files, lay, parts, masses = build_export(p)
    with atomic_dir(out_dir) as tmp:
        for name, data in sorted(files.items()):
            (tmp / name).write_bytes(data)
    return {"layout": lay, "parts": parts, "masses": masses, "files": sorted(files)}


def steady_speed_rad_s(p: Params, ratio: float, voltage: float) -> float:
    """Crank speed where the motor torque through the gear meets the described friction."""
    R, kt, ke = p("datasheet.resistance_ohm"), p("datasheet.torque_constant_Nm_per_A"), p("datasheet.back_emf_V_s_per_rad")
    coulomb = p("datasheet.crank_coulomb_Nm") + ratio * p("datasheet.motor_coulomb_Nm")
    viscous = p("datasheet.crank_viscous_Nm_s_per_rad") + ratio**2 * p("datasheet.motor_viscous_Nm_s_per_rad")
    return (ratio * kt * voltage / R - coulomb) / (ratio**2 * kt * ke / R + viscous)


def summary(p: Params, result: dict) -> list[str]:
    lay, masses = result["layout"], result["masses"]
    rotor = masses["MOTOR_ROTOR"].inertia[2, 2] * POUND * INCH**2  # about its own axis (part z) through the centre
    total = sum(m.mass for m in masses.values()) * POUND
    speed = steady_speed_rad_s(p, lay.ratio, p("datasheet.voltage_V"))
    return [
        f"stroke {lay.tip_tdc_z - lay.tip_bdc_z:.4f} in ({(lay.tip_tdc_z - lay.tip_bdc_z) * 25.4:.2f} mm); ram tip "
        f"{lay.tip_tdc_z:.3f} in above the die plate at TDC, {lay.tip_bdc_z:.3f} in at BDC",
        f"worm gear {lay.ratio:g}:1; motor rotor {rotor:.4e} kg m^2, {rotor * lay.ratio**2:.4e} kg m^2 at the crank",
        f"total mass {total:.4f} kg; steady crank speed at {p('datasheet.voltage_V'):g} V: {speed:.3f} rad/s "
        f"({speed * 30 / math.pi:.1f} rpm)",
        f"{len(result['parts'])} parts, {len(result['files'])} files",
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for flags, options in (
            (("--params",), dict(type=Path, default=DEFAULT_PARAMS, help="parameter file (JSON, see the press README)")),
            (("-o", "--out"), dict(type=Path, default=DEFAULT_OUT, help="export folder (replaced atomically)")),
            (("-q", "--quiet"), dict(action="store_true", help="print nothing on success"))):
        parser.add_argument(*flags, **options)
    args = parser.parse_args(argv)
    try:
        params = Params.load(args.params)
        report = [f"wrote {args.out}"] + [f"  {line}" for line in summary(params, write_export(params, args.out))]
    except ParamError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not args.quiet:
        print("\n".join(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
