"""The machine description: what a CAD export cannot say, written once in a TOML file.

A CAD export carries parts, joints, masses and couplings. It does not say which joint the
motor turns, which shaft the recordings and the cycle refer to, where that shaft's zero
is, the motor's datasheet or the friction. The description does, and every verb reads it::

    [machine]
    name = "press"
    model = "press.xml"                              # converted MJCF, or a CAD export (converted on first use)
    [drive]
    motor_joint = "MOTOR_HOUSING-1--MOTOR_ROTOR-1"   # the joint the motor turns
    shaft_joint = "BASE_FRAME-1--CRANKSHAFT-1"       # main shaft: recordings' angle, the cycle's driver
    zero_site = "RAM-1"                              # shaft angle 0 where this site is highest against gravity
    [motor]
    type = "dc"
    resistance_ohm = 2.6
    torque_constant_Nm_per_A = 0.045
    back_emf_V_s_per_rad = 0.045
    [friction."BASE_FRAME-1--CRANKSHAFT-1"]
    coulomb_Nm = 0.6
    viscous_Nm_s_per_rad = 0.01
    [tool]
    site = "RAM-1"
    plate = "DIE_PLATE-1"

Units are in every key name. Unknown keys and sections are errors with a did-you-mean;
every value is checked for type and physical range. Names are checked against the model
by :mod:`mechanism.machine.machine` (it needs the model). :data:`SCHEMA` is the one list of
keys; docs/machine.md is generated from the same table by a test.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, get_args

from mechanism.errors import UserError, close_matches

MAX_DESCRIPTION_BYTES = 1 << 20


@dataclass(frozen=True)
class Key:
    """One key of the description: its type, its physical range and what it means."""

    kind: type | tuple[type, ...]
    doc: str
    required: bool = False
    low: float | None = None  # inclusive unless ``open_low``
    high: float | None = None
    open_low: bool = False
    choices: tuple[str, ...] = ()
    item: type | None = None  # element type of a list


def _positive(doc: str, required: bool = False, high: float | None = None) -> Key:
    return Key(float, doc, required, low=0.0, open_low=True, high=high)


def _non_negative(doc: str, high: float | None = None, required: bool = False) -> Key:
    return Key(float, doc, required, low=0.0, high=high)


def _name(doc: str, required: bool = False) -> Key:
    return Key(str, doc, required)


FRICTION_KEYS = {
    "coulomb_Nm": _non_negative("kinetic Coulomb level [N m] (N on a slide)", 1e4),
    "viscous_Nm_s_per_rad": _non_negative(
        "viscous coefficient [N m s/rad] (N s/m on a slide)", 1e4
    ),
    "static_Nm": _non_negative("break-away level [N m], at least coulomb_Nm (default: equal)", 1e4),
    "stribeck": Key(
        str,
        "decay from static to Coulomb level with speed",
        choices=("none", "tustin", "hess-soom"),
    ),
    "stribeck_velocity_rad_s": _non_negative("Stribeck decay speed [rad/s]", 1e4),
    "tustin_exponent": Key(float, "Tustin exponent", low=0.1, high=5.0),
    "position_amplitude": Key(
        float,
        "running level varies as 1 + a cos(k q - phase) over the position joint",
        low=0.0,
        high=0.99,
    ),
    "static_position_amplitude": Key(
        float, "the same for the break-away level (default: position_amplitude)", low=0.0, high=0.99
    ),
    "position_phase_deg": Key(
        float, "phase of the position dependence [deg]", low=-360.0, high=360.0
    ),
    "position_harmonic": Key(
        float, "k: cycles per turn of the position joint", low=0.0, high=100.0
    ),
    "position_joint": _name("joint whose angle sets the position dependence (default: its own)"),
}

MotorType = Literal["dc", "servo", "current"]  # a [motor] table's type: the drive kind
MOTOR_TYPES: tuple[MotorType, ...] = get_args(MotorType)
# keys each drive kind needs (besides type), and the input its command is in
MOTOR_REQUIRED: dict[MotorType, tuple[str, ...]] = {
    "dc": ("resistance_ohm", "torque_constant_Nm_per_A", "back_emf_V_s_per_rad"),
    "servo": (
        "resistance_ohm",
        "torque_constant_Nm_per_A",
        "back_emf_V_s_per_rad",
        "supply_V",
        "kp_V_per_rad",
    ),
    "current": ("torque_constant_Nm_per_A",),
}
MOTOR_INPUT_UNIT: dict[MotorType, str] = {"dc": "V", "servo": "rad", "current": "A"}

LIMIT_KEYS = {
    "lower_deg": Key(
        float,
        "a hinge's lower hard stop [deg], its own coordinate (0 at the export's pose)",
        low=-3600.0,
        high=3600.0,
    ),
    "upper_deg": Key(float, "a hinge's upper hard stop [deg]", low=-3600.0, high=3600.0),
    "lower_mm": Key(
        float,
        "a slide's lower hard stop [mm], its own coordinate (0 at the export's pose)",
        low=-1e5,
        high=1e5,
    ),
    "upper_mm": Key(float, "a slide's upper hard stop [mm]", low=-1e5, high=1e5),
}

SCHEMA: dict[str, dict[str, Key]] = {
    "machine": {
        "name": _name("a name for reports", required=True),
        "model": _name("converted MJCF or CAD export, relative to this file", required=True),
        "timestep_ms": Key(
            float, "simulation time step [ms]; loops and belts stiffen with it", low=0.01, high=2.0
        ),
        "ground": _name(
            "the part fixed to the world (default: the export's ground, else its heaviest part)"
        ),
        "up": Key(
            str,
            "the export's axis that points up, for a CAD export (default: its gravity vector, else z)",
            choices=("x", "y", "z", "-x", "-y", "-z", "+x", "+y", "+z"),
        ),
    },
    "drive": {
        "motor_joint": _name(
            'the joint the motor turns (with [motor]; optional with [motor."JOINT"] tables: '
            "the first is the main motor)"
        ),
        "shaft_joint": _name(
            "the main shaft: recordings' angle and the cycle's driver", required=True
        ),
        "zero_site": _name(
            "the shaft angle is 0 where this site is highest against gravity (or zero_angle_deg)"
        ),
        "zero_angle_deg": Key(
            float,
            "the shaft angle's 0 as the shaft joint's own coordinate [deg], where no site "
            "rises and falls (a vertical shaft)",
            low=-3600.0,
            high=3600.0,
        ),
        "range_deg": Key(
            list,
            "[lower, upper] shaft joint coordinates [deg] inspected for a drive that rocks "
            "(default: its limits)",
            item=float,
        ),
    },
    "motor": {
        "type": Key(
            str,
            "drive kind: a DC motor (input: voltage), a servo (a DC motor behind a position loop; input: "
            "the goal angle) or a current drive (input: the current command)",
            required=True,
            choices=MOTOR_TYPES,
        ),
        "resistance_ohm": _positive("armature resistance [ohm] (dc, servo)", high=1e4),
        "torque_constant_Nm_per_A": _positive(
            "torque constant Kt [N m/A]", required=True, high=100.0
        ),
        "back_emf_V_s_per_rad": _positive("back-EMF constant Ke [V s/rad] (dc, servo)", high=100.0),
        "supply_V": _positive("servo: the supply voltage its driver switches [V]", high=1e3),
        "kp_V_per_rad": _non_negative("servo: proportional gain of the position loop [V/rad]", 1e6),
        "kd_V_s_per_rad": _non_negative(
            "servo: derivative gain of the position loop [V s/rad] (default 0)", 1e4
        ),
        "duty_limit": Key(
            float,
            "servo: the largest duty its driver puts out, a fraction of supply_V (default 1)",
            low=0.0,
            open_low=True,
            high=1.0,
        ),
        "max_current_A": _positive(
            "current drive: the amplifier's current limit [A] (default: none)", high=1e4
        ),
        "inductance_H": _non_negative("winding inductance [H] (0: quasi-static current)", 10.0),
        "rated_voltage_V": _positive(
            "the highest terminal voltage a run may apply [V] (default 30)", high=1e3
        ),
        "cogging_Nm": _non_negative("cogging torque amplitude [N m]", 100.0),
        "cogging_per_rev": Key(int, "cogging periods per motor turn", low=1, high=1000),
        "thermal_resistance_K_per_W": _positive(
            "winding-to-ambient thermal resistance [K/W]", high=1e3
        ),
        "thermal_time_constant_s": _positive("winding thermal time constant [s]", high=1e6),
    },
    "supply": {
        "voltage_V": _positive("supply voltage of the PWM switch [V]", high=1e3),
        "series_resistance_ohm": _non_negative(
            "switch on-resistance and wiring: the motor sees at most "
            "voltage_V minus this times the current",
            1e3,
        ),
        "duty_percent": Key(
            list, "PWM duty points [%] of the measured duty -> motor voltage map", item=float
        ),
        "motor_voltage_V": Key(list, "motor terminal voltage [V] at each duty point", item=float),
    },
    "warm": {
        "time_constant_s": _positive(
            "warming time constant [s]: level(t) = warm + (cold - warm) exp(-t/tau)", high=1e6
        ),
    },
    "loads": {
        "belt_tension_low_Nm": Key(
            float, "extra shaft Coulomb friction at low belt tension [N m]", low=-1e3, high=1e3
        ),
        "belt_tension_hard_Nm": Key(
            float, "extra shaft Coulomb friction at hard belt tension [N m]", low=-1e3, high=1e3
        ),
        "feeding_joint": _name("joint the feed mechanism loads when engaged"),
        "feeding_coulomb_Nm": _non_negative("extra Coulomb friction on feeding_joint [N m]", 1e3),
    },
    "tool": {
        "site": _name("the tool's working point (a needle tip, a ram tip)"),
        "plate": _name("the part the tool works against; heights are measured from its top"),
        "eye_site": _name("a second point on the tool's axis (a needle eye), for hook timing"),
        "part": _name("the tool's own part, for clearance to the hook"),
        "layer_thickness_mm": _positive("fabric layer thickness [mm]", high=50.0),
        "piercing_force_per_layer_N": _non_negative("force to pierce one layer [N]", 1e3),
        "drag_fraction": Key(
            float, "withdrawal drag as a fraction of the piercing force", low=0.0, high=1.0
        ),
        "point_taper_mm": _positive(
            "length over which the piercing force builds up [mm]", high=50.0
        ),
    },
    "stepper": {
        "type": _name("the stepper motors' type, for reports"),
        "step_angle_deg": _positive(
            "full-step angle [deg] (two-phase: 360 / (4 pole_pairs))", required=True, high=90.0
        ),
        "pole_pairs": Key(
            int, "pole pairs p of the torque equation", required=True, low=1, high=1000
        ),
        "holding_torque_Nm": _positive(
            "holding torque, two phases on at the rated current [N m]", required=True, high=100.0
        ),
        "detent_torque_Nm": _non_negative(
            "detent (unpowered cogging) torque amplitude [N m]", 100.0, required=True
        ),
        "rated_current_A": _positive(
            "chopper (peak) current per phase [A]", required=True, high=100.0
        ),
        "resistance_ohm": _positive("phase resistance [ohm]", required=True, high=1e4),
        "inductance_H": _positive("phase inductance [H]", required=True, high=10.0),
        "supply_V": _positive("chopper supply voltage [V]", required=True, high=1e3),
        "chopper_hz": _positive("chopper oscillator frequency [Hz]", required=True, high=1e7),
        "rotor_inertia_kg_m2": _positive("rotor inertia [kg m^2]", required=True, high=1.0),
        "damping_Nm_s_rad": _non_negative("viscous damping c [N m s/rad]", 10.0, required=True),
        "step_rate_steps_s": _positive(
            "the drive's usual slew rate [full steps/s] (default --rate)", high=1e5
        ),
    },
    "thread_cut": {
        "forward_s": _positive(
            "the cutter's stroke out: time at the step rate [s]", required=True, high=60.0
        ),
        "back_s": _positive(
            "back to the start: time at the step rate [s]", required=True, high=60.0
        ),
    },
    "hook": {
        "joint": _name("the rotary hook's joint"),
        "site": _name("the hook's point"),
    },
    "lumped": {
        "inertia_motor_side_kgm2": _positive(
            "the whole machine's inertia seen at the motor, as a lumped model identified it",
            high=1e3,
        ),
        "coulomb_shaft_Nm": _non_negative(
            "the whole machine's kinetic Coulomb friction at the shaft [N m]", 1e4
        ),
        "viscous_motor_side_Nm_s_per_rad": _non_negative(
            "the whole machine's viscous coefficient at the motor [N m s/rad]", 1e4
        ),
    },
    "recording": {
        "records": _name(
            "JSON recordings: the key holding the list of records (dotted for nested objects; default: the top level)"
        ),
        "time": _name(
            "time column, or a product/quotient of columns and numbers (default: time, time_s, t)"
        ),
        "time_unit": Key(
            str, "unit of time after the expression (default s)", choices=("s", "ms", "us")
        ),
        "signed_bits": Key(
            dict,
            "registers logged unsigned that hold two's-complement values, column = bits (65535 -> -1 at 16)",
            item=int,
        ),
        "voltage": _name("motor voltage [V] after the expression (default: voltage, voltage_V)"),
        "shaft_angle": _name(
            "the described shaft's angle, a column or expression (default: shaft_angle, arm_angle, ..._rad)"
        ),
        "shaft_angle_unit": Key(
            str,
            "unit of shaft_angle (default rad)",
            choices=("rad", "deg", "rev", "counts", "m", "mm"),
        ),
        "counts_per_rev": Key(
            int,
            "encoder counts per shaft turn: the unit of counts, and the encoder resolution",
            low=4,
            high=1e9,
        ),
        "travel_per_rev_mm": _positive(
            "with m or mm: travel per shaft turn [mm] (a screw's lead, a pulley's circumference)",
            high=1e6,
        ),
        "direction": Key(
            int,
            "+1, or -1 to flip the sign: shaft_angle = direction * angle + offset_rad",
            low=-1,
            high=1,
        ),
        "offset_rad": Key(float, "added after the direction [rad]", low=-1e6, high=1e6),
        "unwrap": Key(
            bool,
            "unwrap jumps of more than half a turn (default: only when the angle is found wrapped, with a warning)",
        ),
        "current": _name("motor current [A], a column or expression (default: current, current_A)"),
    },
    "inspect": {
        "probes": Key(list, "probes of the demo, 'point_or_joint:quantity'", item=str),
        "clearance_pairs": Key(list, "part pairs the demo checks, 'A:B'", item=str),
        "required_clearance_mm": _non_negative("smallest acceptable clearance [mm]", 1e3),
        "probe_speed_rpm": _positive("shaft speed of the demo's probe cycle [rpm]", high=1e5),
        "mistimed_variant": _name("the demo's faulty design variant, 'parameter=offset'"),
        "flywheel_voltages_V": Key(
            list,
            "motor voltages of the demo's flywheel sweep (inertia added on the shaft)",
            item=float,
        ),
    },
}
# Sections keyed by joint name; their keys are FRICTION_KEYS.
JOINT_TABLES = {"friction": FRICTION_KEYS, "warm_friction": FRICTION_KEYS, "limits": LIMIT_KEYS}
# Named variant-parameter targets (mechanism-variants/1 syntax) the machine offers.
PRESET_TABLE = "variant_presets"


@dataclass(frozen=True)
class MachineDescription:
    """A validated description. ``path`` is the TOML file (None when built in code)."""

    name: str
    model: Path
    motor_joint: str
    shaft_joint: str
    zero_site: str | None
    motor: dict[str, Any]  # the main motor's table (motor_joint's)
    friction: dict[str, dict[str, Any]] = field(default_factory=dict)
    # joint -> its motor table, the main one first
    motors: dict[str, dict[str, Any]] = field(default_factory=dict)
    # joint -> (lower, upper) [rad or m]
    limits: dict[str, tuple[float, float]] = field(default_factory=dict)
    # joint -> "deg" (a hinge's) or "mm" (a slide's)
    limit_units: dict[str, str] = field(default_factory=dict)
    warm_friction: dict[str, dict[str, Any]] = field(default_factory=dict)
    # the optional sections as written
    sections: dict[str, dict[str, Any]] = field(default_factory=dict)
    variant_presets: dict[str, str] = field(default_factory=dict)
    path: Path | None = None

    def section(self, name: str) -> dict[str, Any]:
        return self.sections.get(name, {})

    @property
    def tool_site(self) -> str | None:
        return self.section("tool").get("site")

    @property
    def drive_tables(self) -> dict[str, dict[str, Any]]:
        """joint -> motor table, the main motor first (its table is ``motor``, which edits replace)."""
        return {
            self.motor_joint: self.motor,
            **{j: t for j, t in self.motors.items() if j != self.motor_joint},
        }

    @property
    def zero_angle_rad(self) -> float | None:
        value = self.section("drive").get("zero_angle_deg")
        return None if value is None else math.radians(value)

    @property
    def range_rad(self) -> tuple[float, float] | None:
        value = self.section("drive").get("range_deg")
        return None if value is None else (math.radians(value[0]), math.radians(value[1]))

    @property
    def timestep_s(self) -> float | None:
        value = self.section("machine").get("timestep_ms")
        return None if value is None else value * 1e-3

    def where(self, section: str, key: str | None = None) -> str:
        """'file: [section] key' for error messages."""
        place = f"[{section}]" + (f" {key}" if key else "")
        return f"{self.path}: {place}" if self.path else place


def _fail(source: str, section: str, key: str | None, reason: str) -> UserError:
    place = f"[{section}]" + (f" {key}" if key else "")
    return UserError(f"machine description {source}: {place}: {reason}")


def check_value(source: str, section: str, name: str, key: Key, value: Any) -> Any:
    def bad(reason: str) -> UserError:
        return _fail(source, section, name, reason)

    if key.kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if key.kind is dict:
        if not isinstance(value, dict):
            raise bad(f"expected a table such as {{ name = 16 }}, got {type(value).__name__}")
        item = Key(
            key.item or str,
            key.doc,
            low=2 if key.item is int else None,
            high=64 if key.item is int else None,
        )
        return {k: check_value(source, section, f"{name}.{k}", item, v) for k, v in value.items()}
    if key.kind is bool:
        if not isinstance(value, bool):
            raise bad(f"expected true or false, got {value!r}")
        return value
    if key.kind is list:
        if not isinstance(value, list):
            raise bad(f"expected a list, got {type(value).__name__}")
        return [
            check_value(source, section, f"{name}[{i}]", Key(key.item or str, key.doc), v)
            for i, v in enumerate(value)
        ]
    if not isinstance(value, key.kind) or isinstance(value, bool):
        raise bad(f"expected {'a number' if key.kind in (float, int) else 'text'}, got {value!r}")
    if isinstance(value, float) and not math.isfinite(value):
        raise bad(f"must be a finite number, got {value}")
    if key.choices and value not in key.choices:
        raise bad(f"{value!r} is not one of {', '.join(key.choices)}")
    if isinstance(value, str) and not value.strip():
        raise bad("must not be empty")
    if isinstance(value, (int, float)):
        if key.low is not None and (value <= key.low if key.open_low else value < key.low):
            raise bad(
                f"{value:g} is out of range: must be {'>' if key.open_low else '>='} {key.low:g} ({key.doc})"
            )
        if key.high is not None and value > key.high:
            raise bad(f"{value:g} is out of range: must be <= {key.high:g} ({key.doc})")
    return value


def _check_table(source: str, section: str, table: Any, keys: dict[str, Key]) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise _fail(source, section, None, "expected a table of keys")
    out = {}
    for name, value in table.items():
        if name not in keys:
            raise _fail(
                source, section, name, f"unknown key; did you mean {close_matches(name, keys)}?"
            )
        out[name] = check_value(source, section, name, keys[name], value)
    for name, key in keys.items():
        if key.required and name not in out:
            raise _fail(source, section, name, f"missing ({key.doc})")
    return out


def _check_friction(source: str, section: str, laws: dict[str, Any]) -> dict[str, dict[str, Any]]:
    out = {}
    for joint, table in laws.items():
        law = _check_table(source, f'{section}."{joint}"', table, FRICTION_KEYS)
        if "static_Nm" in law and law["static_Nm"] < law.get("coulomb_Nm", 0.0):
            raise _fail(
                source,
                f'{section}."{joint}"',
                "static_Nm",
                "the break-away level is below the Coulomb level",
            )
        out[joint] = law
    return out


def _check_limits(
    source: str, tables: Any
) -> tuple[dict[str, tuple[float, float]], dict[str, str]]:
    """[limits."JOINT"]: lower and upper, both in degrees (a hinge) or both in mm (a slide), in SI."""
    if not isinstance(tables, dict):
        raise _fail(source, "limits", None, 'expected [limits."JOINT"] tables')
    out, units = {}, {}
    for joint, table in tables.items():
        section = f'limits."{joint}"'
        values = _check_table(source, section, table, LIMIT_KEYS)
        for unit, scale in (("deg", math.pi / 180.0), ("mm", 1e-3)):
            pair = [values.get(f"lower_{unit}"), values.get(f"upper_{unit}")]
            if pair == [None, None]:
                continue
            if None in pair or len(values) != 2:
                raise _fail(
                    source,
                    section,
                    None,
                    "needs lower_deg and upper_deg (a hinge) or lower_mm and upper_mm "
                    "(a slide), one pair",
                )
            # both given (checked above)
            lower, upper = (
                float(pair[0] or 0.0),
                float(pair[1] or 0.0),
            )
            if not upper > lower:
                raise _fail(
                    source, section, f"upper_{unit}", f"must be above lower_{unit} ({lower:g})"
                )
            out[joint] = (lower * scale, upper * scale)
            units[joint] = unit
        if joint not in out:
            raise _fail(
                source,
                section,
                None,
                "needs lower_deg and upper_deg (a hinge) or lower_mm and upper_mm (a slide)",
            )
    return out, units


def _check_motor(source: str, section: str, table: Any) -> dict[str, Any]:
    motor = _check_table(source, section, table, SCHEMA["motor"])
    kind = motor["type"]
    for key in MOTOR_REQUIRED[kind]:
        if key not in motor:
            raise _fail(
                source,
                section,
                key,
                f"missing ({SCHEMA['motor'][key].doc}; a {kind} drive needs it)",
            )
    allowed = set(MOTOR_REQUIRED[kind]) | {"type", "cogging_Nm", "cogging_per_rev"}
    allowed |= {
        "dc": {
            "inductance_H",
            "thermal_resistance_K_per_W",
            "thermal_time_constant_s",
            "rated_voltage_V",
        },
        "servo": {"kd_V_s_per_rad", "duty_limit"},
        "current": {"max_current_A"},
    }[kind]
    for key in motor:
        if key not in allowed:
            raise _fail(source, section, key, f"not a key of a {kind} drive (type = {kind!r})")
    return motor


def _check_motors(
    source: str, data: dict[str, Any], drive: dict[str, Any]
) -> tuple[str, dict[str, dict[str, Any]]]:
    """(the main motor's joint, joint -> motor table): ``[motor]`` with ``[drive] motor_joint``, or
    ``[motor."JOINT"]`` tables (the main one: motor_joint when given, else the first)."""
    raw = data["motor"]
    if not isinstance(raw, dict):
        raise _fail(source, "motor", None, 'expected a table of keys, or [motor."JOINT"] tables')
    tables = {k: v for k, v in raw.items() if isinstance(v, dict)}
    if tables and len(tables) != len(raw):
        loose = next(k for k in raw if k not in tables)
        raise _fail(
            source,
            "motor",
            loose,
            "give either [motor] keys (one motor, with [drive] motor_joint) or "
            '[motor."JOINT"] tables, not both',
        )
    if not tables:
        if "motor_joint" not in drive:
            raise _fail(
                source,
                "drive",
                "motor_joint",
                'missing (the joint the motor turns; or give [motor."JOINT"] tables)',
            )
        return drive["motor_joint"], {drive["motor_joint"]: _check_motor(source, "motor", raw)}
    motors = {
        joint: _check_motor(source, f'motor."{joint}"', table) for joint, table in tables.items()
    }
    main = drive.get("motor_joint", next(iter(motors)))
    if main not in motors:
        raise _fail(
            source,
            "drive",
            "motor_joint",
            f'{main!r} has no [motor."{main}"] table; tables: {", ".join(motors)}',
        )
    return main, {main: motors[main], **{j: m for j, m in motors.items() if j != main}}


def parse_description(
    data: dict[str, Any], source: str = "<description>", base: Path | None = None
) -> MachineDescription:
    """Validate a parsed TOML document. Relative model paths resolve against ``base``."""
    known = [*SCHEMA, *JOINT_TABLES, PRESET_TABLE]
    for section in data:
        if section not in known:
            raise _fail(
                source,
                section,
                None,
                f"unknown section; did you mean {close_matches(section, known)}?",
            )
    for section in ("machine", "drive", "motor"):
        if section not in data:
            raise _fail(source, section, None, "missing section")
    sections = {
        name: _check_table(source, name, data[name], keys)
        for name, keys in SCHEMA.items()
        if name in data and name != "motor"
    }
    motor_joint, motors = _check_motors(source, data, sections["drive"])
    sections["motor"] = motors[motor_joint]
    supply = sections.get("supply", {})
    if len(supply.get("duty_percent", [])) != len(supply.get("motor_voltage_V", [])):
        raise _fail(source, "supply", "motor_voltage_V", "needs one voltage per duty_percent point")
    duties = supply.get("duty_percent", [])
    if any(b <= a for a, b in zip(duties, duties[1:])) or any(not 0 <= d <= 100 for d in duties):
        raise _fail(source, "supply", "duty_percent", "points must increase within 0-100 %")
    stepper = sections.get("stepper", {})
    if stepper and not math.isclose(360.0 / stepper["step_angle_deg"], 4 * stepper["pole_pairs"]):
        raise _fail(
            source,
            "stepper",
            "step_angle_deg",
            f"a two-phase motor with {stepper['pole_pairs']} pole pairs steps {90.0 / stepper['pole_pairs']:g} deg, "
            f"not {stepper['step_angle_deg']:g}",
        )
    if "thread_cut" in sections and "step_rate_steps_s" not in stepper:
        raise _fail(
            source,
            "thread_cut",
            None,
            "needs [stepper] with step_rate_steps_s (the stroke runs at that rate)",
        )
    presets = data.get(PRESET_TABLE, {})
    if not isinstance(presets, dict) or not all(isinstance(v, str) for v in presets.values()):
        raise _fail(source, PRESET_TABLE, None, 'expected name = "target" pairs')
    model = Path(sections["machine"]["model"])
    if not model.is_absolute():
        # "../mjcf/x.xml" reads as the folder it is in
        model = Path(os.path.normpath((base or Path.cwd()) / model))
    drive = sections["drive"]
    limits, limit_units = _check_limits(source, data.get("limits", {}))
    if "zero_site" not in drive and "zero_angle_deg" not in drive:
        raise _fail(
            source,
            "drive",
            "zero_site",
            "missing: name the site whose highest point is the shaft angle's 0, "
            "or give zero_angle_deg (the shaft joint's coordinate of that 0)",
        )
    if "zero_site" in drive and "zero_angle_deg" in drive:
        raise _fail(source, "drive", "zero_angle_deg", "give zero_site or zero_angle_deg, not both")
    if "range_deg" in drive and (
        len(drive["range_deg"]) != 2 or not drive["range_deg"][1] > drive["range_deg"][0]
    ):
        raise _fail(
            source, "drive", "range_deg", "expected [lower, upper] in degrees, lower below upper"
        )
    return MachineDescription(
        name=sections["machine"]["name"],
        model=model,
        motor_joint=motor_joint,
        shaft_joint=drive["shaft_joint"],
        zero_site=drive.get("zero_site"),
        motor=sections["motor"],
        motors=motors,
        friction=_check_friction(source, "friction", data.get("friction", {})),
        warm_friction=_check_friction(source, "warm_friction", data.get("warm_friction", {})),
        limits=limits,
        limit_units=limit_units,
        sections=sections,
        variant_presets=dict(presets),
    )


def read_description(path: str | os.PathLike) -> MachineDescription:
    """Read and validate a description file (bounded size, TOML, every key checked)."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            raw = handle.read(MAX_DESCRIPTION_BYTES + 1)
    except IsADirectoryError:
        raise UserError(
            f"machine description {path}: is a directory, expected a TOML file"
        ) from None
    except OSError as exc:
        raise UserError(f"machine description {path}: {exc.strerror or exc}") from None
    if len(raw) > MAX_DESCRIPTION_BYTES:
        raise UserError(
            f"machine description {path}: larger than {MAX_DESCRIPTION_BYTES >> 10} KiB"
        )
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"machine description {path}: not valid TOML: {exc}") from None
    # a link to a shipped description resolves its model beside the real file
    resolved = path.resolve()
    description = parse_description(data, str(path), resolved.parent)
    return _with_path(description, path)


