"""The machine: a described, converted CAD model with its motor, friction and loads.

:func:`load_machine` reads a machine description (mechanism.machine.description), loads
its model (converting a CAD export on first use), checks every name against the model and
builds one compiled MuJoCo model through ``MjSpec``:

- the motor as a native ``<dcmotor>`` on the described motor joint (mechanism.physics.motor);
- friction per joint from the description, cold or partly warm (mechanism.physics.friction);
- loads (mechanism.physics.loads): fabric on the tool, belt tension, feeding;
- a sensor for the motor torque (the current).

The :class:`Machine` carries the roles every verb needs (motor joint, shaft joint, the
shaft's zero and direction, tool site and plate) and the linkage tables over one shaft
revolution, so no module looks a joint up by a literal name. The shaft angle is
``direction * (q_shaft - zero)``: 0 where the zero site is highest against gravity,
increasing when the motor turns forward (positive voltage).
"""

from __future__ import annotations

import functools
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, cast, get_args

import mujoco
import numpy as np

from mechanism import native
from mechanism.errors import UserError, close_matches
from mechanism.kinematics.linkage import LinkageTables, compute_tables, up_axis
from mechanism.kinematics.pose import (
    approach,
    joint_dof,
    passive_joints,
    solve_pose,
    velocity_ratios,
)
from mechanism.kinematics.travel import Travel, find_travel
from mechanism.machine import parts
from mechanism.machine.description import MachineDescription, read_description
from mechanism.machine.models import (
    DEFAULT_DESCRIPTION,
    load_spec,
    resolve_model,
    shipped_description,
    shipped_machines,
)
from mechanism.physics.friction import FrictionLaw, FrictionSet, python_friction
from mechanism.physics.inputs import (
    DEFAULT_RATED_VOLTAGE_V,
    DutyMap,
    VoltageProfile,
    check_rated_voltage,
)
from mechanism.physics.loads import FabricLoad, python_needle_load
from mechanism.machine.description import MOTOR_INPUT_UNIT
from mechanism.physics.motor import (
    CurrentDrive,
    DCMotor,
    ServoDrive,
    SupplyLimit,
    Thermal,
    apply_servos_to_spec,
    bind_servos,
    python_servo_limit,
    python_supply_limit,
)
from mechanism.tolerances import ZERO_SNAP_RAD

ACTUATOR = "drive_motor"  # the actuator the machine adds (its own name, not a CAD name)
TORQUE_SENSOR = "drive_motor_torque"
DEFAULT_TIMESTEP_S = 0.0005
ZERO_SEARCH_SAMPLES = 180
BeltTension = Literal["low", "normal", "hard"]  # the description's [loads] belt_tension_*_Nm
BELT_TENSIONS: tuple[BeltTension, ...] = get_args(BeltTension)
# the voltage a hard stop is sized for where the description gives no supply voltage
STALL_VOLTAGE_V = 24.0
STALL_CURRENT_A = 10.0  # a current drive's stall current where the description gives no limit
# a hard stop holds the stalled motor within half a degree (a slide: 0.5 mm)
STOP_HOLD_RAD = math.radians(0.5)
STOP_HOLD_M = 0.5e-3
STOP_IMPEDANCE = (0.95, 0.9999)  # MuJoCo's default dmax up to as stiff as its soft constraints go


@dataclass
class MachineConfig:
    """Operating conditions of one run (what changes between runs of one machine)."""

    warm_s: float = 0.0  # seconds of running before this run (0: cold)
    layers: int = 0
    needle: bool = True  # the tool engages the fabric
    feeding: bool = False
    belt_tension: BeltTension = "normal"
    motor: DCMotor | None = None  # replaces the described motor
    friction: dict[str, FrictionLaw] | None = None  # replaces described laws joint by joint
    fabric: FabricLoad | None = None
    timestep_s: float | None = None  # default: the description's, else 0.5 ms

    def __post_init__(self):
        if self.belt_tension not in BELT_TENSIONS:
            raise UserError(
                f"belt tension must be one of {', '.join(BELT_TENSIONS)}, got {self.belt_tension!r}"
            )
        if self.timestep_s is not None and not 1e-5 <= self.timestep_s <= 2e-3:
            raise UserError("time step must be between 0.01 ms and 2 ms")
        if not (math.isfinite(self.warm_s) and 0 <= self.warm_s <= 1e6):
            raise UserError(f"warm-up time must be between 0 and 1e6 s, got {self.warm_s:g}")


def friction_law(values: dict, motor_joint: str | None = None) -> FrictionLaw:
    """A friction law from a description table (FRICTION_KEYS)."""
    static = values.get("static_Nm")
    return FrictionLaw(
        coulomb=values.get("coulomb_Nm", 0.0),
        static=static,
        viscous=values.get("viscous_Nm_s_per_rad", 0.0),
        stribeck=values.get(
            "stribeck",
            "tustin" if static is not None and values.get("stribeck_velocity_rad_s") else "none",
        ),
        stribeck_velocity=values.get("stribeck_velocity_rad_s", 0.0),
        tustin_exponent=values.get("tustin_exponent", 1.0),
        position_amplitude=values.get("position_amplitude", 0.0),
        static_position_amplitude=values.get("static_position_amplitude"),
        position_phase_rad=math.radians(values.get("position_phase_deg", 0.0)),
        position_harmonic=values.get("position_harmonic", 1.0),
        position_joint=values.get("position_joint"),
    )


