"""Sensor probes: watch a point of any part, or the load a joint carries.

A probe is a MuJoCo site plus a MuJoCo sensor added to the model through ``MjSpec``
(:func:`add_probes`), so the numbers are MuJoCo's own sensor outputs, evaluated either
along a kinematic cycle (:func:`probe_cycle`: the driver at constant speed, loads from
rigid inverse dynamics, see :mod:`mechanism.kinematics.cycle`) or along a dynamic simulation
(:func:`probe_simulation`).

Quantities and conventions (all in the world frame: z up on the sewing machine):

``position``      ``framepos`` of the probe site, mm.
``velocity``      ``framelinvel``, m/s.
``acceleration``  ``framelinacc`` with gravity removed, m/s² (MuJoCo's sensor, like an
                  accelerometer, reads +g at rest; the probe reports d²x/dt²).
``force``         the force the parent side of a joint exerts on the child side, N.
``torque``        the moment of that load about the probe point, N·m; its component along
                  a hinge axis is what the joint's drive (or coupling) transmits, the
                  other components are the bending moment the bearing carries.

The point of a position/velocity/acceleration probe is ``point_mm`` in the target's
frame: the part's site (its CAD part frame), a user-named frame's site (``needle_tip``),
or a body. A force/torque probe names a joint: a tree joint gets MuJoCo ``force`` and
``torque`` sensors on a site of the child body at the joint anchor (``cfrc_int``: the
whole load through that joint, including what its drive transmits); a loop-closing joint
(``loop:<joint>`` connect constraints) has no MuJoCo sensor, so its load is the sum of
its constraint forces on the equality's ``body1`` (the converter's follower) and their
moment about the anchor (the site is still added and marks the point). A force/torque probe on a part instead
of a joint reports the load its body receives from its parent body. ``point_mm``
moves the moment reference (in the joint's body frame, or the part frame).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import mujoco
import numpy as np

from mechanism.machine import parts
from mechanism.kinematics.cycle import (
    DEFAULT_RESOLUTION_DEG,
    DEFAULT_SPEED_RPM,
    cycle_angles,
    kinematic_cycle,
    set_state,
)
from mechanism.errors import UserError, close_matches

KINEMATIC = {
    # quantity: (sensor, component names, unit suffix, scale from SI)
    "position": (mujoco.mjtSensor.mjSENS_FRAMEPOS, ("x", "y", "z"), "mm", 1000.0),
    "velocity": (mujoco.mjtSensor.mjSENS_FRAMELINVEL, ("vx", "vy", "vz"), "m_s", 1.0),
    "acceleration": (mujoco.mjtSensor.mjSENS_FRAMELINACC, ("ax", "ay", "az"), "m_s2", 1.0),
}
LOADS = {
    "force": (mujoco.mjtSensor.mjSENS_FORCE, ("Fx", "Fy", "Fz"), "F", "N"),
    "torque": (mujoco.mjtSensor.mjSENS_TORQUE, ("Mx", "My", "Mz"), "M", "Nm"),
}
QUANTITIES = tuple(KINEMATIC) + tuple(LOADS)


@dataclass(frozen=True)
class Probe:
    """What to watch: ``target`` (part, frame, body, or a joint for loads), ``quantity``
    (one of :data:`QUANTITIES`) and an optional point [mm] in the target's frame."""

    target: str
    quantity: str
    point_mm: tuple[float, float, float] | None = None

    def __post_init__(self):
        if self.quantity not in QUANTITIES:
            raise UserError(
                f"unknown probe quantity {self.quantity!r}; choose from {', '.join(QUANTITIES)}"
            )
        if self.point_mm is not None:
            point = tuple(float(v) for v in self.point_mm)
            if len(point) != 3 or not all(np.isfinite(point)):
                raise UserError(
                    f"probe point {self.point_mm!r}: expected three finite numbers X,Y,Z in mm"
                )
            object.__setattr__(self, "point_mm", point)

    @property
    def label(self) -> str:
        if not self.point_mm or not any(self.point_mm):
            return self.target
        return f"{self.target}_at_" + "_".join(f"{v:g}" for v in self.point_mm)

    @property
    def columns(self) -> list[str]:
        if self.quantity in KINEMATIC:
            _, components, unit, _ = KINEMATIC[self.quantity]
            return [f"{self.label}_{c}_{unit}" for c in components]
        _, components, magnitude, unit = LOADS[self.quantity]
        return [f"{self.label}_{c}_{unit}" for c in (*components, magnitude)]


