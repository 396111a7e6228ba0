"""Hand-built stand-ins for real CAD exports: each writes a small export with the features and
quirks one real exporter showed us (docs/real_exports.md lists the real files), from a design
whose geometry the tests know exactly.

Every builder writes into a folder and returns a ``Built``: the export's path, the total mass its
parts state (in kg, summed over the instances from the design's own numbers) and ``facts`` the tests
check against: the joints the mates or joints define, the designed points and axes. Geometry files
are named but not written, as in the real exports kept outside the repository.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tests.helpers.exports import (
    SLASH,
    FourBar,
    Inst,
    gen2_assembly,
    gen2_export,
    gen2_joint,
    gen2_mate,
    gen2_part,
    gen2_transform,
    gen2_unknown,
    in_frame,
    instance_path,
    instance_tree,
    mate_side,
    pin_mates,
    rotation,
)

X, Y, Z = np.eye(3)
INCH, LBM = 0.0254, 0.45359237


@dataclass
class Built:
    path: Path
    mass_kg: float  # what the export's parts weigh together, from the design's numbers
    facts: dict = field(default_factory=dict)


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def turned(i: int) -> np.ndarray:
    """An arbitrary part orientation: mates are written in each part's frame, so a frame convention
    the reader gets wrong gives wrong joints."""
    return rotation((1.0, 0.4 * i - 1.3, 0.7), 0.5 + 0.9 * i)


def circles_meet(c1, r1, c2, r2, near) -> np.ndarray:
    """The crossing of two circles (centres in a plane's 2-D coordinates) nearest ``near``."""
    c1, c2 = np.asarray(c1, float), np.asarray(c2, float)
    d = np.linalg.norm(c2 - c1)
    along = (r1 * r1 - r2 * r2 + d * d) / (2 * d)
    half = math.sqrt(max(r1 * r1 - along * along, 0.0))
    u = (c2 - c1) / d
    mid, across = c1 + along * u, np.array([-u[1], u[0]])
    return min((mid + half * across, mid - half * across), key=lambda p: np.linalg.norm(p - near))


class _Doc:
    """Parts, instances and mates of one second-generation export, from world poses."""

    def __init__(self):
        self.poses: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.masses: dict[str, float] = {}  # part entity uid -> mass (export units)
        self.parts: list[str] = []

    def part(
        self,
        uid: str,
        mass: float,
        com=(0, 0, 0),
        inertia=(1e-5, 1e-5, 1e-5, 0, 0, 0),
        name=None,
        geometry=None,
        extra="",
    ) -> str:
        """A part entity; ``com`` in its own frame; geometry named after it unless given."""
        name = name or uid.split("*")[0]
        self.masses[uid] = mass
        self.parts.append(
            gen2_part(name, uid, mass, com, inertia, geometry or f"{name}_sldprt.STEP", extra)
        )
        return uid

    def tree(self, *instances: Inst) -> str:
        return instance_tree(instances, self.poses)

    def mass(self, instances) -> float:
        """The instances' total mass (parts counted once per instance; the exports here are in kg)."""
        return sum(self.masses.get(i.entity, 0.0) + self.mass(i.children) for i in instances)

    def side(self, shape, key, point, axis=None, within=""):
        return mate_side(shape, key, self.poses[key], point, axis, within)

    def mate(self, tag, name, first, second, within="") -> str:
        """``first``/``second``: (shape, instance key, world point, world axis or None)."""
        return gen2_mate(
            tag, name, self.side(*first, within=within), self.side(*second, within=within)
        )

    def pin(self, name, a, b, point, normal, within="") -> list[str]:
        return pin_mates(name, a, b, self.poses, point, normal, within)

    def frame(self, key, rotation_world, point, within=""):
        """A joint frame given in the world, written in instance ``key``'s frame."""
        rot, origin = self.poses[key]
        return instance_path(key, within), gen2_transform(
            rot.T @ rotation_world, in_frame((rot, origin), point)
        )


def _write(folder: Path, name: str, text: str) -> Path:
    path = Path(folder) / name
    path.write_text(text, encoding="utf-8")
    return path


def _printed(text: str, fmt: str) -> str:
    """Every decimal number in ``text`` printed as an exporter with format ``fmt`` would."""
    return re.sub(
        r"(?<![\w.])-?\d+\.\d+(?:e[-+]?\d+)?", lambda m: format(float(m.group()), fmt), text
    )


# -- Pro/E four-bar: first generation, inches and pounds, RootPart -----------------------------


def proe_fourbar(folder: Path) -> Built:
    """A crank-rocker written as Pro/E Wildfire's SimMechanics Link 3 does: lbm and inches, the
    frame grounded through a massless RootPart, joint axes along -z."""
    design = FourBar(
        crank=40.0,
        coupler=110.0,
        rocker=90.0,
        ground=120.0,
        crank_angle0=math.radians(75),
        plane=rotation((1, 0, 0), math.pi),
        origin_mm=np.array([-150.0, 20.0, 5.0]),
    )
    path = design.export(
        folder, length_unit="in", mass_unit="lbm", root_part=True, write_meshes=False
    )
    return Built(path, LBM * sum(design.masses().values()), {"fourbar": design})


# -- SolidWorks ball and beam: mates only, a spatial loop, a loose part ------------------------


def ball_and_beam(folder: Path) -> Built:
    """A servo horn tilts a beam through a rod with a cross pin at each end (a spatial loop of 7
    revolutes and a cylindrical), every joint given by SolidWorks mates (coincident, concentric,
    parallel, distance, angle), parts bolted by mates, a ball mated to nothing.

    The horn turns about y at S, the beam about y at P; the rod's cross pins are perpendicular to
    it, in the plane of motion (the xz plane through S and P). Moving parts have their centres of
    mass in that plane and isotropic inertia, so the linkage moves as the planar four-bar S-A-B-P."""
    o = np.array([-0.1, -0.075, 1.0])
    s, p = o + (0, 0, 0.05), o + (0.22, 0, 0.11)
    horn, beam, alpha0 = 0.025, 0.17, math.radians(5)
    a = s + horn * np.array([math.cos(alpha0), 0, math.sin(alpha0)])
    b = p - beam * X
    cross = unit(np.cross(Y, b - a))
    doc = _Doc()
    moving = lambda m: (m * 1e-4,) * 3 + (0, 0, 0)  # isotropic: the same in every frame
    spec = [
        ("Base", "base-1", 0.30, o, np.eye(3), o),
        ("Soporte", "support-1", 0.05, o + (0, -0.03, 0.005), turned(1), None),
        ("Servo", "servo-1", 0.06, o + (-0.01, -0.02, 0.03), turned(2), None),
        ("Brazo", "horn-1", 0.010, a, turned(3), 0.5 * (s + a)),
        ("Rueda", "wheel-1", 0.020, s + 0.004 * Y, turned(4), s),
        ("Horquilla", "clevis-1", 0.005, a, turned(5), a),
        ("Varilla", "rod-1", 0.008, a, turned(6), 0.5 * (a + b)),
        ("Horquilla S", "fork_s-1", 0.004, b, turned(7), b),
        ("Balanza", "beam-1", 0.040, p, turned(8), p - 0.06 * X),
        ("Horquilla B", "fork_b-1", 0.006, p, turned(9), p),
        ("Varilla L", "post-1", 0.007, p - 0.06 * Z, turned(10), p - 0.05 * Z),
        (
            "Soporte sensor",
            "bracket-1",
            0.012,
            o + (-0.03, 0, 0.13),
            turned(11),
            o + (-0.03, 0, 0.13),
        ),
        ("Sensor", "sensor-1", 0.004, o + (-0.045, 0, 0.14), turned(12), o + (-0.045, 0, 0.14)),
        ("Bola", "ball-1", 0.003, o + (0.1, 0, 0.125), np.eye(3), None),
    ]
    instances = []
    for part_name, key, mass, origin, rot, com in spec:
        com_local = (0, 0, 0) if com is None else in_frame((rot, origin), com)
        doc.part(f"{part_name}*:*Predeterminado", mass, com_local, moving(mass), name=part_name)
        instances.append(
            Inst(
                key,
                f"{part_name}*:*Predeterminado",
                rot,
                origin,
                ' grounded="true"' if key == "base-1" else "",
            )
        )
    tree = doc.tree(*instances)
    m = doc.mate
    bolt = o + (0, -0.03, 0.005)
    q = o + (-0.01, -0.02, 0.03)
    tilt = np.array([math.cos(math.radians(30)), 0, math.sin(math.radians(30))])
    side_a, side_b = unit((0, 0.6, 0.8)), unit((0, -0.6, 0.8))
    e = o + (-0.03, 0, 0.13)
    mates = [
        m(
            "Coincident",
            "Coincidente1",
            ("plane", "base-1", bolt, Z),
            ("plane", "support-1", bolt, -Z),
        ),
        m(
            "Concentric",
            "Concéntrica1",
            ("cylinder", "base-1", bolt + 0.02 * X, Z),
            ("cylinder", "support-1", bolt + 0.02 * X, Z),
        ),
        m(
            "Concentric",
            "Concéntrica2",
            ("cylinder", "base-1", bolt - 0.02 * X, Z),
            ("cylinder", "support-1", bolt - 0.02 * X, -Z),
        ),
        m(
            "Concentric",
            "Concéntrica3",
            ("cylinder", "support-1", q, Y),
            ("cylinder", "servo-1", q + 0.004 * Y, Y),
        ),
        m(
            "Distance",
            "Distancia1",
            ("plane", "support-1", q - 0.005 * Y, Y),
            ("plane", "servo-1", q - 0.002 * Y, -Y),
        ),
        m(
            "Angle",
            "Ángulo1",
            ("plane", "support-1", q + 0.01 * X, X),
            ("plane", "servo-1", q + 0.01 * X + 0.005 * Z, tilt),
        ),
        *doc.pin("Eje servo", "servo-1", "horn-1", s - 0.005 * Y, Y),
        m(
            "Coincident",
            "Coincidente4",
            ("plane", "horn-1", s + 0.002 * Y, Y),
            ("plane", "wheel-1", s + 0.002 * Y, -Y),
        ),
        *[
            m(
                "Concentric",
                f"Concéntrica{5 + i}",
                ("cylinder", "horn-1", s + 0.012 * sign * unit(np.cross(Y, a - s)), Y),
                ("cylinder", "wheel-1", s + 0.012 * sign * unit(np.cross(Y, a - s)), -Y),
            )
            for i, sign in enumerate((1, -1))
        ],
        *doc.pin("Pasador A", "wheel-1", "clevis-1", a + 0.006 * Y, Y),
        *doc.pin("Cruceta A", "clevis-1", "rod-1", a, cross),
        *doc.pin("Cruceta B", "rod-1", "fork_s-1", b, cross),
        *doc.pin("Pasador B", "fork_s-1", "beam-1", b + 0.004 * Y, Y),
        m(
            "Concentric",
            "Concéntrica9",
            ("cylinder", "fork_b-1", p + 0.01 * Y, Y),
            ("cylinder", "beam-1", p, -Y),
        ),
        m(
            "Parallel",
            "Paralela1",
            ("plane", "fork_b-1", p + 0.012 * Y, Y),
            ("plane", "beam-1", p - 0.003 * Y + 0.01 * X, Y),
        ),
        *doc.pin("Pivote horquilla", "post-1", "fork_b-1", p - 0.02 * Z, Z),
        *doc.pin("Pivote columna", "base-1", "post-1", p - 0.091 * Z, Z),
        # the same faces mated twice
        *[
            m(
                "Coincident",
                f"Coincidente{10 + i}",
                ("plane", "beam-1", e + d, -X),
                ("plane", "bracket-1", e + d, X),
            )
            for i, d in enumerate((0.001 * Z, -0.004 * Z + 0.002 * Y))
        ],
        m(
            "Coincident",
            "Coincidente12",
            ("plane", "beam-1", e + 0.01 * Y, side_a),
            ("plane", "bracket-1", e + 0.01 * Y, -side_a),
        ),
        m(
            "Coincident",
            "Coincidente13",
            ("plane", "beam-1", e - 0.01 * Y, side_b),
            ("plane", "bracket-1", e - 0.01 * Y, -side_b),
        ),
        m(
            "Coincident",
            "Coincidente14",
            ("plane", "bracket-1", e - 0.015 * X, -X),
            ("plane", "sensor-1", e - 0.015 * X, X),
        ),
        *[
            m(
                "Concentric",
                f"Concéntrica{10 + i}",
                ("cylinder", "bracket-1", e + d, X),
                ("cylinder", "sensor-1", e + d, -X),
            )
            for i, d in enumerate((0.01 * Z + 0.02 * Y, 0.01 * Z - 0.02 * Y))
        ],
    ]
    path = _write(
        folder,
        "ballbeam.xml",
        gen2_export(
            tree,
            "",
            "".join(doc.parts),
            constraints="".join(mates),
            model_units=("millimeter", "kilogram"),
        ),
    )
    joints = {
        ("servo-1", "horn-1"): "revolute",
        ("wheel-1", "clevis-1"): "revolute",
        ("clevis-1", "rod-1"): "revolute",
        ("rod-1", "fork_s-1"): "revolute",
        ("fork_s-1", "beam-1"): "revolute",
        ("fork_b-1", "beam-1"): "cylindrical",
        ("post-1", "fork_b-1"): "revolute",
        ("base-1", "post-1"): "revolute",
    }
    return Built(
        path,
        doc.mass(instances),
        {
            "joints": joints,
            "S": s,
            "P": p,
            "A": a,
            "B": b,
            "rod": np.linalg.norm(b - a),
            "horn": horn,
            "beam": beam,
            "loose": "ball-1",
        },
    )


# -- SolidWorks Furuta pendulum: Y-up, an UnknownConstraint, a hidden part ----------------------


def furuta(folder: Path) -> Built:
    """A Furuta pendulum in a Y-up world: an arm turns about the vertical y axis, a pendulum hangs
    from a horizontal axis along the arm. Mates only; a hidden motor mount; ``circle`` geometry;
    a bearing mated to two parts bolted together; a lock mate the exporter could not describe."""
    o, up = np.array([0.012, -0.048, 0.046]), Y
    lift = lambda height, x=0.0, z=0.0: o + np.array([x, height, z])  # y is up
    pivot = lift(0.125, 0.08)  # the pendulum's axis: along x through here
    doc = _Doc()
    names = {
        "stand-1": (0.18, o),
        "stand cap-1": (0.055, lift(0.135)),
        "bearing housing-1": (0.015, lift(0.142)),
        "bearing 6000 (10x26x8)-1": (0.012, lift(0.137)),
        "motor mount-1": (0.0043, lift(0.07)),
        "shaft coupling-1": (0.0024, lift(0.10)),
        "arm-1": (0.047, lift(0.112)),
        "encoder mount-1": (0.0155, lift(0.12, 0.07)),
        "pendulum holder-1": (0.012, lift(0.125, 0.06)),
        "pendulum-1": (0.157, pivot),
        "bearing cap-3": (0.0033, pivot - 0.02 * X),
    }
    instances = []
    for i, (key, (mass, origin)) in enumerate(names.items()):
        entity = f"{key.rsplit('-', 1)[0]}*:*Default"
        # the stand's z is the world's up
        rot = rotation(X, -math.pi / 2) if key == "stand-1" else turned(i)
        # the pendulum hangs straight down
        com = pivot - 0.1 * up + 0.01 * X if key == "pendulum-1" else origin
        doc.part(entity, mass, in_frame((rot, origin), com), (mass * 1e-4,) * 3 + (0, 0, 0))
        attrs = (
            ' grounded="true"'
            if key == "stand-1"
            else ' visible="false"'
            if key == "motor mount-1"
            else ""
        )
        instances.append(Inst(key, entity, rot, origin, attrs))
    tree = doc.tree(*instances)
    m = doc.mate
    stand, cap, housing, bearing, mount, coupling, arm, encoder, holder, pendulum, bcap = names
    tip = lift(0.12, 0.07)
    mates = [
        m(
            "Concentric",
            "Concentric1",
            ("cylinder", stand, lift(0.135), -up),
            ("cylinder", cap, lift(0.145), -up),
        ),
        m(
            "Concentric",
            "Concentric2",
            ("cylinder", stand, lift(0.127, 0.045), up),
            ("cylinder", cap, lift(0.135, 0.045), -up),
        ),
        m(
            "Coincident",
            "Coincident1",
            ("plane", stand, lift(0.135), up),
            ("plane", cap, lift(0.135), -up),
        ),
        m(
            "Concentric",
            "Concentric3",
            ("cylinder", cap, lift(0.137), up),
            ("cylinder", housing, lift(0.146), -up),
        ),
        m(
            "Coincident",
            "Coincident3",
            ("plane", cap, lift(0.140), up),
            ("plane", housing, lift(0.140), -up),
        ),
        m(
            "Concentric",
            "Concentric4",
            ("cylinder", cap, lift(0.14, 0.0175), up),
            ("cylinder", housing, lift(0.149, 0.0175), -up),
        ),
        m(
            "Concentric",
            "Concentric6",
            ("cylinder", stand, lift(-0.008), up),
            ("circle", mount, lift(0.065), up),
        ),
        m(
            "Coincident",
            "Coincident4",
            ("plane", stand, lift(0.065), up),
            ("plane", mount, lift(0.065), up),
        ),
        m(
            "Concentric",
            "Concentric7",
            ("cylinder", housing, lift(0.149), -up),
            ("cylinder", arm, lift(0.112), up),
        ),
        m(
            "Concentric",
            "Concentric13",
            ("cylinder", housing, lift(0.149), -up),
            ("cylinder", coupling, lift(0.13), -up),
        ),
        m(
            "Coincident",
            "Coincident15",
            ("plane", mount, lift(0.075), -up),
            ("plane", coupling, lift(0.075), up),
        ),
        m(
            "Coincident",
            "Coincident5",
            ("plane", arm, tip + 0.0 * X, X),
            ("plane", encoder, tip, -X),
        ),
        m(
            "Concentric",
            "Concentric8",
            ("cylinder", arm, tip + (0, 0.01, 0.01), X),
            ("cylinder", encoder, tip + (0.004, 0.01, 0.01), -X),
        ),
        m(
            "Coincident",
            "Coincident7",
            ("plane", arm, tip + 0.005 * X, up),
            ("plane", encoder, tip + 0.005 * X, -up),
        ),
        m(
            "Coincident",
            "Coincident6",
            ("plane", arm, tip - 0.01 * X, Z),
            ("circle", encoder, tip + 0.015 * up, X),
        ),
        m(
            "Coincident",
            "Coincident8",
            ("plane", arm, lift(0.125, 0.055), X),
            ("plane", holder, lift(0.125, 0.055), -X),
        ),
        m(
            "Coincident",
            "Coincident9",
            ("plane", arm, lift(0.125, 0.065), -X),
            ("plane", holder, lift(0.125, 0.065), X),
        ),
        m(
            "Concentric",
            "Concentric9",
            ("cylinder", arm, lift(0.13, 0.06, 0.005), X),
            ("cylinder", holder, lift(0.13, 0.062, 0.005), -X),
        ),
        m(
            "Coincident",
            "Coincident10",
            ("plane", arm, lift(0.118, 0.06), up),
            ("plane", holder, lift(0.118, 0.06), -up),
        ),
        m(
            "Concentric",
            "Concentric27",
            ("circle", arm, lift(0.112), -up),
            ("cylinder", coupling, lift(0.1), up),
        ),
        m(
            "Coincident",
            "Coincident25",
            ("plane", arm, lift(0.112), -up),
            ("plane", coupling, lift(0.112), up),
        ),
        m(
            "Coincident",
            "Coincident21",
            ("plane", cap, lift(0.137), up),
            ("plane", bearing, lift(0.137), -up),
        ),
        m(
            "Concentric",
            "Concentric20",
            ("cylinder", housing, lift(0.149), -up),
            ("cylinder", bearing, lift(0.14), up),
        ),
        m(
            "Coincident",
            "Coincident26",
            ("plane", encoder, pivot - 0.004 * X, X),
            ("plane", pendulum, pivot - 0.004 * X, -X),
        ),
        m(
            "Concentric",
            "Concentric28",
            ("cylinder", encoder, pivot - 0.006 * X, -X),
            ("cylinder", pendulum, pivot, X),
        ),
        m(
            "Concentric",
            "Concentric29",
            ("cylinder", holder, pivot - 0.02 * X, -X),
            ("cylinder", pendulum, pivot, X),
        ),
        m(
            "Concentric",
            "Concentric18",
            ("cylinder", holder, pivot - 0.018 * X, X),
            ("cylinder", bcap, pivot - 0.02 * X, -X),
        ),
        gen2_unknown("Lock3", [holder], [bcap]),
    ]
    path = _write(
        folder,
        "furuta assembly.xml",
        gen2_export(
            tree,
            "",
            "".join(doc.parts),
            constraints="".join(mates),
            model_units=("millimeter", "kilogram"),
        ),
    )
    joints = {
        ("stand-1", "motor mount-1"): "revolute",
        ("bearing housing-1", "arm-1"): "cylindrical",
        ("bearing housing-1", "shaft coupling-1"): "cylindrical",
        ("motor mount-1", "shaft coupling-1"): "planar",
        ("arm-1", "shaft coupling-1"): "revolute",
        # each pair its own joint, as Simscape's import: the bearing sits on the cap by a face (planar) and in
        # the housing bolted to it by its bore (cylindrical); the pendulum turns in the encoder mount and in
        # the holder bolted to the arm beside it: two joints, one loop
        ("stand cap-1", "bearing 6000 (10x26x8)-1"): "planar",
        ("bearing housing-1", "bearing 6000 (10x26x8)-1"): "cylindrical",
        ("encoder mount-1", "pendulum-1"): "revolute",
        ("pendulum holder-1", "pendulum-1"): "cylindrical",
    }
    # the holder and the bearing cap are fixed together by the lock mate the exporter could not describe
    return Built(
        path,
        doc.mass(instances),
        {
            "joints": joints,
            "up": up,
            "motor_axis_point": o,
            "pivot": pivot,
            "pendulum": "pendulum holder-1--pendulum-1_hinge",
            "hidden": "motor mount-1",
        },
    )


# -- SimMechanics Link 4 hexapod leg link: legacy root, one rigid sub-assembly used twice -------

SERVO_PARTS = {  # inner instance -> (part entity, mass kg, origin and orientation in the servo's frame)
    "case-1": ("servo case", 0.0042, (0.0, 0.016, 0.005), np.eye(3)),
    "top-1": (
        "servo top",
        0.0031,
        (0.018, 0.017, -0.005),
        rotation(X, math.pi / 2) @ rotation(Z, math.pi),
    ),
    "bottom-1": ("servo bottom", 0.0012, (-0.001, -0.0066, 0.005), np.eye(3)),
    "spline-1": ("spline", 0.0076, (0.008, 0.021, 0.005), np.eye(3)),
    "screw-1": ("screw", 5.7e-5, (0.016, -0.006, 0.013), rotation((1, 2, 0), 0.9)),
    "screw-2": ("screw", 5.7e-5, (-0.018, -0.006, 0.013), rotation((1, -2, 0), 0.7)),
}


def hexapod_link(folder: Path) -> Built:
    """A hexapod leg link as SimMechanics Link 4.6 wrote it (root ``SimMechanicsImportXML`` 1.0):
    two instances of one rigid servo sub-assembly (the same inner uids twice), joined by two
    brackets and a plate with Cyrillic names, bolted by mates named in Russian: one rigid body."""
    doc = _Doc()
    inch = '<ModelUnits mass="kilogram" length="inch"/>'  # the part documents' own unit: not the data's
    for entity, mass in dict.fromkeys((e, m) for e, m, _, _ in SERVO_PARTS.values()):
        doc.part(
            f"{entity}*:*Default",
            mass,
            (0.001, -0.002, 0.0),
            (2e-7, 3e-7, 4e-7, 1e-9, 0, 2e-9),
            extra=inch,
        )
    bracket, plate = "кронштейн", "пластина"
    doc.part(
        f"{bracket}*:*Default",
        0.0043,
        (0, 0.006, 0.0045),
        (8e-7, 1.6e-6, 1.3e-6, -1e-7, 0, 0),
        extra=inch,
    )
    doc.part(
        f"{plate}*:*Default",
        0.0027,
        (-0.01, 0.006, 0),
        (3e-7, 4e-7, 4.5e-7, 0, 0, -1.2e-7),
        extra=inch,
    )
    servo_b = (rotation((1, 1, -1), 2.3), np.array([0.0397, 0.00116, 0.0152]))

    def servo(uid, pose, attrs):
        rot, origin = pose
        inner = [
            Inst(
                key,
                f"{entity}*:*Default",
                rot @ r,
                origin + rot @ np.asarray(t),
                ' grounded="true"' if key == "top-1" else "",
            )
            for key, (entity, _, t, r) in SERVO_PARTS.items()
        ]
        return Inst(uid, "servo", rot, origin, attrs + ' rigid="true"', tuple(inner))

    instances = [
        servo("servo-2", (np.eye(3), np.zeros(3)), ' grounded="true"'),
        Inst(
            f"{bracket}-1",
            f"{bracket}*:*Default",
            rotation(X, math.pi / 2),
            (-0.0006, 0.0057, -0.009),
        ),
        Inst(
            f"{plate}-2", f"{plate}*:*Default", rotation(X, -math.pi / 2), (0.0304, 0.0111, -0.0112)
        ),
        Inst(
            f"{bracket}-2",
            f"{bracket}*:*Default",
            rotation(Z, -math.pi / 2),
            (0.0304, 0.0028, 0.0095),
        ),
        servo("servo-3", servo_b, ""),
    ]
    tree = doc.tree(*instances)
    m = doc.mate
    top_a, top_b, one, two, flat = (
        "servo-2/top-1",
        "servo-3/top-1",
        f"{bracket}-1",
        f"{bracket}-2",
        f"{plate}-2",
    )
    pa, pb = (
        np.array([0.0434, 0.0149, -0.0047]),
        servo_b[1] + servo_b[0] @ np.array([-0.0047, 0.0048, 0.02]),
    )
    zb, yb = servo_b[0] @ Z, servo_b[0] @ Y
    mates = [
        m(
            "Concentric",
            "Концентричность1",
            ("cylinder", top_a, pa, Z),
            ("cylinder", one, pa + 0.002 * Z, -Z),
        ),
        m(
            "Coincident",
            "Совпадение1",
            ("plane", top_a, pa + 0.0019 * Z, -Z),
            ("plane", one, pa + (0.003, 0.001, 0.0019), -Z),
        ),
        m(
            "Parallel",
            "Параллельность1",
            ("plane", "servo-2/case-1", (-0.0186, 0.0012, -0.0098), Y),
            ("plane", one, (0.01, 0.0015, 0), -Y),
        ),
        m(
            "Concentric",
            "Концентричность2",
            ("cylinder", one, (0.0083, 0.0015, -0.0054), Y),
            ("cylinder", flat, (0.0083, 0.003, -0.0054), -Y),
        ),
        m(
            "Concentric",
            "Концентричность3",
            ("cylinder", one, (0.0083, 0.0015, -0.0137), Y),
            ("cylinder", flat, (0.0083, 0.003, -0.0137), -Y),
        ),
        m(
            "Coincident",
            "Совпадение2",
            ("plane", one, (0.0, 0.0, 0.0), -Y),
            ("plane", flat, (0.02, 0.0, 0.01), Y),
        ),
        m(
            "Concentric",
            "Концентричность4",
            ("cylinder", flat, (0.0, 0.015, 0.0), X),
            ("cylinder", two, (0.01, 0.015, 0.0), -X),
        ),
        m(
            "Concentric",
            "Концентричность5",
            ("cylinder", flat, (0.0, 0.007, 0.0), X),
            ("cylinder", two, (0.01, 0.007, 0.0), X),
        ),
        m(
            "Coincident",
            "Совпадение3",
            ("plane", flat, (0.03, 0.0023, -0.0123), X),
            ("plane", two, (0.03, 0.0, 0.0), -X),
        ),
        m(
            "Concentric",
            "Концентричность6",
            ("cylinder", two, pb, -zb),
            ("cylinder", top_b, pb - 0.003 * zb, zb),
        ),
        m(
            "Coincident",
            "Совпадение4",
            ("plane", two, pb + 0.001 * yb, -zb),
            ("plane", top_b, pb + 0.002 * yb, zb),
        ),
        m(
            "Parallel",
            "Параллельность2",
            ("plane", two, pb, yb),
            ("plane", "servo-3/case-1", pb + 0.01 * zb, -yb),
        ),
    ]
    assemblies = '<Assembly name="servo" uid="servo"><ModelUnits mass="kilogram" length="millimeter"/></Assembly>'
    path = _write(
        folder,
        "Link1.xml",
        gen2_export(
            tree,
            "",
            "".join(doc.parts),
            assemblies,
            constraints="".join(mates),
            model_units=("millimeter", "kilogram"),
            legacy=True,
        ),
    )
    case_b = servo_b[1] + servo_b[0] @ np.asarray(SERVO_PARTS["case-1"][2])
    return Built(
        path,
        doc.mass(instances),
        {"n_parts": 2 * len(SERVO_PARTS) + 3, "case_b": case_b, "unicode_parts": {one, two, flat}},
    )


# -- SimMechanics Link 4 robot shin: a flexible sub-assembly with its own mates ----------------


def robot_shin(folder: Path) -> Built:
    """A knee (grounded), a shin turning about the knee pin, and a damper between them whose
    housing, cap and rod are a flexible sub-assembly turned about z, with its own mates and its
    housing grounded in it. The foot is a rigid sub-assembly holding another rigid one. Pins are
    mated concentric only on one side (they may slide), and numbers are printed to 6 digits."""
    knee, ankle = np.array([0.12, 0.10, 0.16]), np.array([0.13, -0.26, 0.16])
    h, d = np.array([0.08, 0.11, 0.15]), np.array([0.15, -0.10, 0.15])  # the damper's two eyes
    axis = unit(d - h)
    damper = rotation(Z, math.atan2(-axis[0], axis[1]))  # its y axis along the damper
    doc = _Doc()
    for entity, mass in (
        ("lower_knee", 0.59),
        ("knee_pin", 0.056),
        ("upper_shin", 0.31),
        ("housing", 0.12),
        ("cap", 0.011),
        ("stroke", 0.03),
        ("damper_pin", 0.039),
        ("ankle_pin", 0.04),
        ("ankle", 0.09),
        ("sole", 0.24),
        ("spring_a", 0.02),
        ("spring_b", 0.02),
    ):
        doc.part(
            f"{entity}*:*Default",
            mass,
            (0.002, -0.001, 0.003),
            (1.0e-5, 2.1e-5, 2.5e-5, 1e-7, -5e-8, 7e-7),
        )
    spring = Inst(
        "spring_pack-1",
        "spring_pack",
        turned(3),
        ankle + (0.0, 0.05, 0.0),
        ' rigid="true"',
        (
            Inst(
                "spring_a-1",
                "spring_a*:*Default",
                turned(4),
                ankle + (0.01, 0.06, 0.0),
                ' grounded="true"',
            ),
            Inst("spring_b-1", "spring_b*:*Default", turned(5), ankle + (0.01, 0.07, 0.0)),
        ),
    )
    instances = [
        Inst(
            "lower_knee-1",
            "lower_knee*:*Default",
            np.eye(3),
            knee + (0.01, 0.01, 0.0),
            ' grounded="true"',
        ),
        Inst(
            "damper-1",
            "damper",
            damper,
            h,
            children=(
                Inst("housing-1", "housing*:*Default", damper, h, ' grounded="true"'),
                Inst("cap-1", "cap*:*Default", damper @ rotation(Y, 0.26), h + 0.14 * axis),
                Inst("stroke-1", "stroke*:*Default", damper, d),
            ),
        ),
        Inst("damper_pin-1", "damper_pin*:*Default", turned(6), d),
        Inst("damper_pin-2", "damper_pin*:*Default", turned(7), h),
        Inst(
            "foot-1",
            "foot",
            rotation(Z, 0.03),
            ankle,
            ' rigid="true"',
            (
                Inst("ankle-1", "ankle*:*Default", rotation(Z, 0.003), ankle),
                Inst("sole-1", "sole*:*Default", rotation(Z, 0.19), ankle + (0.03, -0.04, 0)),
                spring,
            ),
        ),
        Inst("ankle_pin-1", "ankle_pin*:*Default", turned(8), ankle),
        Inst("upper_shin-1", "upper_shin*:*Default", np.eye(3), knee),
        Inst("knee_pin-1", "knee_pin*:*Default", turned(9), knee),
    ]
    tree = doc.tree(*instances)
    m = doc.mate
    inner = [
        *doc.pin(
            "Concentric1",
            "damper-1/housing-1",
            "damper-1/cap-1",
            h + 0.14 * axis,
            axis,
            within="damper-1",
        ),
        m(
            "Concentric",
            "Concentric2",
            ("cylinder", "damper-1/cap-1", h + 0.145 * axis, -axis),
            ("cylinder", "damper-1/stroke-1", d - 0.05 * axis, axis),
            within="damper-1",
        ),
    ]
    mates = [
        m(
            "Concentric",
            "Concentric8",
            ("cylinder", "lower_knee-1", knee, Z),
            ("cylinder", "knee_pin-1", knee + 0.06 * Z, Z),
        ),
        *doc.pin("Knee", "upper_shin-1", "knee_pin-1", knee + 0.01 * Z, Z),
        m(
            "Coincident",
            "Coincident7",
            ("plane", "lower_knee-1", knee, -Z),
            ("plane", "upper_shin-1", knee, Z),
        ),
        m(
            "Concentric",
            "Concentric26",
            ("cylinder", "lower_knee-1", h + 0.01 * Z, Z),
            ("cylinder", "damper_pin-2", h, -Z),
        ),
        *doc.pin("Housing eye", "damper-1/housing-1", "damper_pin-2", h, Z),
        *doc.pin("Rod eye", "damper-1/stroke-1", "damper_pin-1", d, Z),
        *doc.pin("Shin eye", "upper_shin-1", "damper_pin-1", d + 0.012 * Z, Z),
        m(
            "Concentric",
            "Concentric35",
            ("cylinder", "upper_shin-1", ankle, Z),
            ("cylinder", "ankle_pin-1", ankle + 0.03 * Z, Z),
        ),
        *doc.pin("Ankle", "foot-1/ankle-1", "ankle_pin-1", ankle + 0.01 * Z, Z),
        m(
            "Coincident",
            "Coincident20",
            ("plane", "upper_shin-1", ankle - 0.02 * X, Z),
            ("plane", "foot-1/sole-1", ankle - 0.02 * X, -Z),
        ),
    ]
    assemblies = (
        gen2_assembly("damper", constraints="".join(inner))
        + gen2_assembly("foot")
        + gen2_assembly("spring_pack")
    )
    text = gen2_export(
        tree,
        "",
        "".join(doc.parts),
        assemblies,
        constraints="".join(mates),
        model_units=("millimeter", "kilogram"),
        legacy=True,
    )
    path = _write(folder, "robot_shin.xml", _printed(text, ".6g"))
    return Built(
        path,
        doc.mass(instances),
        {"knee": knee, "housing_eye": h, "rod_eye": d, "damper_axis": axis},
    )


# -- Creo arm: no DataUnits, line axes that are not unit vectors --------------------------------

CREO_CHAIN = [  # (instance uid, part, kind, world axis, a world point on it in mm) from the base outwards
    ("9", "COLUMN", "revolute", Z, (0.0, 0.0, -150.0)),
    ("11", "BOOM", "prismatic", X, (0.0, 0.0, -220.0)),
    ("12", "SLEEVE", "prismatic", Z, (620.0, 0.0, 0.0)),
    ("14", "WRIST", "revolute", X, (540.0, 0.0, 110.0)),
    ("15", "SLIDER", "prismatic", Y, (500.0, 0.0, 110.0)),
    ("16", "TOOL", "revolute", Y, (400.0, 0.0, 110.0)),
]


def creo_arm(folder: Path) -> Built:
    """A six-axis arm as Creo 6's Simscape Multibody Link writes it: no ``<DataUnits>`` (numbers
    in the ``ModelUnits``, mm), numeric instance uids, each joint from a ``line``-``line`` and a
    ``plane``-``plane`` coincidence with line axes written as long vectors, masses from Creo's
    default density (10^10 kg and more), and a massless skeleton part mated to nothing."""
    doc = _Doc()
    doc.part(
        "SKELETON_prt",
        0.0,
        inertia=(0, 0, 0, 0, 0, 0),
        name="ASM_SKEL",
        geometry="asm_skel_prt.step",
    )
    instances = [
        Inst("2", "SKELETON_prt", name="ASM_SKEL"),
        Inst(
            "5",
            doc.part(
                "BASE_prt",
                4.4e10,
                (0, 0, 6.4),
                (9.2e14, 9.2e14, 1.5e15, 0, 0, 0),
                name="BASE",
                geometry="base_prt.step",
            ),
            name="BASE",
            attrs=' grounded="true"',
        ),
    ]
    for i, (uid, part, _, _axis, point) in enumerate(CREO_CHAIN):
        mass = 2.5e11 / (i + 1)
        entity = doc.part(
            f"{part}_prt",
            mass,
            (300.0, 10.0 * i, -50.0),
            (mass * 4e4, mass * 1.6e5, mass * 1.9e5, 0, mass * 2e3, 0),
            name=part,
            geometry=f"{part.lower()}_prt.step",
        )
        instances.append(
            Inst(
                uid,
                entity,
                turned(i) if i % 2 else rotation(Z, math.pi / 2 * i),
                np.asarray(point) + (-80.0, 0, 0),
                name=part,
            )
        )
    tree = doc.tree(*instances)
    # joints: (base uid, follower uid) -> (kind, axis, a point on it in metres)
    mates, joints = (
        [],
        {},
    )
    previous = "5"
    for uid, _, kind, axis, point in CREO_CHAIN:
        point = np.asarray(point)
        # locks the rest
        normal = axis if kind == "revolute" else next(v for v in (Z, X, Y) if abs(v @ axis) < 0.5)
        mates += [
            doc.mate(
                "Coincident",
                f"Coincident_{uid}_0",
                ("line", previous, point - 125 * axis, 250 * axis),
                ("line", uid, point + 60 * axis, -180 * axis),
            ),
            doc.mate(
                "Coincident",
                f"Coincident_{uid}_1",
                ("plane", previous, point, normal),
                ("plane", uid, point, normal),
            ),
        ]
        joints[(previous, uid)] = (kind, axis, point * 1e-3)
        previous = uid
    text = gen2_export(
        tree,
        "",
        "".join(doc.parts),
        length="mm",
        mass="kg",
        constraints="".join(mates),
        data_units=False,
    )
    return Built(
        _write(folder, "ASM0002.xml", text),
        doc.mass(instances),
        {"joints": joints, "skeleton": "ASM_SKEL"},
    )


# -- SolidWorks parallel-arm printer: a five-bar and a bed, every link a rigid sub-assembly -----


def scara_printer(folder: Path) -> Built:
    """A printer head carried by a five-bar (cranks at O1 and O2, forearms meeting at the head's
    axis N) kept square by two parallelograms (a third crank at O3 = O2 + e with a rocker plate,
    and a tie rod parallel to the second forearm), and a bed sliding on two rails. Every link is
    a rigid sub-assembly with its part grounded in it, two of them used several times; pins are
    ``circle``-``circle`` coincidences, the head's second forearm and the tie rod are only
    concentric. Freedoms: the two cranks and the bed."""
    crank, forearm, height = 0.09, 0.17, 0.03
    o1, o2, e, g = (
        np.array([-0.04, 0.10]),
        np.array([0.04, 0.10]),
        np.array([0.03, 0.0]),
        np.array([0.0, -0.03]),
    )
    theta_b, theta_c = math.radians(110), math.radians(70)
    p1 = o1 + crank * np.array([math.cos(theta_b), math.sin(theta_b)])
    c = o2 + crank * np.array([math.cos(theta_c), math.sin(theta_c)])
    n = circles_meet(p1, forearm, c, forearm, near=(0.0, 0.4))
    at = lambda xy, z: np.array([xy[0], xy[1], z])
    doc = _Doc()
    for entity, mass in (
        ("chassis", 0.5),
        ("rail", 0.05),
        ("spacer", 0.002),
        ("stepper___ _____", 0.28),
        ("bed plate", 0.15),
        ("guide block", 0.01),
        ("arm link", 0.02),
        ("forearm", 0.03),
        ("rocker plate", 0.015),
        ("tie rod", 0.012),
        ("carriage", 0.1),
        ("extruder", 0.05),
        ("fan___ 24v", 0.01),
    ):
        doc.part(
            f"{entity}.STEP*:*Default", mass, (0.01, 0.0, 0.002), (1e-5, 2e-5, 2.5e-5, 0, 0, 1e-7)
        )
    fixed = ' grounded="true"'
    rail = rotation(X, -math.pi / 2)  # the rails' z along the world y
    part = lambda uid, entity, rot, origin: Inst(
        uid, f"{entity}.STEP*:*Default", rot, origin, fixed
    )
    link = lambda uid, asm, entity, origin, angle: (
        Inst(  # the part sits upside down in its sub-assembly
            uid,
            asm,
            rotation(Z, angle + 0.5),
            origin + (0.01, 0, 0.005),
            ' rigid="true"',
            (part(f"{entity}-1", entity, rotation(Z, angle) @ rotation(X, math.pi), origin),),
        )
    )
    to = lambda a, b: math.atan2(*(np.asarray(b) - a)[::-1])
    instances = [
        Inst(
            "bed-1",
            "bed",
            np.eye(3),
            (0, 0.05, 0.02),
            ' rigid="true"',
            (
                part("bed plate-1", "bed plate", np.eye(3), (0, 0.05, 0.03)),
                part("guide block-1", "guide block", rail, (-0.06, 0.05, 0.02)),
                part("guide block-2", "guide block", rail, (0.06, 0.05, 0.02)),
            ),
        ),
        Inst(
            "base-1",
            "base",
            np.eye(3),
            (0, 0, 0),
            ' grounded="true" rigid="true"',
            (
                part("chassis-1", "chassis", np.eye(3), (0, 0.15, -0.01)),
                part("rail-1", "rail", rail, (-0.06, 0.0, 0.02)),
                part("rail-2", "rail", rail, (0.06, 0.0, 0.02)),
                *[
                    part(f"spacer-{i + 1}", "spacer", np.eye(3), at(o, height))
                    for i, o in enumerate((o1, o2, o2 + e))
                ],
                Inst(
                    "motor block-1",
                    "motor block",
                    np.eye(3),
                    (0, 0.1, -0.05),
                    ' grounded="true" rigid="true"',
                    tuple(
                        part(
                            f"stepper___ _____-{i + 1}", "stepper___ _____", np.eye(3), at(o, -0.05)
                        )
                        for i, o in enumerate((o1, o2))
                    ),
                ),
            ),
        ),
        link("crank-1", "crank", "arm link", at(o2 + e, height), theta_c),
        link("crank-2", "crank", "arm link", at(o1, height), theta_b),
        link("crank-3", "crank", "arm link", at(o2, height), theta_c),
        link("distal-1", "distal", "forearm", at(p1, height + 0.004), to(p1, n)),
        link("distal-2", "distal", "forearm", at(c, height + 0.004), to(c, n)),
        link("rocker-1", "rocker", "rocker plate", at(c, height - 0.004), 0.0),
        link("tie-1", "tie", "tie rod", at(c + g, height + 0.008), to(c, n)),
        Inst(
            "head-1",
            "head",
            rotation(Y, math.pi / 2),
            at(n, 0.06),
            ' rigid="true"',
            (
                part("carriage-1", "carriage", rotation(Y, math.pi / 2), at(n, 0.06)),
                part("extruder-1", "extruder", np.eye(3), at(n, 0.02)),
                *[
                    part(
                        f"fan___ 24v-{i}",
                        "fan___ 24v",
                        rotation(Z, i),
                        at(n + (0.02 * (-1) ** i, 0), 0.07),
                    )
                    for i in (1, 2)
                ],
            ),
        ),
    ]
    tree = doc.tree(*instances)
    m = doc.mate
    circle = lambda a, b, xy, z, name, tag="Coincident": m(
        tag, name, ("circle", a, at(xy, z), Z), ("circle", b, at(xy, z), Z)
    )
    face = lambda a, b, xy, z, name: m(
        "Coincident", name, ("plane", a, at(xy, z), Z), ("plane", b, at(xy, z), Z)
    )
    mates = [
        m(
            "Concentric",
            "Concentric1",
            ("cylinder", "base-1/rail-1", (-0.06, 0.2, 0.02), -Y),
            ("cylinder", "bed-1/guide block-1", (-0.06, 0.05, 0.02), -Y),
        ),
        m(
            "Concentric",
            "Concentric2",
            ("cylinder", "base-1/rail-2", (0.06, 0.2, 0.02), -Y),
            ("cylinder", "bed-1/guide block-2", (0.06, 0.05, 0.02), -Y),
        ),
        circle("base-1/spacer-1", "crank-2/arm link-1", o1, height, "Coincident1"),
        circle("base-1/spacer-2", "crank-3/arm link-1", o2, height, "Coincident2"),
        circle("base-1/spacer-3", "crank-1/arm link-1", o2 + e, height, "Coincident3"),
        circle("crank-3/arm link-1", "rocker-1/rocker plate-1", c, height, "Coincident4"),
        circle("crank-1/arm link-1", "rocker-1/rocker plate-1", c + e, height, "Coincident5"),
        circle("crank-2/arm link-1", "distal-1/forearm-1", p1, height + 0.004, "Coincident6"),
        circle("crank-3/arm link-1", "distal-2/forearm-1", c, height + 0.004, "Coincident7"),
        m(
            "Concentric",
            "Concentric3",
            ("circle", "distal-1/forearm-1", at(n, 0.038), Z),
            ("circle", "head-1/carriage-1", at(n, 0.06), -Z),
        ),
        circle("distal-2/forearm-1", "head-1/carriage-1", n, 0.038, "Concentric4", "Concentric"),
        face("distal-2/forearm-1", "head-1/carriage-1", n, 0.038, "Coincident8"),
        circle("head-1/carriage-1", "tie-1/tie rod-1", n + g, 0.042, "Concentric5", "Concentric"),
        face("head-1/carriage-1", "tie-1/tie rod-1", n + g, 0.042, "Coincident10"),
        m(
            "Concentric",
            "Concentric6",
            ("cylinder", "rocker-1/rocker plate-1", at(c + g, 0.03), -Z),
            ("cylinder", "tie-1/tie rod-1", at(c + g, 0.04), -Z),
        ),
    ]
    path = _write(
        folder,
        "printer.xml",
        gen2_export(
            tree,
            "",
            "".join(doc.parts),
            constraints="".join(mates),
            model_units=("millimeter", "kilogram"),
        ),
    )
    joints = {
        ("base-1", "bed-1"): "prismatic",
        ("base-1", "crank-1"): "revolute",
        ("base-1", "crank-2"): "revolute",
        ("base-1", "crank-3"): "revolute",
        ("crank-3", "rocker-1"): "revolute",
        ("crank-1", "rocker-1"): "revolute",
        ("crank-2", "distal-1"): "revolute",
        ("crank-3", "distal-2"): "revolute",
        ("distal-2", "head-1"): "revolute",
        ("head-1", "tie-1"): "revolute",
        ("distal-1", "head-1"): "cylindrical",
        ("rocker-1", "tie-1"): "cylindrical",
    }
    return Built(
        path,
        doc.mass(instances),
        {
            "joints": joints,
            "o1": o1,
            "o2": o2,
            "crank": crank,
            "forearm": forearm,
            "theta_b": theta_b,
            "theta_c": theta_c,
            "head": n,
        },
    )


# -- Onshape hexacopter: joints, centimetre documents, one sub-assembly used six times ---------


def onshape_copter(folder: Path, arms: int = 6) -> Built:
    """A multicopter as Onshape's Simscape exporter writes it: ``ModelUnits`` in centimetres and
    numbers in metres (``DataUnits``), printed with nine decimals; one arm-motor sub-assembly used
    ``arms`` times (its inner uids repeat) with the arm grounded in it, a ``Cylindrical`` and a
    ``Planar`` joint between the same arm and motor (together: the motor spins), a ``Revolute``
    propeller; the arms fastened to the hub by root ``Weld`` joints, some written hub-first and
    some arm-first."""
    hub = np.array([0.001, -0.002, -0.010])
    # in the arm's / motor's frame
    reach, motor_at, blade_at = (
        0.024,
        np.array([0.20, 0.0, 0.01]),
        np.array([0.0, 0.0, 0.025]),
    )
    doc = _Doc()
    cm = '<ModelUnits length="centimeter" mass="kilogram"/>'
    for uid, mass, com, name in (
        ("JHD*:*a5c1", 0.0203, (0, 0, 0.005), "Hub"),
        ("JHD*:*7e02", 0.0665, (0.1, 0, 0.005), "Arm"),
        ("JHD*:*30f9", 0.0172, (0, 0, 0.0102), "Motor"),
        ("JHD*:*c44b", 0.0041, (0, 0, 0.0005), "Blade"),
    ):
        doc.part(
            uid,
            mass,
            com,
            (2.7e-6, 2.4e-4, 2.4e-4, 0, 0, 0),
            name=name,
            geometry=f"{name}.step",
            extra=cm,
        )
    instances = [
        Inst("MhUb9+k2Tq", "JHD*:*a5c1", np.eye(3), hub, ' grounded="true"', name="Hub &lt;1&gt;")
    ]
    flip = rotation(X, math.pi)  # Onshape's mate frames often point z down
    blades = []
    for k in range(arms):
        phi = math.radians(15 + 360 * k / arms)
        arm_rot = rotation(Z, phi)
        arm_origin = hub + reach * arm_rot @ X
        motor_rot, motor_origin = arm_rot @ rotation(Z, 0.3), arm_origin + arm_rot @ motor_at
        blade_rot, blade_origin = motor_rot @ rotation(Z, 1.2), motor_origin + motor_rot @ blade_at
        blades.append(blade_origin)
        instances.append(
            Inst(
                f"Mq{k}Rx+{7 * k % 10}",
                "a9d2f4",
                np.eye(3),
                hub + (0.1 * k, -0.05, 0.03),
                name=f"Arm-Motor &lt;{k + 1}&gt;",
                children=(
                    Inst(
                        "MarmX7",
                        "JHD*:*7e02",
                        arm_rot,
                        arm_origin,
                        ' grounded="true"',
                        name="Arm &lt;1&gt;",
                    ),
                    Inst("MmotY3", "JHD*:*30f9", motor_rot, motor_origin, name="Motor &lt;1&gt;"),
                    Inst("Mbla/Z5", "JHD*:*c44b", blade_rot, blade_origin, name="Blade &lt;1&gt;"),
                ),
            )
        )
    tree = doc.tree(*instances)
    # the sub-assembly's joints, written once in its first instance's frames (the same in every instance)
    first = instances[1].uid
    arm, motor, blade = (f"{first}/{u}" for u in ("MarmX7", "MmotY3", f"Mbla{SLASH}Z5"))
    arm_rot, arm_origin = doc.poses[arm]
    motor_rot, motor_origin = doc.poses[motor]
    joint = lambda kind, name, a, b, rot, point: gen2_joint(
        kind, name, *doc.frame(a, rot, point, first), *doc.frame(b, rot, point, first)
    )
    inner = (
        joint("Cylindrical", "MotorShaft", arm, motor, arm_rot @ flip, motor_origin - 0.005 * Z)
        + joint(
            "Planar",
            "MotorSeat",
            arm,
            motor,
            arm_rot @ flip,
            arm_origin + arm_rot @ (0.104, 0, 0.01),
        )
        + joint(
            "Revolute", "Prop", motor, blade, motor_rot @ flip, motor_origin + motor_rot @ blade_at
        )
    )
    welds = []
    for k, inst in enumerate(instances[1:]):
        arm_key = f"{inst.uid}/MarmX7"
        rot, origin = doc.poses[arm_key]
        sides = [
            ("MhUb9+k2Tq", rot @ rotation(Y, -math.pi / 2)),
            (arm_key, rot @ rotation(Y, -math.pi / 2)),
        ]
        if k >= arms - 3:
            sides.reverse()
        welds.append(
            gen2_joint(
                "Weld",
                f"Fastened{k + 1}",
                *doc.frame(sides[0][0], sides[0][1], origin + 0.005 * Z),
                *doc.frame(sides[1][0], sides[1][1], origin + 0.005 * Z),
            )
        )
    assemblies = f'<Assembly name="Arm-Motor" uid="a9d2f4">{cm}<Constraints/><Joints>{inner}</Joints></Assembly>'
    text = gen2_export(
        tree, "".join(welds), "".join(doc.parts), assemblies, model_units=("centimeter", "kilogram")
    )
    path = _write(folder, "Copter.xml", _printed(text, ".9f"))
    return Built(path, doc.mass(instances), {"arms": arms, "blades": blades})


# -- issue 14: what the held-out real exports did wrong ----------------------------------------


def simscape_link_gen1(folder: Path) -> Built:
    """A first-generation file as Simscape Multibody Link 4.8 and later writes it: the same
    ``PhysicalModelingXMLFile`` with the model element named ``<SimscapeMultibody>`` instead of
    ``<SimMechanics>`` (a crank-rocker in millimetres and grams)."""
    design = FourBar(
        crank=30.0,
        coupler=95.0,
        rocker=70.0,
        ground=90.0,
        crank_angle0=math.radians(60),
        plane=rotation((0, 1, 0), 0.4),
        origin_mm=np.array([20.0, -10.0, 40.0]),
    )
    path = design.export(folder, write_meshes=False)
    text = path.read_text(encoding="utf-8")
    path.write_text(
        text.replace("<SimMechanics>", "<SimscapeMultibody>").replace(
            "</SimMechanics>", "</SimscapeMultibody>"
        ),
        encoding="utf-8",
    )
    return Built(path, 1e-3 * sum(design.masses().values()), {"fourbar": design})


def _lever_with_skeleton(folder: Path, name: str, lightest_kg: float) -> Built:
    """A lever pinned to a grounded base, a massless skeleton part (Creo's layout part) pinned to
    the lever's tip, and a small spring pin bolted into the lever by mates. The skeleton moves and
    has no mass; the spring pin is the lightest part (``lightest_kg``)."""
    o, tip, pin_at = (
        np.array([0.0, 0.0, 0.05]),
        np.array([0.12, 0.0, 0.05]),
        np.array([0.06, 0.0, 0.05]),
    )
    doc = _Doc()
    doc.part("BASE_prt", 1.0, (0, 0, 0), (2e-3, 2e-3, 3e-3, 0, 0, 0), name="BASE")
    doc.part("LEVER_prt", 0.2, (0.06, 0, 0), (1e-5, 2.5e-4, 2.5e-4, 0, 0, 0), name="LEVER")
    doc.part("SKEL_prt", 0.0, (0, 0, 0), (0, 0, 0, 0, 0, 0), name="SKEL")
    doc.part(
        "SPRING_PIN_prt",
        lightest_kg,
        (0, 0, 0),
        (lightest_kg * 1e-6,) * 3 + (0, 0, 0),
        name="SPRING_PIN",
    )
    instances = [
        Inst("1", "BASE_prt", np.eye(3), (0, 0, 0), ' grounded="true"', name="BASE"),
        Inst("2", "LEVER_prt", turned(1), o, name="LEVER"),
        Inst("3", "SKEL_prt", turned(2), tip, name="SKEL"),
        Inst("4", "SPRING_PIN_prt", turned(3), pin_at, name="SPRING_PIN"),
    ]
    tree = doc.tree(*instances)
    mates = [
        *doc.pin("hinge", "1", "2", o, Z),
        *doc.pin("layout", "2", "3", tip, Z),
        *doc.pin("press_fit", "2", "4", pin_at, Z),
        doc.mate(
            "Concentric",
            "press_fit_key",
            ("cylinder", "2", pin_at + 0.01 * X, Z),
            ("cylinder", "4", pin_at + 0.01 * X, Z),
        ),
    ]
    text = gen2_export(
        tree, "", "".join(doc.parts), length="meter", mass="kilogram", constraints="".join(mates)
    )
    return Built(
        _write(folder, name, text),
        doc.mass(instances),
        {
            "skeleton": "SKEL",
            "lightest": "SPRING_PIN",
            "joints": {("1", "2"): "revolute", ("2", "3"): "revolute"},
        },
    )


def massless_link_tiny_parts(folder: Path) -> Built:
    """Class 2: a massless moving part in an assembly whose lightest part weighs half a milligram:
    a stand-in of a thousandth of that has an inertia near 1e-18 kg*m^2, which MuJoCo refuses."""
    return _lever_with_skeleton(folder, "LEVER_TINY.xml", 5e-7)


def massless_skeleton_moving(folder: Path) -> Built:
    """Class 5: the same lever with a 10 g spring pin: a stand-in mass added to the skeleton would
    change the total by 1e-5 of it; the export's total must stay exact."""
    return _lever_with_skeleton(folder, "LEVER_SKEL.xml", 0.01)


def _pinned_four_bar(s, a, b, p, normal=Y):
    """Points of a four-bar: driven pivot S, crank pin A, rocker pin B, rocker pivot P."""
    return {
        "S": np.asarray(s, float),
        "A": np.asarray(a, float),
        "B": np.asarray(b, float),
        "P": np.asarray(p, float),
        "normal": normal,
    }


def _rigid(name: str, first_path, second_path, sides: bool = False) -> str:
    """Creo's ``<Rigid>`` constraint as Simscape Multibody Link 7.4 writes it (Creo 11): the two
    instances' ``InstancePath`` elements, no constraint geometry; ``sides``: each path inside a
    geometry-less ``ConstraintGeometry`` instead."""
    paths = [
        f"<InstancePath>{''.join(f'<Uid>{u}</Uid>' for u in path)}</InstancePath>"
        for path in (first_path, second_path)
    ]
    if sides:
        paths = [f'<ConstraintGeometry geomType="Unknown">{p}</ConstraintGeometry>' for p in paths]
    return f'<Rigid name="{name}">{"".join(paths)}</Rigid>'


def creo_ball_beam_rigid(folder: Path) -> Built:
    """Class 4: a ball-and-beam as Creo writes it: the servo bolted to the base and the ball
    holder bolted to the beam by ``<Rigid>`` constraints without constraint geometry (the first as
    Creo 11 writes it, the second with geometry-less sides); pins as
    axis-and-plane coincidences. The servo horn, the rod, the holder and the beam form the
    four-bar S-A-B-P: one freedom, one loop."""
    o = np.array([0.0, 0.0, 0.0])
    g = _pinned_four_bar(
        o + (0, 0, 0.05), o + (0.02, 0, 0.065), o + (0.15, 0, 0.12), o + (0.25, 0, 0.10)
    )
    doc = _Doc()
    spec = [
        ("BASE", "10", 0.5, o, np.eye(3), ' grounded="true"'),
        ("SERVO", "11", 0.06, o + (0, -0.02, 0.04), turned(1), ""),
        ("HORN", "12", 0.01, g["S"], turned(2), ""),
        ("ROD", "13", 0.008, g["A"], turned(3), ""),
        ("HOLDER", "14", 0.004, g["B"], turned(4), ""),
        ("BEAM", "15", 0.04, g["P"], turned(5), ""),
    ]
    instances = []
    for part, uid, mass, origin, rot, attrs in spec:
        doc.part(
            f"{part}_prt", mass, (0.001, 0.0, 0.002), (mass * 1e-4,) * 3 + (0, 0, 0), name=part
        )
        instances.append(Inst(uid, f"{part}_prt", rot, origin, attrs, name=part))
    tree = doc.tree(*instances)
    line_pin = lambda name, a, b, point: [  # noqa: E731  Creo: axis lines and planes coincide
        doc.mate(
            "Coincident",
            f"{name}_axis",
            ("line", a, point - 0.01 * Y, 0.02 * Y),
            ("line", b, point + 0.01 * Y, -0.02 * Y),
        ),
        doc.mate("Coincident", f"{name}_plane", ("plane", a, point, Y), ("plane", b, point, -Y)),
    ]
    mates = [
        _rigid("RIGID_1", ["10"], ["11"]),
        *line_pin("PIN_S", "11", "12", g["S"]),
        *line_pin("PIN_A", "12", "13", g["A"]),
        *line_pin("PIN_B", "13", "14", g["B"]),
        _rigid("RIGID_2", ["14"], ["15"], sides=True),
        *line_pin("PIN_P", "10", "15", g["P"]),
    ]
    text = gen2_export(
        tree, "", "".join(doc.parts), length="meter", mass="kilogram", constraints="".join(mates)
    )
    return Built(
        _write(folder, "BALLBEAM_CREO.xml", text),
        doc.mass(instances),
        {**g, "welded": [("BASE", "SERVO"), ("HOLDER", "BEAM")]},
    )


def ball_in_groove(folder: Path) -> Built:
    """Class 6: a beam on a pivot and a ball resting in its V groove, the ball held by two
    sphere-plane ``Tangent`` mates (SolidWorks). Simscape makes no joint from them."""
    p = np.array([0.0, 0.0, 0.1])
    ball_at = p + (0.05, 0, 0.012)
    # the groove's faces' normals
    left, right = (
        unit((0, 0.7071, 0.7071)),
        unit((0, -0.7071, 0.7071)),
    )
    r = 0.01
    doc = _Doc()
    doc.part("base*:*Default", 0.5, (0, 0, 0.02), (1e-3, 1e-3, 1e-3, 0, 0, 0))
    doc.part("beam*:*Default", 0.1, (0.05, 0, 0), (2e-5, 1e-4, 1e-4, 0, 0, 0))
    doc.part("ball*:*Default", 0.03, (0, 0, 0), (1.2e-6, 1.2e-6, 1.2e-6, 0, 0, 0))
    instances = [
        Inst("base-1", "base*:*Default", np.eye(3), (0, 0, 0), ' grounded="true"'),
        Inst("beam-1", "beam*:*Default", turned(1), p),
        Inst("ball-1", "ball*:*Default", turned(2), ball_at),
    ]
    tree = doc.tree(*instances)
    mates = [
        *doc.pin("Pivot", "base-1", "beam-1", p, Y),
        doc.mate(
            "Tangent",
            "Tangent1",
            ("sphere", "ball-1", ball_at, None),
            ("plane", "beam-1", ball_at - r * left, left),
        ),
        doc.mate(
            "Tangent",
            "Tangent2",
            ("plane", "beam-1", ball_at - r * right, right),
            ("sphere", "ball-1", ball_at, None),
        ),
    ]
    text = gen2_export(
        tree,
        "",
        "".join(doc.parts),
        constraints="".join(mates),
        model_units=("millimeter", "kilogram"),
    )
    return Built(
        _write(folder, "ballgroove.xml", text),
        doc.mass(instances),
        {"ball": "ball-1", "beam": "beam-1"},
    )


def planar_puck(
    folder: Path, tilt_axis=(0, 0, 1), tilt_angle: float = 0.6, digits: str = ".6g"
) -> Built:
    """Class 3: a puck face-mated to a table (a planar joint: its pivot is not fixed by the mates)
    and pinned to a link that turns on a bracket of the table, all away from the assembly origin;
    numbers printed to six digits as real exporters print them. The table is level, turned by
    ``tilt_angle`` about ``tilt_axis``."""
    tilt = rotation(tilt_axis, tilt_angle)
    n, ex = tilt[:, 2], tilt[:, 0]
    origin = np.array([0.9, -0.6, 0.3])  # the table stands away from the assembly origin
    pivot, pin = origin + 0.03 * n, origin + 0.08 * ex + 0.03 * n
    contact = pin - 0.03 * n  # the puck sits on the table here
    doc = _Doc()
    doc.part("table*:*Default", 2.0, (0, 0, -0.01), (0.02, 0.02, 0.04, 0, 0, 0))
    doc.part("link*:*Default", 0.05, (0.04, 0, 0), (1e-6, 3e-5, 3e-5, 0, 0, 0))
    doc.part("puck*:*Default", 0.2, (0, 0, 0.01), (8e-5, 8e-5, 1.5e-4, 0, 0, 0))
    instances = [
        Inst("table-1", "table*:*Default", tilt, origin, ' grounded="true"'),
        Inst("link-1", "link*:*Default", tilt @ rotation(Z, 0.3), pivot),
        Inst("puck-1", "puck*:*Default", tilt @ rotation(Z, 1.1), contact),
    ]
    tree = doc.tree(*instances)
    mates = [
        *doc.pin("Bracket", "table-1", "link-1", pivot, n),
        *doc.pin("Knob", "link-1", "puck-1", pin, n),
        doc.mate(
            "Coincident", "Face", ("plane", "table-1", contact, n), ("plane", "puck-1", contact, -n)
        ),
    ]
    text = gen2_export(
        tree,
        "",
        "".join(doc.parts),
        constraints="".join(mates),
        model_units=("millimeter", "kilogram"),
    )
    return Built(
        _write(folder, "puck.xml", _printed(text, digits)),
        doc.mass(instances),
        {
            "normal": n,
            "contact": contact,
            "pin": pin,
            "pivot": pivot,
            "planar": ("table-1", "puck-1"),
        },
    )


def conveyor_with_origin_mates(folder: Path, rollers: int = 50, bolts: int = 4) -> Built:
    """Class 7: a large assembly (``rollers`` * (1 + ``bolts``) + 22 instances): a swing arm pinned
    to a grounded frame carries rollers, each a rigid sub-assembly pinned to the arm; every roller's
    axis is also mated ``Coincident`` with the assembly's Top Plane (the origin, an empty
    ``InstancePath``), which places it but leaves it four freedoms against the world. Simscape
    makes joints only from the pins: the arm's and each roller's spin."""
    pitch, arm_length = 0.03, 0.03 * (rollers + 1)
    doc = _Doc()
    doc.part("frame*:*Default", 20.0, (0.5, 0, -0.1), (1.0, 1.0, 1.5, 0, 0, 0))
    doc.part("arm*:*Default", 3.0, (arm_length / 2, 0, 0), (0.01, 0.5, 0.5, 0, 0, 0))
    doc.part("roller*:*Default", 0.15, (0, 0, 0), (6e-5, 6e-5, 2e-5, 0, 0, 0))
    doc.part("bolt*:*Default", 0.004, (0, 0, 0.005), (1e-8, 1e-8, 5e-9, 0, 0, 0))
    axle = rotation(X, -math.pi / 2)  # the rollers' z along the world y
    frame_bolts = tuple(
        Inst(
            f"bolt-{i + 1}", "bolt*:*Default", np.eye(3), (0.05 * i, 0.1, -0.1), ' grounded="true"'
        )
        for i in range(20)
    )
    instances = [
        Inst(
            "frame-1",
            "frame",
            np.eye(3),
            (0, 0, 0),
            ' grounded="true" rigid="true"',
            (
                Inst("frame-1", "frame*:*Default", np.eye(3), (0, 0, -0.05), ' grounded="true"'),
                *frame_bolts,
            ),
        ),
        Inst("arm-1", "arm*:*Default", turned(1), (0, 0, 0)),
    ]
    centres = [np.array([pitch * (k + 1), 0.0, 0.0]) for k in range(rollers)]
    for k, c in enumerate(centres):
        inner = (
            Inst(
                "roller-1", "roller*:*Default", axle @ rotation(Z, 0.2 * k), c, ' grounded="true"'
            ),
            *[
                Inst(
                    f"bolt-{j + 1}",
                    "bolt*:*Default",
                    axle,
                    c + 0.005 * np.array([math.cos(j), 0, math.sin(j)]),
                )
                for j in range(bolts)
            ],
        )
        instances.append(Inst(f"roller-{k + 1}", "roller", axle, c, ' rigid="true"', inner))
    tree = doc.tree(*instances)
    top_plane = ("plane", [], (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))  # the assembly's own Top Plane
    mates = doc.pin("Swing", "frame-1/frame-1", "arm-1", np.zeros(3), Y)
    for k, c in enumerate(centres):
        key = f"roller-{k + 1}/roller-1"
        mates += doc.pin(f"Axle{k + 1}", "arm-1", key, c, Y)
        mates.append(
            gen2_mate("Coincident", f"OnTop{k + 1}", top_plane, doc.side("line", key, c, Y))
        )
    assemblies = gen2_assembly("frame") + gen2_assembly("roller")
    text = gen2_export(
        tree,
        "",
        "".join(doc.parts),
        assemblies,
        constraints="".join(mates),
        model_units=("millimeter", "kilogram"),
    )
    n_instances = 2 + len(frame_bolts) + rollers * (1 + bolts)
    return Built(
        _write(folder, "conveyor.xml", text),
        doc.mass(instances),
        {"rollers": rollers, "instances": n_instances, "arm": "frame-1--arm-1"},
    )