def warmed(cold: dict, warm: dict, fraction: float) -> dict:
    """Friction table after warming: each warm value reached by ``fraction`` (0 cold, 1 warm)."""
    out = dict(cold)
    for key, value in warm.items():
        if isinstance(value, float) and isinstance(cold.get(key, 0.0), float):
            out[key] = cold.get(key, 0.0) + (value - cold.get(key, 0.0)) * fraction
        else:
            out[key] = value
    if "static_Nm" in out and "coulomb_Nm" in out and out["static_Nm"] < out["coulomb_Nm"]:
        out["static_Nm"] = out["coulomb_Nm"]
    return out


def drive_from_description(motor: dict) -> DCMotor | ServoDrive | CurrentDrive:
    """The drive of a [motor] table: a DC motor, a servo or a current drive."""
    kind = motor.get("type", "dc")
    if kind == "current":
        return CurrentDrive(motor["torque_constant_Nm_per_A"], motor.get("max_current_A"))
    if kind == "servo":
        core = DCMotor(
            resistance_ohm=motor["resistance_ohm"],
            torque_constant_Nm_A=motor["torque_constant_Nm_per_A"],
            back_emf_V_s_rad=motor["back_emf_V_s_per_rad"],
            cogging_Nm=motor.get("cogging_Nm", 0.0),
            cogging_poles=motor.get("cogging_per_rev", DCMotor.cogging_poles),
        )
        return ServoDrive(
            core,
            motor["supply_V"],
            motor["kp_V_per_rad"],
            motor.get("kd_V_s_per_rad", 0.0),
            motor.get("duty_limit", 1.0),
        )
    return motor_from_description(motor)


def motor_from_description(motor: dict) -> DCMotor:
    thermal = None
    if "thermal_resistance_K_per_W" in motor or "thermal_time_constant_s" in motor:
        thermal = Thermal(
            resistance_K_W=motor.get("thermal_resistance_K_per_W", Thermal.resistance_K_W),
            time_constant_s=motor.get("thermal_time_constant_s", Thermal.time_constant_s),
        )
    return DCMotor(
        resistance_ohm=motor["resistance_ohm"],
        torque_constant_Nm_A=motor["torque_constant_Nm_per_A"],
        back_emf_V_s_rad=motor["back_emf_V_s_per_rad"],
        inductance_H=motor.get("inductance_H", 0.0),
        cogging_Nm=motor.get("cogging_Nm", 0.0),
        cogging_poles=motor.get("cogging_per_rev", DCMotor.cogging_poles),
        thermal=thermal,
    )


def duty_map_from(description: MachineDescription) -> DutyMap:
    """The described PWM supply's measured duty -> motor voltage map."""
    supply = description.section("supply")
    if "duty_percent" not in supply:
        raise UserError(
            f"this machine describes no PWM supply ([supply] duty_percent and motor_voltage_V in "
            f"{description.path or 'its description'})"
        )
    return DutyMap(np.array(supply["duty_percent"]), np.array(supply["motor_voltage_V"]))


def supply_limit(description: MachineDescription) -> SupplyLimit | None:
    """The supply's voltage limit under load, when the description gives its series resistance."""
    supply = description.section("supply")
    if "series_resistance_ohm" not in supply:
        return None
    if "voltage_V" not in supply:
        raise UserError(
            f"machine description {description.where('supply', 'voltage_V')}: a series resistance needs the supply voltage"
        )
    return SupplyLimit(supply["voltage_V"], supply["series_resistance_ohm"])


def fabric_from_description(tool: dict, layers: int) -> FabricLoad:
    keys = ("layer_thickness_mm", "piercing_force_per_layer_N", "drag_fraction", "point_taper_mm")
    return FabricLoad(layers=layers, **{k: tool[k] for k in keys if k in tool})


def _require(
    kind: str,
    name: str,
    names: list[str],
    description: MachineDescription,
    section: str,
    key: str | None,
) -> None:
    if name not in names:
        raise UserError(
            f"machine description {description.where(section, key)}: the model has no {kind} {name!r}; "
            f"close matches: {close_matches(name, names)}"
        )


def _names(spec_items) -> list[str]:
    return [item.name for item in spec_items if item.name]