@dataclass
class AttachedProbe:
    """A probe after :func:`add_probes`: the names of what it added to the spec."""

    probe: Probe
    site: str
    sensor: str | None  # None for a loop-closing joint's load (constraint forces, no sensor)
    loop_joint: str | None = None


@dataclass
class ProbeResult:
    """Columns by name (units in the names) plus notes for the CSV header."""

    columns: dict[str, np.ndarray]
    comments: list[str] = field(default_factory=list)
    x_name: str = "time_s"  # the column to plot against (an angle column is plotted in degrees)

    def write_csv(self, path: str | os.PathLike) -> None:
        from mechanism.files.tables import write_table

        write_table(path, self.columns, comments=self.comments)

    def plot(self, path: str | os.PathLike, probes: Sequence[Probe]) -> None:
        plot_probes(self, probes, path)


def add_probes(spec: mujoco.MjSpec, probes: Iterable[Probe]) -> list[AttachedProbe]:
    """Add a site and a sensor for each probe to ``spec`` (names ``probe:<label>:<quantity>``).

    Names are resolved on the model compiled from ``spec`` as it is now; unknown names
    raise UserError with close matches. Compile the spec afterwards to get a model with
    the probes in it.
    """
    probes = list(dict.fromkeys(probes))
    model = _compile(spec)
    attached = []
    for probe in probes:
        name = f"probe:{probe.label}:{probe.quantity}"
        point = np.asarray(probe.point_mm or (0.0, 0.0, 0.0)) / 1000.0
        if probe.quantity in KINEMATIC:
            frame = parts.find_frame(model, probe.target)
            _add_site(spec, model, frame.body, frame.point_in_body(point), name)
            _add_sensor(spec, KINEMATIC[probe.quantity][0], name)
            attached.append(AttachedProbe(probe, name, name))
            continue
        joint = _load_joint(model, probe.target)
        if joint is None:  # a part: the load its body receives from its parent
            frame = parts.find_frame(model, probe.target)
            _add_site(spec, model, frame.body, frame.point_in_body(point), name)
            _add_sensor(spec, LOADS[probe.quantity][0], name)
            attached.append(AttachedProbe(probe, name, name))
        elif joint[0] == "tree":
            jid = joint[1]
            _add_site(spec, model, int(model.jnt_bodyid[jid]), model.jnt_pos[jid] + point, name)
            _add_sensor(spec, LOADS[probe.quantity][0], name)
            attached.append(AttachedProbe(probe, name, name))
        else:
            equalities = joint[1]
            first = equalities[0]
            anchors = [
                model.eq_data[e, 0:3]
                for e in equalities
                if model.eq_obj1id[e] == model.eq_obj1id[first]
            ]
            _add_site(
                spec, model, int(model.eq_obj1id[first]), np.mean(anchors, axis=0) + point, name
            )
            attached.append(AttachedProbe(probe, name, None, loop_joint=probe.target))
    return attached


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    try:
        return spec.compile()
    except Exception as exc:
        raise UserError(f"model does not compile: {' '.join(str(exc).split())}") from None


def _load_joint(model, name: str):
    """('tree', joint id), ('loop', [equality ids]) or None when ``name`` is not a joint."""
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if jid >= 0:
        return ("tree", jid)
    equalities = parts.loop_equalities(model, name)
    if equalities:
        connects = [e for e in equalities if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT]
        if (
            len(connects) != len(equalities)
            or model.eq_objtype[connects[0]] != mujoco.mjtObj.mjOBJ_BODY
        ):
            raise UserError(
                f"joint {name!r}: loads are available for loop joints closed by body connect constraints only"
            )
        return ("loop", connects)
    try:
        parts.find_frame(model, name)
    except UserError:
        candidates = (
            parts.joint_names(model) + parts.loop_joint_names(model) + parts.frame_names(model)
        )
        raise UserError(
            f"no joint or part named {name!r} in the model; close matches: {close_matches(name, candidates)}"
        ) from None
    return None


