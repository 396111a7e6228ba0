#!/usr/bin/env python3
"""Generate the servo arm's CAD export from one parameter file.

    python assets/cad/servo_arm/generate.py [--params FILE] [-o DIR]

writes, into DIR (default ``assets/cad/servo_arm/export``):

* ``servo_arm.xml``: a second-generation ``SimscapeMultibodyImportXML`` 2.0 export as Simscape
  Multibody Link writes it from a SolidWorks assembly: no joints, the assembly's mates
  (``Concentric``, ``Coincident``) between part geometry, and the servo's gearbox as a
  ``GearConstraint`` with its ratio (the designer's gear mate between the motor rotor and the
  output horn of a purchased servo whose gear train is not modelled); instances named as
  SolidWorks names components (``SERVO_HORN-1``), numbers in millimetres and grams (an MMGS
  document, ``DataUnits``). The assembly is Y up, as SolidWorks' default front view draws it:
  the export carries the gravity vector (0, -9806.65, 0) mm/s^2;
* one binary STL per part, in millimetres, in the part's own frame (``<PART>.STL``).

The converter finds the joints from the mates (named ``<base>--<follower>``, e.g.
``SERVO_CASE-1--SERVO_HORN-1``) and turns the gear mate into a 200:1 joint coupling.

The mechanism: a geared hobby servo turns its horn (the crank of a four-bar); a coupler drives a
bell-crank arm pivoted on the frame (the rocker), whose beam carries a steel payload and, at its
tip, a hanging pendulum on a free pin (the passive joint). Every joint axis is along z, the
four-bar moves in the vertical x-y plane. Solids are manifold3d booleans; mass, centre of mass and
inertia come from the solid as stored in its STL and the material density. The output is
deterministic byte for byte. Assembly pose: horn straight up, the arm's beam horizontal, the
pendulum hanging.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
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


def _press_generator():
    """The press's generator: its solids, mass properties and gen-2 XML pieces are shared."""
    spec = importlib.util.spec_from_file_location("press_generator", HERE.parent / "press" / "generate.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


press = _press_generator()
shapes = press.shapes
ParamError = shapes.ParamError
box, cylinder, union, tube = shapes.box, shapes.cylinder, shapes.union, shapes.tube
Part, Side = press.Part, press.Side
numbers, transform_xml, geometry_xml = press.numbers, press.transform_xml, press.geometry_xml

DEFAULT_PARAMS = HERE / "servo_arm.params.json"
DEFAULT_OUT = HERE / "export"
EXPORT_NAME = "servo_arm"
PARAMS_FORMAT = "mechanism-cad-params/1"
SEGMENTS = 48
SMALL = 24
GRAVITY_MM_S2 = 9806.65
X, Y, Z = np.eye(3)
GROUNDED = ' grounded="true"'

UNITS = {"mm": "length", "deg": "angle", "kg/m^3": "density", "1": "count", "-": "text", "V": "datasheet",
         "ohm": "datasheet", "N*m/A": "datasheet", "V*s/rad": "datasheet", "V/rad": "datasheet",
         "N*m": "datasheet", "N*m*s/rad": "datasheet"}


# --------------------------------------------------------------------------- parameters

class Params:
    """``section -> name -> {value, unit, source}``; lengths in millimetres (the CAD document's unit)."""

    def __init__(self, data: dict, path: Path):
        if not isinstance(data, dict) or data.get("format") != PARAMS_FORMAT:
            raise ParamError(f"{path}: 'format' must be {PARAMS_FORMAT!r}")
        self.path = Path(path)
        self.entries = {f"{s}.{n}": e for s, v in data.items() if isinstance(v, dict) for n, e in v.items()}
        for key, entry in self.entries.items():
            if not isinstance(entry, dict) or not {"value", "unit", "source"} <= set(entry) or not str(entry["source"]).strip():
                raise ParamError(f"{path}: {key} needs a value, a unit and a source")
            if entry["unit"] not in UNITS:
                raise ParamError(f"{path}: {key}: unit {entry['unit']!r} is not one of {sorted(UNITS)}")

    @classmethod
    def load(cls, path: Path) -> "Params":
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ParamError(f"{path}: no such file") from None
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ParamError(f"{path}: not a JSON parameter file ({exc})") from None
        return cls(data, Path(path))

    def _entry(self, key: str) -> dict:
        if key not in self.entries:
            raise ParamError(f"{self.path}: missing parameter {key}")
        return self.entries[key]

    def text(self, key: str) -> str:
        return str(self._entry(key)["value"])

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


# --------------------------------------------------------------------------- the four-bar

def rocker_angle(a: float, b: float, c: float, d: float, theta2: float) -> float:
    """Freudenstein: the rocker angle (from the ground line O2 -> O4) of the open four-bar whose crank
    is at ``theta2``; the coupler pin B lies above the ground line (the branch this assembly uses)."""
    k1, k2, k3 = d / a, d / c, (a * a - b * b + c * c + d * d) / (2 * a * c)
    big_a = math.cos(theta2) - k1 - k2 * math.cos(theta2) + k3
    big_b = -2 * math.sin(theta2)
    big_c = k1 - (k2 + 1) * math.cos(theta2) + k3
    disc = big_b * big_b - 4 * big_a * big_c
    if disc < 0:
        raise ParamError(f"the four-bar cannot be assembled with the horn at {math.degrees(theta2):g} deg")
    return math.remainder(2 * math.atan2(-big_b - math.sqrt(disc), 2 * big_a), 2 * math.pi)


@dataclass
class Layout:
    """Derived points (mm, world: x right, y up, z toward the viewer) at the assembly pose."""

    o2: np.ndarray  # servo output axis
    o4: np.ndarray  # arm pivot
    a: np.ndarray  # horn pin
    b: np.ndarray  # arm's lever pin
    tip: np.ndarray  # pendulum pivot
    motor: np.ndarray  # motor axis
    theta2: float  # horn angle from the ground line [rad]
    theta4: float  # lever angle from the ground line [rad]
    ratio: float  # motor turns per horn turn


def layout(p: Params) -> Layout:
    a, b, c, d = (p.positive(f"four_bar.{k}") for k in ("crank", "coupler", "rocker", "ground"))
    lengths = sorted((a, b, c, d))
    if lengths[0] + lengths[3] > lengths[1] + lengths[2]:
        raise ParamError(f"{p.path}: four_bar: not a Grashof linkage (shortest + longest > the other two)")
    if a != lengths[0]:
        raise ParamError(f"{p.path}: four_bar.crank must be the shortest link (the horn)")
    theta2 = math.radians(p("four_bar.horn_angle_deg"))
    theta4 = rocker_angle(a, b, c, d, theta2)
    o2 = np.zeros(3)
    o4 = np.array([d, 0.0, 0.0])
    pin_a = a * np.array([math.cos(theta2), math.sin(theta2), 0.0])
    pin_b = o4 + c * np.array([math.cos(theta4), math.sin(theta4), 0.0])
    tip = o4 + p.positive("arm.beam_length") * X
    motor = np.array([p("servo.motor_x"), 0.0, 0.0])
    ratio = p.positive("servo.gear_ratio")
    return Layout(o2, o4, pin_a, pin_b, tip, motor, theta2, theta4, ratio)


def turn_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def bar(length: float, width: float, z0: float, z1: float) -> mf.Manifold:
    """A bar from the origin along +x."""
    return box(0.0, length, -0.5 * width, 0.5 * width, z0, z1)


def bar_to(point, width: float, z0: float, z1: float) -> mf.Manifold:
    """A bar from the origin to ``point`` (x, y)."""
    angle = math.degrees(math.atan2(point[1], point[0]))
    return bar(math.hypot(point[0], point[1]), width, z0, z1).rotate((0.0, 0.0, angle))


def pin(point, shoulder_r: float, shoulder: tuple, pin_r: float, pin: tuple) -> mf.Manifold:
    """A shouldered pin along z at ``point`` (x, y): shoulder from shoulder[0] to [1], pin beyond."""
    return union(cylinder(shoulder_r, *shoulder, SMALL), cylinder(pin_r, *pin, SMALL)).translate((point[0], point[1], 0.0))


def build_parts(p: Params, lay: Layout) -> list[Part]:
    c = p.positive("fits.running_clearance")
    t = p.positive("links.thickness")
    pin_r, shoulder_r = p.positive("links.pin_radius"), p.positive("links.shoulder_radius")
    eye = p.positive("links.eye_radius")
    layer = p.positive("links.layer_gap")  # the coupler's layer in front of the horn and the arm
    # the frame: back plate, foot, and the arm's pivot post with its pin
    back = p.positive("frame.back_z")
    plate = p.positive("frame.plate_thickness")
    foot_y = -p.positive("frame.foot_depth")
    frame = union(
        box(p("frame.x0"), p("frame.back_x1"), foot_y, p("frame.top_y"), -back - plate, -back),
        box(p("frame.x0"), p("frame.foot_x1"), foot_y - plate, foot_y, -back - plate, p("frame.foot_z1")),
        cylinder(p.positive("frame.post_radius"), -back, 0.0, SEGMENTS).translate(tuple(lay.o4)),
        cylinder(p.positive("arm.pivot_radius"), -0.5, t + 1.0, SEGMENTS).translate(tuple(lay.o4)))
    # the servo's case (grounded, bolted to the back plate): a box with the motor's cavity and the output bore
    case_x0, case_x1 = p("servo.case_x0"), p("servo.case_x1")
    half = 0.5 * p.positive("servo.case_height")
    hub_r, hub_depth = p.positive("servo.hub_radius"), p.positive("servo.hub_depth")
    cavity_r = p.positive("servo.cavity_radius")
    case = (box(case_x0, case_x1, -half, half, -back, -c)
            - cylinder(cavity_r, -back + 3.0, -6.0, SEGMENTS).translate(tuple(lay.motor))
            - cylinder(hub_r + c, -hub_depth - c, 0.0, SEGMENTS))
    # the motor's rotor: shaft and armature, on the motor axis (part frame on the axis)
    arm_r, arm_len = p.positive("servo.armature_radius"), p.positive("servo.armature_length")
    rotor = union(cylinder(p.positive("servo.motor_shaft_radius"), -back + 4.0, -7.0, SMALL),
                  cylinder(arm_r, -back + 8.0, -back + 8.0 + arm_len, SEGMENTS))
    # the horn: a hub in the case's bore, a lever to the crank pin A (part frame on the output axis)
    a_local = lay.a - lay.o2
    horn = union(cylinder(hub_r, -hub_depth, t, SEGMENTS), cylinder(eye + 2.0, 0.0, t, SEGMENTS),
                 bar_to(a_local, 2 * eye, 0.0, t), cylinder(eye, 0.0, t, SMALL).translate((a_local[0], a_local[1], 0.0)),
                 pin(a_local, shoulder_r, (t, t + layer), pin_r, (t + layer, t + layer + t + 1.0)))
    # the coupler (part frame at A, x along A -> B)
    length = float(np.linalg.norm(lay.b - lay.a))
    z0, z1 = t + layer + c, t + layer + t
    coupler = (union(bar(length, 2 * pin_r + 3.0, z0, z1), cylinder(eye, z0, z1, SMALL),
                     cylinder(eye, z0, z1, SMALL).translate((length, 0.0, 0.0)))
               - cylinder(pin_r + c, z0 - 1, z1 + 1, SMALL) - cylinder(pin_r + c, z0 - 1, z1 + 1, SMALL).translate((length, 0.0, 0.0)))
    # the arm (part frame at O4): pivot boss, lever to B with its pin, beam to the tip with the pendulum's pin
    b_local, tip_local = lay.b - lay.o4, lay.tip - lay.o4
    boss = p.positive("arm.boss_radius")
    beam_w = p.positive("arm.beam_width")
    hole_x = p.positive("payload.hole_x")
    bolt_r = p.positive("payload.bolt_radius")
    pend_layer = p.positive("pendulum.layer_gap")
    arm = union(cylinder(boss, c, t, SEGMENTS), bar_to(b_local, 2 * eye, c, t),
                cylinder(eye, c, t, SMALL).translate((b_local[0], b_local[1], 0.0)),
                pin(b_local, shoulder_r, (t, t + layer), pin_r, (t + layer, t + layer + t + 1.0)),
                bar(tip_local[0], beam_w, c, t), cylinder(0.5 * beam_w + 1.0, c, t, SEGMENTS).translate((tip_local[0], 0.0, 0.0)),
                pin(tip_local, shoulder_r, (-pend_layer, c), pin_r, (-pend_layer - t - 1.0, -pend_layer)))
    arm = (arm - cylinder(p("arm.pivot_radius") + c, -1.0, t + 1.0, SEGMENTS)
           - cylinder(bolt_r, -1.0, t + 1.0, SMALL).translate((hole_x, 0.0, 0.0)))
    # the payload: a steel block bolted on the beam's front face, flush with its lower edge
    px0, px1 = -0.5 * p.positive("payload.length"), 0.5 * p.positive("payload.length")
    payload = (box(px0, px1, -0.5 * beam_w, -0.5 * beam_w + p.positive("payload.height"), 0.0, p.positive("payload.thickness"))
               - cylinder(bolt_r, -1.0, p("payload.thickness") + 1.0, SMALL))
    # the pendulum (part frame at its pivot): an eye on the tip pin, a rod down, a disc bob
    rod_len, rod_w = p.positive("pendulum.rod_length"), p.positive("pendulum.rod_width")
    bob_r, pt = p.positive("pendulum.bob_radius"), p.positive("pendulum.thickness")
    pz0, pz1 = -pend_layer - pt, -pend_layer - c
    pendulum = (union(cylinder(eye, pz0, pz1, SMALL), box(-0.5 * rod_w, 0.5 * rod_w, -rod_len, 0.0, pz0, pz1),
                      cylinder(bob_r, pz0, pz1, SEGMENTS).translate((0.0, -rod_len, 0.0)))
                - cylinder(pin_r + c, pz0 - 1.0, pz1 + 1.0, SMALL))
    coupler_axes = turn_z(math.atan2(*(lay.b - lay.a)[1::-1]))
    payload_at = lay.o4 + np.array([hole_x, 0.0, t])
    return [
        Part("FRAME", "aluminium", frame, np.eye(3), np.zeros(3), grounded=True, color=(0.55, 0.57, 0.6)),
        Part("SERVO_CASE", "nylon", case, np.eye(3), lay.o2, grounded=True, color=(0.1, 0.1, 0.12)),
        Part("MOTOR_ROTOR", "steel", rotor, np.eye(3), lay.motor, color=(0.75, 0.55, 0.3)),
        Part("SERVO_HORN", "aluminium", horn, np.eye(3), lay.o2, color=(0.85, 0.85, 0.88)),
        Part("COUPLER", "aluminium", coupler, coupler_axes, lay.a, color=(0.3, 0.5, 0.8)),
        Part("ARM", "aluminium", arm, np.eye(3), lay.o4, color=(0.8, 0.4, 0.2)),
        Part("PAYLOAD", "steel", payload, np.eye(3), payload_at, color=(0.4, 0.4, 0.42)),
        Part("PENDULUM", "steel", pendulum, np.eye(3), lay.tip, color=(0.7, 0.7, 0.2)),
    ]


# --------------------------------------------------------------------------- mates

def mates(p: Params, lay: Layout, parts: dict[str, Part]) -> list[tuple[str, str, Side, Side]]:
    """The assembly's mates as SolidWorks numbers them: (tag, name, first side, second side)."""
    t, layer = p("links.thickness"), p("links.layer_gap")
    frame, case, rotor, horn = parts["FRAME"], parts["SERVO_CASE"], parts["MOTOR_ROTOR"], parts["SERVO_HORN"]
    coupler, arm, payload, pendulum = parts["COUPLER"], parts["ARM"], parts["PAYLOAD"], parts["PENDULUM"]
    back = p("frame.back_z")
    shoulder = t + layer  # the coupler runs on the pins' shoulders
    rotor_face = lay.motor + (-back + 4.0) * Z  # the rotor shaft's end against the cavity's thrust face
    hole = lay.o4 + np.array([p("payload.hole_x"), 0.0, t])
    edge = hole + np.array([0.0, -0.5 * p("arm.beam_width"), 0.0])
    tip_face = lay.tip - p("pendulum.layer_gap") * Z
    return [
        ("Coincident", "Coincident1", Side("plane", frame, [0, 0, -back], Z), Side("plane", case, [0, 0, -back], -Z)),
        ("Concentric", "Concentric1", Side("cylinder", case, rotor_face, Z), Side("cylinder", rotor, rotor_face, Z)),
        ("Coincident", "Coincident2", Side("plane", case, rotor_face, Z), Side("plane", rotor, rotor_face, -Z)),
        ("Concentric", "Concentric2", Side("cylinder", case, lay.o2, Z), Side("cylinder", horn, lay.o2, Z)),
        ("Coincident", "Coincident3", Side("plane", case, lay.o2, Z), Side("plane", horn, lay.o2, -Z)),
        ("Concentric", "Concentric3", Side("cylinder", frame, lay.o4, Z), Side("cylinder", arm, lay.o4, Z)),
        ("Coincident", "Coincident4", Side("plane", frame, lay.o4, Z), Side("plane", arm, lay.o4, -Z)),
        ("Concentric", "Concentric4", Side("cylinder", horn, lay.a + shoulder * Z, Z), Side("cylinder", coupler, lay.a + shoulder * Z, Z)),
        ("Coincident", "Coincident5", Side("plane", horn, lay.a + shoulder * Z, Z), Side("plane", coupler, lay.a + shoulder * Z, -Z)),
        ("Concentric", "Concentric5", Side("cylinder", arm, lay.b + shoulder * Z, Z), Side("cylinder", coupler, lay.b + shoulder * Z, Z)),
        ("Coincident", "Coincident6", Side("plane", arm, lay.b + shoulder * Z, Z), Side("plane", coupler, lay.b + shoulder * Z, -Z)),
        ("Concentric", "Concentric6", Side("cylinder", arm, hole, Z), Side("cylinder", payload, hole, Z)),
        ("Coincident", "Coincident7", Side("plane", arm, hole, Z), Side("plane", payload, hole, -Z)),
        ("Coincident", "Coincident8", Side("plane", arm, edge, -Y), Side("plane", payload, edge, -Y)),
        ("Concentric", "Concentric7", Side("cylinder", arm, tip_face, Z), Side("cylinder", pendulum, tip_face, Z)),
        ("Coincident", "Coincident9", Side("plane", arm, tip_face, -Z), Side("plane", pendulum, tip_face, Z)),
    ]


# --------------------------------------------------------------------------- XML

def part_xml(part: Part, props, stl: str) -> str:
    t = props.inertia  # g*mm^2 about the centre of mass, part axes (tensor entries)
    inertia = [t[0, 0], t[1, 1], t[2, 2], t[1, 2], t[2, 0], t[0, 1]]
    r, g, b = part.color
    colour = f'a="1.000000000" b="{b:.9f}" g="{g:.9f}" r="{r:.9f}"'
    return (f'      <Part name="{part.name}" uid="{part.name}.SLDPRT">\n'
            f'         <ModelUnits length="millimeter" mass="gram"/>\n'
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
    # the gear mate: the motor rotor is the base (input), the horn the follower; ratio = motor turns per horn turn
    motor = Side("cylinder", by_name["MOTOR_ROTOR"], lay.motor, Z)
    output = Side("cylinder", by_name["SERVO_HORN"], lay.o2, Z)
    constraints += (f'         <GearConstraint name="GearMate1">\n{geometry_xml(motor, " " * 12)}'
                    f'{geometry_xml(output, " " * 12)}'
                    f"            <Ratio>{numbers([lay.ratio])}</Ratio>\n"
                    f"         </GearConstraint>\n")
    parts_xml = "".join(part_xml(part, masses[part.name], stls[part.name]) for part in parts)
    return (f'<?xml version="1.0" encoding="utf-8"?>\n'
            f'<SimscapeMultibodyImportXML xmlns="urn:mathworks:SimscapeMultibody:import" '
            f'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" version="2.0">\n'
            f'   <Created by="{p.text("export.created_by")}" from="SolidWorks" on="{p.text("export.created_on")}" '
            f'using="mechanism assets/cad/servo_arm/generate.py (second-generation writer)"/>\n'
            f'   <ModelUnits length="millimeter" mass="gram"/>\n'
            f'   <DataUnits length="millimeter" mass="gram"/>\n'
            f"   <Gravity>{numbers([0.0, -GRAVITY_MM_S2, 0.0])}</Gravity>\n"
            f'   <RootAssembly name="SERVO_ARM" uid="SERVO_ARM.SLDASM" version="{p.path.name}">\n'
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
        density_g_mm3 = p.positive(f"materials.{part.material}") * 1e-6
        masses[part.name] = shapes.mass_properties(mesh, density_g_mm3, part.name)
        stls[part.name] = f"{part.name}.STL"
        files[stls[part.name]] = shapes.binary_stl(mesh, f"{part.name} mm mechanism assets/cad/servo_arm/generate.py")
    files[f"{EXPORT_NAME}.xml"] = export_xml(p, lay, parts, masses, stls).encode("ascii")
    return files, lay, parts, masses


def write_export(p: Params, out_dir: Path) -> dict:
    files, lay, parts, masses = build_export(p)
    with atomic_dir(out_dir) as tmp:
        for name, data in sorted(files.items()):
            (tmp / name).write_bytes(data)
    return {"layout": lay, "parts": parts, "masses": masses, "files": sorted(files)}


def summary(p: Params, result: dict) -> list[str]:
    lay, masses = result["layout"], result["masses"]
    rotor = masses["MOTOR_ROTOR"].inertia[2, 2] * 1e-9  # g mm^2 -> kg m^2, about its own axis
    total = sum(m.mass for m in masses.values()) * 1e-3
    kt, r, v = p("datasheet.torque_constant_Nm_per_A"), p("datasheet.resistance_ohm"), p("datasheet.supply_V")
    return [
        f"four-bar {p('four_bar.crank'):g}/{p('four_bar.coupler'):g}/{p('four_bar.rocker'):g}/{p('four_bar.ground'):g} mm; "
        f"horn at {math.degrees(lay.theta2):g} deg, lever at {math.degrees(lay.theta4):.4f} deg",
        f"gearbox {lay.ratio:g}:1; motor rotor {rotor:.4e} kg m^2, {rotor * lay.ratio**2:.4e} kg m^2 at the horn; "
        f"stall torque at the horn {lay.ratio * kt * v / r:.3f} N m, no-load speed {v / p('datasheet.back_emf_V_s_per_rad') / lay.ratio:.3f} rad/s",
        f"total mass {total:.4f} kg",
        f"{len(result['parts'])} parts, {len(result['files'])} files",
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for flags, options in (
            (("--params",), dict(type=Path, default=DEFAULT_PARAMS, help="parameter file (JSON, see assets/mjcf/servo_arm.md)")),
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