def check_names(description: MachineDescription, spec: mujoco.MjSpec) -> None:
    """Every joint, site and part the description names exists in the model."""
    joints, sites = _names(spec.joints), _names(spec.sites)
    geoms = _names(spec.geoms)
    _require("joint", description.motor_joint, joints, description, "drive", "motor_joint")
    for joint in description.drive_tables:
        _require("joint", joint, joints, description, f'motor."{joint}"', None)
    _require("joint", description.shaft_joint, joints, description, "drive", "shaft_joint")
    if description.zero_site is not None:
        _require("site", description.zero_site, sites, description, "drive", "zero_site")
    slides = {j.name for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_SLIDE}
    for joint in description.limits:
        _require("joint", joint, joints, description, f'limits."{joint}"', None)
        unit = "mm" if joint in slides else "deg"
        if description.limit_units.get(joint, unit) != unit:
            raise UserError(
                f"machine description {description.where(f'limits.{chr(34)}{joint}{chr(34)}')}: "
                f"{joint!r} is a {'slide' if unit == 'mm' else 'hinge'}: give lower_{unit} and upper_{unit}"
            )
    for table in ("friction", "warm_friction"):
        for joint, law in getattr(description, table).items():
            _require("joint", joint, joints, description, f'{table}."{joint}"', None)
            if "position_joint" in law:
                _require(
                    "joint",
                    law["position_joint"],
                    joints,
                    description,
                    f'{table}."{joint}"',
                    "position_joint",
                )
    tool, hook, loads = (
        description.section("tool"),
        description.section("hook"),
        description.section("loads"),
    )
    for key in ("site", "eye_site"):
        if key in tool:
            _require("site", tool[key], sites, description, "tool", key)
    for key in ("plate", "part"):
        if key in tool and not any(g == tool[key] or g.startswith(tool[key] + "_") for g in geoms):
            _require(
                "part",
                tool[key],
                sorted({g.removesuffix("_visual") for g in geoms}),
                description,
                "tool",
                key,
            )
    if "joint" in hook:
        _require("joint", hook["joint"], joints, description, "hook", "joint")
    if "site" in hook:
        _require("site", hook["site"], sites, description, "hook", "site")
    if "feeding_joint" in loads:
        _require("joint", loads["feeding_joint"], joints, description, "loads", "feeding_joint")
    ground = description.section("machine").get("ground")
    if ground is not None:
        owners = [g for g in [*spec.geoms, *spec.sites] if g.name in (ground, f"{ground}_visual")]
        if not owners:
            _require(
                "part",
                ground,
                sorted({g.removesuffix("_visual") for g in geoms} | set(sites)),
                description,
                "machine",
                "ground",
            )
        body = owners[0].parent
        fixed = True
        while body is not None and body.name != "world":
            fixed = fixed and not list(body.joints)
            body = body.parent
        if not fixed:
            raise UserError(
                f"machine description {description.where('machine', 'ground')}: the MJCF does not fix "
                f"{ground!r} to the world; [machine] ground acts when the model is a CAD export "
                f"(converted with that part fixed): name the export as the model"
            )


def plate_top(model: mujoco.MjModel, data: mujoco.MjData, part: str) -> float:
    """Height [m] against gravity of a part's top surface (its highest mesh vertex)."""
    up = up_axis(model)
    tops = []
    for gid in parts.part_geoms(model, part):
        mesh = model.geom_dataid[gid]
        if model.geom_type[gid] != mujoco.mjtGeom.mjGEOM_MESH or mesh < 0:
            tops.append(float(up @ data.geom_xpos[gid]))
            continue
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        world = (
            model.mesh_vert[start : start + count] @ data.geom_xmat[gid].reshape(3, 3).T
            + data.geom_xpos[gid]
        )
        tops.append(float((world @ up).max()))
    return max(tops)


_CALLBACK_INSTALLED = False


def install_callbacks() -> bool:
    """Install the passive-force callback once per process (C if possible); True when
    compiled. Models without our numerics are untouched."""
    global _CALLBACK_INSTALLED
    library = native.load("machine")
    if not _CALLBACK_INSTALLED:
        if library is not None:
            mujoco.set_mjcb_passive(library.mechanism_passive)
        else:

            def passive(model, data):
                python_friction(model, data)
                python_needle_load(model, data)
                python_supply_limit(model, data)
                python_servo_limit(model, data)

            mujoco.set_mjcb_passive(passive)
        _CALLBACK_INSTALLED = True
    return library is not None


def resolve_description(
    description: MachineDescription | str | os.PathLike | None,
) -> MachineDescription:
    """A description from itself, a TOML path, a shipped machine's name, or None (the default machine)."""
    if isinstance(description, MachineDescription):
        return description
    if description is None:
        return read_description(DEFAULT_DESCRIPTION)
    if isinstance(description, str) and description in shipped_machines():
        return read_description(shipped_description(description))
    return read_description(description)


@dataclass(frozen=True)
class ShaftFrame:
    """Where the shaft angle starts and which way it counts, in the shaft joint's coordinate."""

    zero_rad: float
    direction: float