def _add_site(spec, model, body: int, pos, name: str) -> None:
    if spec.site(name) is not None:
        return
    body_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)
    element = spec.body(body_name) if body_name else spec.bodies[body]
    element.add_site(
        name=name, pos=[float(v) for v in pos], size=[0.001, 0, 0], group=5, rgba=[1, 0.2, 0.1, 1]
    )


def _add_sensor(spec, sensor_type, site: str) -> None:
    if spec.sensor(site) is None:
        spec.add_sensor(name=site, type=sensor_type, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site)


def read_probes(
    model: mujoco.MjModel, data: mujoco.MjData, attached: Sequence[AttachedProbe]
) -> list[float]:
    """The current values of all probes (flattened in column order), from ``sensordata``
    and, for loop joints, ``efc_force``; ``data`` must be at the acceleration stage."""
    values: list[float] = []
    for item in attached:
        quantity = item.probe.quantity
        site = model.site(item.site).id
        if quantity in KINEMATIC:
            reading = data.sensor(item.sensor).data.copy()
            if quantity == "acceleration":
                reading += model.opt.gravity
            values.extend(reading * KINEMATIC[quantity][3])
            continue
        if item.sensor is not None:  # sensor frame = site frame; report in world
            vector = data.site_xmat[site].reshape(3, 3) @ data.sensor(item.sensor).data
        else:
            # add_probes gives every probe without a sensor its loop joint
            assert item.loop_joint is not None
            vector = _loop_load(model, data, item.loop_joint, data.site_xpos[site], quantity)
        values.extend([*vector, float(np.linalg.norm(vector))])
    return values