def _with_path(description: MachineDescription, path: Path) -> MachineDescription:
    from dataclasses import replace

    return replace(description, path=path)


def _kind_name(key: Key) -> str:
    if key.choices:
        return " \\| ".join(f'`"{c}"`' for c in key.choices)
    if key.kind is list:
        return f"list of {'numbers' if key.item is float else 'text'}"
    if key.kind is dict:
        return "table of whole numbers"
    if key.kind is bool:
        return "true \\| false"
    names: dict[object, str] = {float: "number", int: "whole number", str: "text"}
    return names.get(key.kind, str(key.kind))


def _range(key: Key) -> str:
    if key.low is None and key.high is None:
        return ""
    low = "" if key.low is None else f"{'>' if key.open_low else '>='} {key.low:g}"
    high = "" if key.high is None else f"<= {key.high:g}"
    return ", ".join(part for part in (low, high) if part)


def schema_markdown() -> str:
    """Every key of the description as Markdown tables (docs/machine.md is this, checked by a test)."""
    lines = []
    tables = {
        **SCHEMA,
        'friction."JOINT"': FRICTION_KEYS,
        'warm_friction."JOINT"': FRICTION_KEYS,
        'limits."JOINT"': LIMIT_KEYS,
    }
    tables = {
        ('motor"] or [motor."JOINT' if name == "motor" else name): keys
        for name, keys in tables.items()
    }
    for section, keys in tables.items():
        lines += [
            f"### `[{section}]`",
            "",
            "| key | type | range | required | meaning |",
            "| --- | --- | --- | --- | --- |",
        ]
        lines += [
            f"| `{name}` | {_kind_name(key)} | {_range(key)} | {'yes' if key.required else ''} | {key.doc} |"
            for name, key in keys.items()
        ]
        lines.append("")
    lines += [
        f"### `[{PRESET_TABLE}]`",
        "",
        '`name = "target"` pairs: design-variant parameters in the '
        "`mechanism-variants/1` target syntax (docs/inspection.md) that variant files may name.",
        "",
    ]
    return "\n".join(lines)


# effects only a tool working in fabric can have (a needle piercing it once per turn)
NEEDS_FABRIC = ("needle_penetration",)


def lacks_fabric_for(name: str, nominal) -> bool:
    """The effect ``name`` needs a tool working in fabric and the described drive has none."""
    return name in NEEDS_FABRIC and not nominal.tool_in_fabric


def refuse_without_fabric(names, nominal) -> None:
    """A UserError for the first of ``names`` that needs a tool working in fabric where the
    described drive (``nominal.tool_in_fabric``) has none: the diagnosis does not offer it, the
    bench does not conceal it."""
    missing = [name for name in names if lacks_fabric_for(name, nominal)]
    if missing:
        raise UserError(
            f"effect {missing[0]}: the machine has no tool working in fabric ([tool] site, plate "
            "and piercing_force_per_layer_N)"
        )