def find_shaft_frame(
    model: mujoco.MjModel, description: MachineDescription, travel: Travel | None = None
) -> ShaftFrame:
    """The shaft's zero (zero site highest against gravity, or the described ``zero_angle_deg``)
    and its forward direction (the way the shaft turns when the motor turns positive). A drive
    that rocks looks for its zero within its travel (at an end of it where the site is highest
    there)."""
    shaft, motor = description.shaft_joint, description.motor_joint
    rocks = travel is not None and not travel.rotates
    span = (travel.lower, travel.upper) if travel is not None and rocks else None
    coarse = compute_tables(model, shaft, description.zero_site, n=ZERO_SEARCH_SAMPLES, span=span)
    motor_ratio = float(np.mean(coarse.ratios[motor])) if motor in coarse.ratios else 0.0
    if (
        not abs(motor_ratio) > 1e-9
    ):  # another described motor that turns the shaft sets its direction
        others = [
            float(np.mean(coarse.ratios[j]))
            for j in description.drive_tables
            if j in coarse.ratios and j != motor
        ]
        motor_ratio = next((r for r in others if abs(r) > 1e-9), 0.0)
    if not abs(motor_ratio) > 1e-9:
        if len(description.drive_tables) == 1:
            raise UserError(
                f"machine description {description.where('drive', 'motor_joint')}: the motor joint {motor!r} "
                f"does not move when the shaft {shaft!r} turns (no coupling between them)"
            )
        motor_ratio = 1.0  # no motor turns the shaft: it counts in its joint's own direction
    direction = 1.0 if motor_ratio > 0 else -1.0
    if description.zero_angle_rad is not None:
        return ShaftFrame(zero_rad=description.zero_angle_rad, direction=direction)
    height = coarse.tool_z_m
    assert height is not None  # compute_tables was given the zero site
    if np.ptp(height) <= 1e-9 * max(float(model.stat.extent), 1e-3):
        raise UserError(
            f"machine description {description.where('drive', 'zero_site')}: the site {description.zero_site!r} "
            f"does not rise and fall as the shaft turns, so the shaft has no zero: give [drive] "
            f"zero_angle_deg (the shaft joint's coordinate of its zero) instead"
        )
    data = mujoco.MjData(model)
    up = up_axis(model)
    jac = np.zeros((3, model.nv))
    site = model.site(description.zero_site).id
    best = int(np.argmax(height))
    step = float(coarse.angle_rad[1] - coarse.angle_rad[0])
    if rocks:
        approach(model, data, shaft, float(coarse.angle_rad[best]))

    def slope(angle: float) -> float:
        solve_pose(model, data, {shaft: angle})
        mujoco.mj_jacSite(model, data, jac, None, site)
        return float(up @ jac @ velocity_ratios(model, data, shaft))

    from scipy.optimize import brentq

    if rocks and best in (0, len(height) - 1):
        # highest at an end of the travel
        return ShaftFrame(zero_rad=float(coarse.angle_rad[best]), direction=direction)
    low, high = coarse.angle_rad[best] - step, coarse.angle_rad[best] + step
    try:
        zero = (
            brentq(slope, low, high, xtol=1e-13)
            if slope(low) > 0 > slope(high)
            else float(coarse.angle_rad[best])
        )
    except ValueError:
        zero = float(coarse.angle_rad[best])
    if rocks:
        return ShaftFrame(zero_rad=float(zero), direction=direction)
    zero = math.remainder(zero, 2 * np.pi)
    return ShaftFrame(zero_rad=0.0 if abs(zero) < ZERO_SNAP_RAD else zero, direction=direction)


def shaft_travel(
    model: mujoco.MjModel, description: MachineDescription, driver: str | None = None
) -> Travel:
    """The travel inspection's cycle covers for ``driver`` (default: the shaft): the described
    ``[drive] range_deg`` (the shaft), the described limits, the model's joint range, else whole
    revolutions where the mechanism assembles over one, else the range it assembles in."""
    joint = driver or description.shaft_joint
    if joint == description.shaft_joint and description.range_rad is not None:
        return find_travel(
            model, joint, description.range_rad, "the description's [drive] range_deg"
        )
    travel = find_travel(model, joint, description.limits.get(joint))
    if travel.source == "the range the mechanism assembles in":
        import warnings

        warnings.warn(
            f"{travel.joint} cannot turn a whole revolution: inspecting its travel "
            f"{travel.text().removeprefix(travel.joint + ' ')}, where the mechanism assembles (give "
            f'[limits."{travel.joint}"] lower_deg and upper_deg to set it and its hard stops)'
        )
    return travel


def warn_passive(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    description: MachineDescription | None,
    driven: list[str],
) -> list[str]:
    """The passive joints (free to move with the ``driven`` ones held); warns once about each
    with neither a limit nor damping (viscous friction described, or MJCF damping)."""
    import warnings

    passive = passive_joints(model, data, driven)
    friction = description.friction if description is not None else {}
    limits = description.limits if description is not None else {}
    for name in passive:
        joint = model.joint(name).id
        dof = int(model.jnt_dofadr[joint])
        damped = (
            friction.get(name, {}).get("viscous_Nm_s_per_rad", 0.0) > 0
            or model.dof_damping[dof] > 0
        )
        if not (model.jnt_limited[joint] or name in limits or damped):
            warnings.warn(
                f"passive joint {name} has neither a limit nor damping: it swings or slides freely under "
                f'gravity (give [limits."{name}"] or [friction."{name}"] viscous_Nm_s_per_rad)'
            )
    return passive