def _loop_load(model, data, joint: str, point, quantity: str) -> np.ndarray:
    """Sum of a loop joint's connect forces on body1 (force = +efc_force, world frame), or
    their moment about ``point``."""
    total = np.zeros(3)
    rows = np.flatnonzero(data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    for eq in parts.loop_equalities(model, joint):
        force = data.efc_force[rows[data.efc_id[rows] == eq]]
        if force.size != 3:
            continue  # the constraint is inactive
        if quantity == "force":
            total += force
        else:
            body = model.eq_obj1id[eq]
            anchor = data.xpos[body] + data.xmat[body].reshape(3, 3) @ model.eq_data[eq, 0:3]
            total += np.cross(anchor - point, force)
    return total


def _columns(attached: Sequence[AttachedProbe]) -> list[str]:
    return [c for item in attached for c in item.probe.columns]


def probe_cycle(
    spec: mujoco.MjSpec,
    probes: Sequence[Probe],
    speed_rpm: float = DEFAULT_SPEED_RPM,
    revolutions: float = 1.0,
    resolution_deg: float = DEFAULT_RESOLUTION_DEG,
    driver: str | None = None,
    description=None,
) -> ProbeResult:
    """Probe values over a kinematic cycle: ``driver`` turning at ``speed_rpm`` for
    ``revolutions`` turns sampled every ``resolution_deg`` (a driver that rocks: one stroke from
    the lower end of its travel to the upper, mechanism.machine.machine.inspection_travel),
    loads by rigid inverse dynamics (frictionless joints). Adds the probes to ``spec``."""
    from mechanism.kinematics.pose import approach, named_joint
    from mechanism.machine.machine import inspection_frame, inspection_travel

    if not np.isfinite(speed_rpm) or speed_rpm < 0:
        raise UserError(f"cycle speed {speed_rpm} rpm: expected a finite speed >= 0")
    if not (0 < resolution_deg <= 90) or not (0 < revolutions <= 100):
        raise UserError("cycle: resolution must be in (0, 90] degrees and revolutions in (0, 100]")
    attached = add_probes(spec, probes)
    model = _compile(spec)
    data = mujoco.MjData(model)
    joints = parts.joint_names(model)
    # None reached close_matches: a TypeError instead of this UserError
    driver = named_joint(driver)
    if driver not in joints:
        raise UserError(
            f"no driver joint named {driver!r}; close matches: {close_matches(driver, joints)}"
        )
    omega = speed_rpm * 2 * np.pi / 60
    travel = inspection_travel(model, driver, description)
    frame = inspection_frame(model, driver, description, travel)
    if travel.rotates:  # forward from the described zero: the shaft angle rises
        angles = frame.zero_rad + frame.direction * cycle_angles(revolutions, resolution_deg)
        omega *= frame.direction
    else:
        angles = travel.samples(np.radians(resolution_deg))
        approach(model, data, driver, float(angles[0]))
    states = kinematic_cycle(model, angles, omega, driver, data)
    rows, torque = [], []
    for i in range(len(states.angle)):
        torque.append(
            set_state(model, data, states.qpos[i], states.qvel[i], states.qacc[i], driver)
        )
        rows.append(read_probes(model, data, attached))
    table = np.asarray(rows).reshape(len(states.angle), -1)
    columns = {"time_s": states.time, f"{driver}_angle_rad": states.angle}
    described = description is not None and driver == description.shaft_joint
    if described:  # the described shaft angle: 0 at its zero, rising as the motor turns forward
        shaft = frame.direction * (states.angle - frame.zero_rad)
        columns["shaft_angle_rad"] = (
            np.mod(shaft, 2 * np.pi) if travel.rotates and revolutions <= 1 else shaft
        )
    columns.update({name: table[:, i] for i, name in enumerate(_columns(attached))})
    columns[f"{driver}_drive_torque_Nm"] = np.asarray(torque)
    comments = [
        (
            f"kinematic cycle: {driver} at a constant {speed_rpm:g} rpm, {revolutions:g} revolution(s), every {resolution_deg:g} deg"
            if travel.rotates
            else f"kinematic cycle: {travel.text()} at a constant {speed_rpm:g} rpm, every {resolution_deg:g} deg"
        ),
        "world frame, z up; loads: rigid inverse dynamics without friction; force/torque = load on the child side of the joint",
        f"{driver}_drive_torque_Nm: torque the driver must supply to hold the constant speed",
    ]
    if described:
        comments.append(
            "shaft_angle_rad: the described shaft angle (0 at its zero); "
            f"{driver}_angle_rad: the joint's own coordinate (0 at the export's pose)"
        )
    return ProbeResult(columns, comments, "shaft_angle_rad" if described else f"{driver}_angle_rad")


def probe_simulation(
    probes: Sequence[Probe],
    voltage: float,
    duration_s: float,
    description=None,
    progress: bool = False,
) -> ProbeResult:
    """Probe values along a dynamic simulation of the machine (motor, friction and loads of
    :class:`mechanism.machine.machine.Machine`; ``description`` as Machine takes it) from rest at
    shaft angle 0 under a constant voltage.

    The probes are added to the machine's spec before it is compiled; each 1 kHz sample
    of the simulation is replayed (``mj_setState`` + ``mj_forward``) to evaluate them."""
    from mechanism.machine.machine import Machine
    from mechanism.dynamics.simulation import simulate

    attached: list[AttachedProbe] = []
    machine = Machine(description, extend=lambda spec: attached.extend(add_probes(spec, probes)))
    result = simulate(voltage, duration_s, machine=machine, progress=progress)
    model, data = machine.model, machine.data
    motor = machine.actuator
    rows = []
    assert result.state is not None  # the full model's simulate() keeps every sample's state
    for state, applied in zip(result.state, result.voltage_V):
        mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        data.ctrl[motor] = applied
        mujoco.mj_forward(model, data)
        rows.append(read_probes(model, data, attached))
    table = np.asarray(rows).reshape(len(result.time_s), -1)
    columns = {"time_s": result.time_s, f"{machine.shaft_joint}_angle_rad": result.shaft_angle_rad}
    columns.update({name: table[:, i] for i, name in enumerate(_columns(attached))})
    comments = [
        f"dynamic simulation of {machine.name}: "
        + (
            f"{voltage:g} V"
            if not isinstance(voltage, dict)
            else ", ".join(f"{j} {v:g}" for j, v in voltage.items())
        )
        + f" for {duration_s:g} s from rest at shaft angle 0",
        "world frame, z up; force/torque = load on the child side of the joint, with friction and loads",
    ]
    return ProbeResult(columns, comments, "time_s")


def parse_probes(
    parts_args: Sequence[str], quantities: Sequence[str], points: Sequence[str] = ()
) -> list[Probe]:
    """Probes from CLI-style groups: each ``parts_args`` entry is a comma list of names;
    ``quantities`` and ``points`` have one entry for all groups or one per group (a
    quantity entry may be a comma list; a point is ``X,Y,Z`` in mm)."""
    groups = [[name.strip() for name in item.split(",") if name.strip()] for item in parts_args]
    if not groups or not all(groups):
        raise UserError("give at least one --part NAME")
    if len(quantities) not in (1, len(groups)):
        raise UserError(
            f"--quantity given {len(quantities)} times for {len(groups)} --part groups: give it once or once per --part"
        )
    if len(points) not in (0, 1, len(groups)):
        raise UserError(
            f"--point given {len(points)} times for {len(groups)} --part groups: give it once or once per --part"
        )
    probes = []
    for i, names in enumerate(groups):
        wanted = [
            q.strip() for q in quantities[0 if len(quantities) == 1 else i].split(",") if q.strip()
        ]
        point = None
        if points:
            text = points[0 if len(points) == 1 else i]
            try:
                x, y, z = (float(v) for v in text.split(","))  # not three numbers: a ValueError too
                point = (x, y, z)
            except ValueError:
                raise UserError(f"--point {text!r}: expected X,Y,Z in mm") from None
        for name in names:
            for quantity in wanted:
                probes.append(Probe(name, quantity, point))
    return list(dict.fromkeys(probes))


def run_probes(
    probes: Sequence[Probe],
    model_path: str | os.PathLike | None = None,
    voltage: float | None = None,
    duration_s: float | None = None,
    speed_rpm: float = DEFAULT_SPEED_RPM,
    revolutions: float = 1.0,
    resolution_deg: float = DEFAULT_RESOLUTION_DEG,
    driver: str | None = None,
    progress: bool = False,
    description=None,
) -> ProbeResult:
    """Probes over a dynamic simulation of the described machine (``voltage`` and
    ``duration_s`` given; default: the shipped one) or else a kinematic cycle of the model at
    ``model_path`` turned by ``driver``."""
    from mechanism.machine.models import load_spec

    if (voltage is None) != (duration_s is None):
        raise UserError("a dynamic run needs both a voltage and a duration")
    if voltage is not None and duration_s is not None:  # both or neither, checked above
        return probe_simulation(probes, voltage, duration_s, description, progress)
    return probe_cycle(
        load_spec(model_path), probes, speed_rpm, revolutions, resolution_deg, driver, description
    )


def plot_probes(result: ProbeResult, probes: Sequence[Probe], path: str | os.PathLike) -> None:
    from mechanism.files.plotting import plt, save_figure

    probes = list(dict.fromkeys(probes))
    x = result.columns[result.x_name]
    if result.x_name.endswith("_rad"):
        x, xlabel = np.degrees(x), result.x_name[: -len("_rad")] + " [deg]"
    else:
        x, xlabel = x, "time [s]"
    fig, axes = plt.subplots(
        len(probes), 1, figsize=(8, 2.4 * len(probes)), sharex=True, squeeze=False
    )
    for ax, probe in zip(axes[:, 0], probes):
        for name in probe.columns:
            ax.plot(x, result.columns[name], label=name)
        unit = (
            KINEMATIC[probe.quantity][2]
            if probe.quantity in KINEMATIC
            else LOADS[probe.quantity][3]
        )
        ax.set_ylabel(f"{probe.quantity} [{unit.replace('_', '/')}]")
        ax.legend(fontsize=7, loc="best")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel(xlabel)
    save_figure(fig, path)