def inspection_travel(
    model: mujoco.MjModel, driver: str, description: MachineDescription | None = None
) -> Travel:
    """The travel an inspection cycle covers for ``driver``: the described machine's (shaft_travel),
    or for a bare model its joint range, else whole revolutions, else where it assembles."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    names = parts.joint_names(model)
    motors = [
        joint
        for joint in (description.drive_tables if description is not None else ())
        if joint in names
    ]
    warn_passive(model, data, description, [driver, *motors])
    if description is not None:
        return shaft_travel(model, description, driver)
    travel = find_travel(model, driver)
    if travel.source == "the range the mechanism assembles in":
        import warnings

        warnings.warn(
            f"{driver} cannot turn a whole revolution: inspecting {travel.text()}, where the mechanism assembles"
        )
    return travel


def inspection_frame(
    model: mujoco.MjModel,
    driver: str,
    description: MachineDescription | None = None,
    travel: Travel | None = None,
) -> ShaftFrame:
    """The frame inspection reports ``driver``'s angle in: the described shaft's (0 at its zero,
    counting the way the motor turns it forward) when ``driver`` is the described shaft, else the
    joint's own coordinate."""
    if (
        description is None
        or driver != description.shaft_joint
        or description.motor_joint not in parts.joint_names(model)
    ):
        return ShaftFrame(0.0, 1.0)
    return find_shaft_frame(model, description, travel or shaft_travel(model, description))


def stop_stiffness(
    model: mujoco.MjModel,
    joint: int,
    motors: list[tuple[float, int]],
    timestep_s: float,
) -> tuple[np.ndarray, np.ndarray, float]:
    """(solref, solimp, predicted steady penetration [rad or m]) of a hard stop on ``joint``
    that holds the strongest motor's stall torque (``motors``: (stall torque, dof) each), as
    reflected to the joint, plus gravity.

    MuJoCo's soft constraint obeys a1 + d (b v + k r) = (1 - d) a0 with k = 1/(d^2 tc^2) at
    critical damping: held still (a1 = v = 0) against an acceleration a0 = tau / J (tau the
    reflected torque, J the reflected inertia) it sits r = (1 - d) d tc^2 a0 inside the stop.
    tc is the least MuJoCo accepts (two time steps); d = dmax is raised from MuJoCo's default
    0.95 until r is at most STOP_HOLD_RAD (STOP_HOLD_M on a slide)."""
    data = mujoco.MjData(model)
    name = model.joint(joint).name
    approach(model, data, name, float(np.clip(0.0, *model.jnt_range[joint])))
    v = velocity_ratios(model, data, name)
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    inertia = float(v @ mass @ v)
    torque = max(abs(stall * v[dof]) for stall, dof in motors) + abs(float(v @ data.qfrc_bias))
    acceleration = torque / inertia if inertia > 0 else 0.0
    hold = (
        STOP_HOLD_M
        if int(model.jnt_type[joint]) == int(mujoco.mjtJoint.mjJNT_SLIDE)
        else STOP_HOLD_RAD
    )
    tc = 2 * timestep_s
    d = STOP_IMPEDANCE[0] if acceleration <= 0 else 1.0 - hold / (tc * tc * acceleration)
    d = float(np.clip(d, *STOP_IMPEDANCE))
    solimp = np.array([d, d, 0.001, 0.5, 2.0])
    return np.array([tc, 1.0]), solimp, (1 - d) * d * tc * tc * acceleration


def actuator_name(description: MachineDescription, joint: str) -> str:
    """The actuator of the motor on ``joint``: ``drive_motor`` for the main one, ``drive_motor:JOINT`` else."""
    return ACTUATOR if joint == description.motor_joint else f"{ACTUATOR}:{joint}"


def torque_sensor_name(description: MachineDescription, joint: str) -> str:
    return TORQUE_SENSOR if joint == description.motor_joint else f"{TORQUE_SENSOR}:{joint}"


def input_unit(description: MachineDescription, joint: str) -> str:
    """The unit of the motor on ``joint``'s input: V (dc), rad (servo: the goal angle) or A (current)."""
    return MOTOR_INPUT_UNIT[description.drive_tables[joint]["type"]]


def _described(attribute: str) -> Any:
    """A read-only attribute of the Machine that is its description's."""
    return property(
        lambda self: getattr(self.description, attribute), doc=f"the description's {attribute}"
    )


class Machine:
    """A compiled, ready-to-simulate machine. ``machine.model`` / ``machine.data`` are plain
    MuJoCo objects; everything added is visible in ``mujoco.mj_saveLastXML``."""

    def __init__(
        self,
        description: MachineDescription | str | os.PathLike | None = None,
        config: MachineConfig | None = None,
        extend=None,
    ):
        """``description``: a description, its TOML path, or None for the shipped machine.
        ``extend(spec)``, if given, adds to the spec before it is compiled (probe sites and
        sensors, mechanism.inspection.probes); it must not add joints or actuators."""
        self.description = resolve_description(description)
        self.config = config or MachineConfig()
        self.model_path = resolve_model(self.description)
        self._extend = extend
        spec = load_spec(self.model_path)
        check_names(self.description, spec)
        self.timestep_s = (
            self.config.timestep_s or self.description.timestep_s or DEFAULT_TIMESTEP_S
        )
        spec.option.timestep = self.timestep_s  # before friction: its stiffness follows it
        for equality in spec.equalities:  # loops and belts as stiff as the step allows (2 steps)
            equality.solref = [2 * self.timestep_s, 1.0]
        self.drives = {
            joint: drive_from_description(table)
            for joint, table in self.description.drive_tables.items()
        }
        if self.config.motor is not None:
            self.drives[self.motor_joint] = self.config.motor
        main = self.drives[self.motor_joint]
        # the main motor's datasheet (a current drive has no R or Ke: a 1 ohm stand-in keeps the formulas defined)
        self.motor = (
            main
            if isinstance(main, DCMotor)
            else main.motor
            if isinstance(main, ServoDrive)
            else DCMotor(
                resistance_ohm=1.0,
                torque_constant_Nm_A=main.torque_constant_Nm_A,
                back_emf_V_s_rad=main.torque_constant_Nm_A,
            )
        )
        for joint, drive in self.drives.items():
            drive.add_to_spec(spec, joint=joint, name=actuator_name(self.description, joint))
        servos = [joint for joint, drive in self.drives.items() if isinstance(drive, ServoDrive)]
        if servos:
            apply_servos_to_spec(spec, len(servos))
        for joint, (
            lower,
            upper,
        ) in self.description.limits.items():  # hard stops; their stiffness follows compiling
            item = spec.joint(joint)
            item.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            hinge = item.type == mujoco.mjtJoint.mjJNT_HINGE
            # an MJCF in degrees compiles the range as such
            scale = 180.0 / math.pi if hinge and spec.compiler.degree else 1.0
            item.range = [lower * scale, upper * scale]
        self.friction = FrictionSet(self.friction_laws())
        self.friction.apply_to_spec(spec)
        tool = self.description.section("tool")
        self.fabric = self.config.fabric or fabric_from_description(
            tool, self.config.layers if self.config.needle else 0
        )
        if not self.config.needle:
            self.fabric = FabricLoad(layers=0)
        if self.fabric.layers and not (self.tool_site and self.plate_part):
            raise UserError(
                f"fabric layers need a tool site and a plate: set [tool] site and plate in "
                f"{self.description.path or 'the machine description'}"
            )
        self.fabric.apply_to_spec(spec)
        self.supply = supply_limit(self.description) if isinstance(main, DCMotor) else None
        if self.supply:
            self.supply.apply_to_spec(spec)
        for joint in self.drives:
            spec.add_sensor(
                name=torque_sensor_name(self.description, joint),
                type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
                objname=actuator_name(self.description, joint),
            )
        if extend is not None:
            extend(spec)
        try:
            self.model = spec.compile()
        except Exception as exc:
            raise UserError(
                f"cannot build the machine model: {' '.join(str(exc).split())}"
            ) from None
        self.spec = spec
        self.data = mujoco.MjData(self.model)
        self.friction.bind(self.model)
        self.native = install_callbacks()
        self.shaft_qpos, self.shaft_dof = joint_dof(self.model, self.shaft_joint)
        self.motor_qpos, self.motor_dof = joint_dof(self.model, self.motor_joint)
        if self.supply:
            self.supply.bind(self.model, self.motor, self.actuator, self.motor_dof)
        if servos:
            bind_servos(
                self.model,
                [
                    cast(ServoDrive, self.drives[j]).fields(
                        self.model.actuator(actuator_name(self.description, j)).id,
                        *reversed(joint_dof(self.model, j)),
                    )
                    for j in servos
                ],
            )
        self.stops = self._stiffen_stops(spec)
        self.travel = cached_travel(self.model_path, self.description, self.model)
        self.frame = shaft_frame(self.model_path, self.description, self.model, self.travel)
        self.plate_top_z = None
        self.reset(0.0)
        self.passive_joints = warn_passive(
            self.model, self.data, self.description, [*self.drives, self.shaft_joint]
        )
        if self.plate_part:
            self.plate_top_z = plate_top(self.model, self.data, self.plate_part)
        if self.fabric.layers:
            assert self.tool_site and self.plate_top_z is not None  # checked before compiling
            self.fabric.bind(self.model, self.tool_site, self.plate_top_z)

    def _stiffen_stops(self, spec: mujoco.MjSpec) -> dict[str, float]:
        """Every limited joint's stop holds the stalled motor (stop_stiffness); returns each one's
        predicted steady penetration [rad or m]."""
        supply = self.description.section("supply")
        motors = [
            (
                drive.stall_torque_Nm(
                    STALL_CURRENT_A
                    if isinstance(drive, CurrentDrive)
                    else supply.get("voltage_V", STALL_VOLTAGE_V)
                ),
                joint_dof(self.model, joint)[1],
            )
            for joint, drive in self.drives.items()
        ]
        out = {}
        for joint in np.flatnonzero(self.model.jnt_limited):
            solref, solimp, penetration = stop_stiffness(
                self.model, int(joint), motors, self.timestep_s
            )
            self.model.jnt_solref[joint], self.model.jnt_solimp[joint] = solref, solimp
            name = self.model.joint(joint).name
            if name:
                spec.joint(name).solref_limit, spec.joint(name).solimp_limit = solref, solimp
            out[name] = penetration
        return out

    # -- roles, all from the description --
    name: str = _described("name")
    motor_joint: str = _described("motor_joint")
    shaft_joint: str = _described("shaft_joint")
    zero_site: str = _described("zero_site")
    tool_site: str | None = _described("tool_site")

    @property
    def plate_part(self) -> str | None:
        return self.description.section("tool").get("plate")

    @property
    def zero_meaning(self) -> str:
        """What shaft angle 0 is, in the description's words (for reports and plot labels)."""
        description = self.description
        if description.zero_site is not None:
            if description.zero_site != self.tool_site:
                return f"{description.zero_site} highest"
            return f"{description.zero_site} at its top"
        return f"{self.shaft_joint} at {description.section('drive')['zero_angle_deg']:g} deg"

    @property
    def fabric_capable(self) -> bool:
        """Can the tool pierce fabric layers (tool site, plate and a fabric model described)?"""
        tool = self.description.section("tool")
        return bool(self.tool_site and self.plate_part and "piercing_force_per_layer_N" in tool)

    @property
    def actuator(self) -> int:
        return self.model.actuator(ACTUATOR).id

    # arm_* names are kept for the code that predates descriptions: the arm is the shaft.
    arm_qpos = property(lambda self: self.shaft_qpos)
    arm_dof = property(lambda self: self.shaft_dof)

    def friction_laws(self) -> dict[str, FrictionLaw]:
        description, config = self.description, self.config
        tau = description.section("warm").get("time_constant_s")
        fraction = (
            0.0 if not config.warm_s else (1.0 if not tau else 1.0 - math.exp(-config.warm_s / tau))
        )
        tables = {joint: dict(values) for joint, values in description.friction.items()}
        for joint, warm in description.warm_friction.items():
            tables[joint] = warmed(tables.get(joint, {}), warm, fraction)
        laws = {joint: friction_law(values) for joint, values in tables.items()}
        laws.update(config.friction or {})
        loads = description.section("loads")
        extra = {
            "low": loads.get("belt_tension_low_Nm", 0.0),
            "normal": 0.0,
            "hard": loads.get("belt_tension_hard_Nm", 0.0),
        }[config.belt_tension]
        if extra:
            laws[self.shaft_joint] = laws.get(self.shaft_joint, FrictionLaw()).add(coulomb=extra)
        if config.feeding:
            if "feeding_joint" not in loads:
                raise UserError("this machine describes no feed mechanism ([loads] feeding_joint)")
            joint = loads["feeding_joint"]
            laws[joint] = laws.get(joint, FrictionLaw()).add(
                coulomb=loads.get("feeding_coulomb_Nm", 0.0)
            )
        return laws

    def duty_map(self) -> DutyMap:
        return duty_map_from(self.description)

    @property
    def rated_voltage_V(self) -> float:
        return float(self.description.motor.get("rated_voltage_V", DEFAULT_RATED_VOLTAGE_V))

    def check_voltage(self, voltage: VoltageProfile) -> None:
        """Refuse an input above the motor's rated voltage (the description's, else 30 V)."""
        check_rated_voltage(
            voltage, self.rated_voltage_V, self.description.where("motor", "rated_voltage_V")
        )

    # -- the shaft angle --
    def shaft_angle(self, qpos) -> np.ndarray:
        """Shaft angle [rad] from joint positions (any leading shape, last axis nq)."""
        q = np.asarray(qpos)[..., self.shaft_qpos]
        return self.frame.direction * (q - self.frame.zero_rad)

    def shaft_velocity(self, qvel) -> np.ndarray:
        return self.frame.direction * np.asarray(qvel)[..., self.shaft_dof]

    def joint_position(self, shaft_angle_rad: float) -> float:
        return self.frame.zero_rad + self.frame.direction * float(shaft_angle_rad)

    def reset(self, shaft_angle_rad: float = 0.0) -> mujoco.MjData:
        """Machine at rest with the shaft at ``shaft_angle_rad`` (0 = the described zero)."""
        mujoco.mj_resetData(self.model, self.data)
        if self.rotates:
            solve_pose(
                self.model, self.data, {self.shaft_joint: self.joint_position(shaft_angle_rad)}
            )
        else:
            approach(self.model, self.data, self.shaft_joint, self.joint_position(shaft_angle_rad))
        self.data.qvel[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        return self.data

    @functools.cached_property
    def tables(self) -> LinkageTables:
        """J(θ), J'(θ), G(θ), joint ratios and the tool height over one shaft revolution."""
        return compute_tables(
            self.model,
            self.shaft_joint,
            self.tool_site,
            n=720,
            zero_rad=self.frame.zero_rad,
            direction=self.frame.direction,
            span=self.shaft_span_rad,
        )

    @property
    def rotates(self) -> bool:
        """Does the shaft turn whole revolutions (else it rocks between the ends of its travel)?"""
        return self.travel.rotates

    @property
    def shaft_span_rad(self) -> tuple[float, float] | None:
        """(lower, upper) shaft angles [rad] of a drive that rocks; None for one that turns."""
        if self.travel.rotates:
            return None
        ends = sorted(
            self.frame.direction * (value - self.frame.zero_rad)
            for value in (self.travel.lower, self.travel.upper)
        )
        return ends[0], ends[1]

    def ratio(self, joint: str) -> float:
        """Mean dq_joint/dθ over a revolution (turns of ``joint`` per shaft turn for a coupled shaft)."""
        if joint not in self.tables.ratios:
            raise UserError(
                f"no one-degree-of-freedom joint {joint!r}; close matches: {close_matches(joint, self.tables.ratios)}"
            )
        return float(np.mean(self.tables.ratios[joint]))

    @property
    def motor_ratio(self) -> float:
        return self.ratio(self.motor_joint)

    def tool_height_mm(self, tool_world_z) -> np.ndarray:
        """Tool height above the plate top [mm] from its height against gravity [m]."""
        reference = self.plate_top_z if self.plate_top_z is not None else 0.0
        return (np.asarray(tool_world_z) - reference) * 1e3

    def tool_height_mm_at(self, shaft_angle_rad) -> np.ndarray:
        """Tool height above the plate [mm] of the rigid mechanism at shaft angles (exact
        kinematics; dynamic site positions differ by the loops' compliance)."""
        if self.tables.tool_z_m is None:
            return np.full(np.shape(shaft_angle_rad), np.nan)
        return self.tool_height_mm(self.tables.interp(self.tables.tool_z_m, shaft_angle_rad))

    def to_xml(self, path: str | os.PathLike) -> Path:
        """Write a self-contained MJCF of this machine that stock MuJoCo loads and steps
        (``python -m mujoco.viewer --mjcf=PATH``), its meshes copied beside it.

        The motor is a native ``<dcmotor>`` (ctrl = terminal voltage [V]); viscous friction is
        joint ``damping`` and the break-away level joint ``frictionloss``. What MJCF cannot
        express (the kinetic/Stribeck and position-dependent friction, the fabric load, the
        supply's limit) acts through mechanism's passive callback, so stock MuJoCo runs the
        machine with Coulomb friction at its break-away level instead."""
        import shutil

        from mechanism.files.outputs import atomic_dir, atomic_file

        path = Path(path)
        source = self.model_path.parent / (self.spec.meshdir or "")
        meshes = f"{path.stem}_meshes"
        with atomic_dir(path.parent / meshes) as folder:
            for mesh in self.spec.meshes:
                shutil.copy2(source / mesh.file, folder / Path(mesh.file).name)
        # compiles against the original meshes; the folder name is swapped after
        xml = self.spec.to_xml()
        xml, count = re.subn(
            r'(<compiler\b[^>]*\bmeshdir=")[^"]*(")', rf"\g<1>{meshes}\g<2>", xml, count=1
        )
        if not count:
            xml = re.sub(r"<compiler\b", f'<compiler meshdir="{meshes}"', xml, count=1)
        with atomic_file(path) as handle:
            handle.write(xml)
        return path


_FRAMES: dict[tuple, ShaftFrame] = {}


_TRAVELS: dict[tuple, Travel] = {}


def _model_key(model_path: Path, description: MachineDescription) -> tuple:
    stat = Path(model_path).stat()
    return (
        str(Path(model_path).resolve()),
        stat.st_mtime_ns,
        stat.st_size,
        description.shaft_joint,
        description.motor_joint,
        description.zero_site,
        description.zero_angle_rad,
        description.range_rad,
        tuple(sorted(description.limits.items())),
    )


def cached_travel(
    model_path: Path, description: MachineDescription, model: mujoco.MjModel
) -> Travel:
    """The shaft's travel, found once per model file and roles (a search costs poses)."""
    key = _model_key(model_path, description)
    if key not in _TRAVELS:
        _TRAVELS[key] = shaft_travel(model, description)
    return _TRAVELS[key]


def shaft_frame(
    model_path: Path,
    description: MachineDescription,
    model: mujoco.MjModel,
    travel: Travel | None = None,
) -> ShaftFrame:
    """The shaft frame, found once per model file and roles (it costs a revolution of poses)."""
    key = _model_key(model_path, description)
    if key not in _FRAMES:
        _FRAMES[key] = find_shaft_frame(model, description, travel)
    return _FRAMES[key]


def load_machine(path: str | os.PathLike | MachineDescription | None = None, **config) -> Machine:
    """The machine of a description file (None: the shipped Sapphire 870), with operating
    conditions from ``config`` (MachineConfig fields: warm_s, layers, belt_tension, ...)."""
    return Machine(path, MachineConfig(**config))
