"""Dynamic design studies: what a flywheel, a counterweight, another motor, friction or the
supply do to the running machine, over thousands of variants.

Each variant of a variants file (``mechanism-variants/1``, :mod:`mechanism.inspection.variants`)
changes the machine by offsets from its description and its CAD model, and runs from rest
under a voltage step on the reduced 1-DOF model (:class:`~mechanism.dynamics.reduced.ReducedModel`,
the exact Lagrange equation of the linkage). Its metrics (:data:`METRICS`) describe the start
and the steady state. Nothing is compiled per variant:

- description values (``motor:``, ``supply:``, ``tool:``, ``friction:<joint>:``) rebuild the
  motor, friction laws, supply and fabric objects from an edited copy of the description;
- ``inertia:<joint>_kgm2`` adds ``I r_j(θ)²`` to the effective inertia J(θ) (r_j: the joint's
  ratio to the shaft), exact for a joint whose parent does not move (a shaft in the frame);
- ``mass:<part>_kg`` and geometric offsets edit a copy of the compiled model (the point mass
  merged into its body's inertia) and tabulate the linkage again (~0.1 s);
- the operating point (``voltage_V``, ``duty_percent``, ``layers``) is absolute.

:func:`variant_machine` builds the same variant the slow, independent way (an edited
description and a compiled MjSpec with the flywheel or mass as a welded child body): a single
``mechanism.simulate(variant_machine(...), reduced=True)`` gives the same metrics.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import mujoco
import numpy as np

from mechanism.batch.runner import Backend
from mechanism.dynamics.reduced import ReducedModel
from mechanism.errors import UserError, close_matches
from mechanism.kinematics.linkage import LinkageTables, compute_tables, periodic_derivative
from mechanism.machine import parts
from mechanism.machine.description import FRICTION_KEYS, SCHEMA, MachineDescription, check_value
from mechanism.machine.machine import (
    Machine,
    MachineConfig,
    duty_map_from,
    fabric_from_description,
    motor_from_description,
    supply_limit,
)
from mechanism.physics.friction import FrictionSet
from mechanism.inspection.sweep_journal import (
    journal_write_error,
    open_journal,
    read_journal,
    sweep_fingerprint,
)
from mechanism.inspection.sweep_metrics import METRICS, bearing_loads, variant_metrics
from mechanism.inspection.variants import (
    OPERATING_POINT,
    Parameter,
    VariantSet,
    _parse_target,
    apply_parameter,
    linear_coupling,
)

DESCRIPTION_SECTIONS = ("motor", "supply", "tool")  # description sections a sweep may offset
Values = Sequence[float] | np.ndarray  # one variant's parameter values, in the variants' order
REPLACED_IN_CODE = (
    "this machine's motor or fabric was replaced in code (MachineConfig): description offsets (motor:, "
    "tool:) would not reach it; describe it instead"
)
# what a welded point mass needs to compile (MuJoCo's minimum is 1e-15)
POINT_MASS_INERTIA_KGM2 = 1e-12


@dataclass(frozen=True)
class SweepOptions:
    """The run every variant gets: a voltage step from rest at the shaft's zero."""

    voltage_V: float = 12.0
    bearings: tuple[str, ...] = ()  # joints whose peak reaction force is reported (full model)
    duration_s: float = 2.0
    sample_rate_hz: float = 1000.0
    layers: int = 0
    full: bool = False  # the full multibody model (mujoco.rollout) instead of the reduced one


@dataclass
class SweepBase:
    """Everything a worker needs, picklable: it travels once per worker (the object store on Ray)."""

    description: MachineDescription
    config: MachineConfig
    model: mujoco.MjModel
    tables: LinkageTables
    machine_state: dict[str, Any]
    parameters: list[Parameter]
    options: SweepOptions

    @classmethod
    def of(
        cls, machine: Machine, parameters: Sequence[Parameter], options: SweepOptions
    ) -> "SweepBase":
        state = {
            name: getattr(machine, name)
            for name in (
                "motor_joint",
                "shaft_joint",
                "tool_site",
                "plate_part",
                "frame",
                "plate_top_z",
                "timestep_s",
            )
        }
        return cls(
            machine.description,
            machine.config,
            machine.model,
            machine.tables,
            state,
            list(parameters),
            options,
        )


class _VariantMachine:
    """The parts of a Machine the reduced model reads, with a variant's replacements."""

    def __init__(
        self,
        base: SweepBase,
        model: mujoco.MjModel,
        tables: LinkageTables,
        description: MachineDescription,
        layers: int,
    ):
        self.__dict__.update(base.machine_state)
        self.model, self.tables, self.description = model, tables, description
        self.config = config = replace(base.config, layers=layers)
        edited = description is not base.description
        if edited and (config.motor is not None or config.fabric is not None):
            raise UserError(REPLACED_IN_CODE)
        self.motor = config.motor or motor_from_description(description.motor)
        self.friction = FrictionSet(Machine.friction_laws(self))  # type: ignore[arg-type]
        fabric = replace(config.fabric, layers=layers) if config.fabric is not None else None
        self.fabric = fabric or fabric_from_description(description.section("tool"), layers)
        self.supply = supply_limit(description)

    tool_height_mm = Machine.tool_height_mm
    rated_voltage_V = Machine.rated_voltage_V
    check_voltage = Machine.check_voltage


# -- targets --------------------------------------------------------------------------------


def _split(target: str) -> tuple[str, str, str]:
    """``inertia:<joint>_kgm2`` -> ("inertia", joint, ""); ``friction:<joint>:<key>`` -> (..., joint, key)."""
    if target in OPERATING_POINT:
        return "operating", target, ""
    kind, _, rest = target.partition(":")
    if kind == "inertia":
        return kind, rest[: -len("_kgm2")], ""
    if kind == "mass":
        return kind, rest[: -len("_kg")], ""
    if kind == "ratio":
        return kind, rest, ""
    if kind == "friction":
        joint, _, key = rest.rpartition(":")
        return kind, joint, key
    if kind in DESCRIPTION_SECTIONS:
        return kind, rest, ""
    return "geometry", target, ""


def check_parameters(base: SweepBase, variants: VariantSet) -> None:
    """Every target exists in the machine and every variant's value is physical, before any run."""
    model = base.model
    label = variants.source
    joints = parts.joint_names(model)
    for column, param in enumerate(variants.parameters):
        values = variants.values[:, column]
        where = f"{label}: parameter {param.name} ({param.target})"
        if not param.dynamic:
            try:
                param.check(model)
            except UserError as exc:
                raise UserError(f"{label}: {exc}") from None
            continue
        kind, name, key = _split(param.target)
        if kind == "inertia":
            _flywheel_joint(model, name, where)
            _non_negative(values, variants, where, "added inertia")
        elif (
            kind == "mass"
        ):  # a part, a named frame, a body or a geom: wherever the point mass sits
            if name not in parts.frame_names(model):
                raise UserError(
                    f"{where}: no part, frame or body named {name!r}; close matches: "
                    f"{close_matches(name, parts.frame_names(model))}"
                )
            _non_negative(values, variants, where, "added mass")
        elif kind == "ratio":
            eq = linear_coupling(model, name, where, "its ratio cannot be offset")
            ratios = model.eq_data[eq, 1] + values
            if np.any(ratios * model.eq_data[eq, 1] <= 0):
                raise UserError(
                    f"{where}: the ratio must keep its sign and stay non-zero (nominal {model.eq_data[eq, 1]:g})"
                )
        elif kind == "friction":
            if name not in joints:
                raise UserError(
                    f"{where}: no joint named {name!r}; close matches: {close_matches(name, joints)}"
                )
            _numeric_key(key, FRICTION_KEYS, where)
        elif kind in DESCRIPTION_SECTIONS:
            _numeric_key(name, SCHEMA[kind], where)
        elif name == "duty_percent":
            duty_map_from(base.description)  # the machine must describe its PWM supply
            _within(values, variants, where, 0.0, 100.0)
        elif name == "layers":
            if np.any(values != np.round(values)):
                raise UserError(f"{where}: layers must be whole numbers")
            _within(values, variants, where, 0.0, 20.0)
            if np.any(values > 0) and not (
                base.machine_state["tool_site"] and base.machine_state["plate_part"]
            ):
                raise UserError(
                    f"{where}: fabric layers need a tool site and a plate in the machine description"
                )
        else:
            _within(values, variants, where, -1000.0, 1000.0)
    _check_description_offsets(base.description, variants)


def _check_description_offsets(description: MachineDescription, variants: VariantSet) -> None:
    """Every variant's edited description values within the schema's physical range, checked
    on the columns at once (a variant that cannot exist is a bad file, not a row note)."""
    totals: dict[tuple[str, str, str], np.ndarray] = {}
    for column, param in enumerate(variants.parameters):
        kind, name, key = _split(param.target) if param.dynamic else ("geometry", "", "")
        if kind == "friction" or kind in DESCRIPTION_SECTIONS:
            totals[(kind, name, key)] = (
                totals.get((kind, name, key), 0.0) + variants.values[:, column]
            )
    for (kind, name, key), offsets in totals.items():
        if kind == "friction":
            table, spec, field_name = description.friction.get(name, {}), FRICTION_KEYS[key], key
            start = table.get(key, _default(key, table))
        else:
            table = description.motor if kind == "motor" else description.section(kind)
            spec, field_name = SCHEMA[kind][name], name
            if name not in table:
                raise UserError(
                    f"{variants.source}: {description.where(kind, name)} is not in the description; an "
                    "offset needs a value to start from"
                )
            start = table[name]
        values = start + offsets
        low = (
            values < spec.low
            if spec.low is not None and not spec.open_low
            else values <= spec.low
            if spec.low is not None
            else np.zeros(len(values), bool)
        )
        bad = np.flatnonzero(low | ((values > spec.high) if spec.high is not None else False))
        if bad.size:
            i = int(bad[0])
            raise UserError(
                f"{variants.source}: variant {variants.names[i]!r} makes {kind} {field_name} "
                f"{'of ' + name + ' ' if kind == 'friction' else ''}{values[i]:g}, outside its range ({spec.doc})"
            )


def _numeric_key(key: str, keys: dict, where: str) -> None:
    numeric = [k for k, spec in keys.items() if spec.kind in (float, int)]
    if key not in numeric:
        raise UserError(
            f"{where}: {key!r} is not a numeric key of the description; close matches: {close_matches(key, numeric)}"
        )


def _non_negative(values: np.ndarray, variants: VariantSet, where: str, what: str) -> None:
    bad = np.flatnonzero(values < 0)
    if bad.size:
        raise UserError(
            f"{where}: {what} must be >= 0, variant {variants.names[bad[0]]!r} has {values[bad[0]]:g}"
        )


def _within(values: np.ndarray, variants: VariantSet, where: str, low: float, high: float) -> None:
    bad = np.flatnonzero((values < low) | (values > high))
    if bad.size:
        raise UserError(
            f"{where}: values must lie in [{low:g}, {high:g}], variant {variants.names[bad[0]]!r} has {values[bad[0]]:g}"
        )


def _flywheel_joint(model: mujoco.MjModel, joint: str, where: str) -> int:
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    if jid < 0 or model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
        hinges = [
            n
            for n in parts.joint_names(model)
            if model.jnt_type[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n)]
            == mujoco.mjtJoint.mjJNT_HINGE
        ]
        raise UserError(
            f"{where}: no hinge joint named {joint!r}; close matches: {close_matches(joint, hinges)}"
        )
    parent = int(model.body_parentid[model.jnt_bodyid[jid]])
    if model.body_weldid[parent] != 0:
        raise UserError(
            f"{where}: joint {joint!r} sits on a moving body; inertia about its axis is exact only for a "
            "shaft in the frame: add a mass:<part>_kg instead"
        )
    return jid


# -- one variant ----------------------------------------------------------------------------


def edited_description(
    description: MachineDescription, changes: dict[tuple[str, str, str], float]
) -> MachineDescription:
    """The description with offsets added to numeric values (each checked against the schema)."""
    sections = {name: dict(values) for name, values in description.sections.items()}
    motor = dict(description.motor)
    friction = {joint: dict(values) for joint, values in description.friction.items()}
    source = str(description.path or "<description>")
    for (kind, name, key), offset in changes.items():
        if kind == "friction":
            table = friction.setdefault(name, {})
            spec, value = FRICTION_KEYS[key], table.get(key, _default(key, table)) + offset
            table[key] = check_value(source, f"friction.{name}", key, spec, _typed(spec, value))
            if (
                key == "coulomb_Nm"
                and "static_Nm" in table
                and table["static_Nm"] < table["coulomb_Nm"]
            ):
                table["static_Nm"] = table["coulomb_Nm"]
        else:
            table = motor if kind == "motor" else sections.setdefault(kind, {})
            spec = SCHEMA[kind][name]
            if name not in table and kind != "motor":
                raise UserError(
                    f"{description.where(kind, name)}: not in the description; an offset needs a value to start from"
                )
            table[name] = check_value(
                source, kind, name, spec, _typed(spec, table.get(name, 0.0) + offset)
            )
    if "motor" in sections:
        sections["motor"] = motor
    return replace(description, motor=motor, friction=friction, sections=sections)


def _default(key: str, table: dict) -> float:
    return table.get("coulomb_Nm", 0.0) if key == "static_Nm" else 0.0


def _typed(spec, value: float):
    return int(round(value)) if spec.kind is int else float(value)


@dataclass
class _Variant:
    """One variant's values sorted by what they change."""

    description: dict[tuple[str, str, str], float] = field(default_factory=dict)
    inertia: dict[str, float] = field(default_factory=dict)
    mass: dict[str, float] = field(default_factory=dict)
    ratio: dict[str, float] = field(default_factory=dict)
    geometry: list[tuple[Parameter, float]] = field(default_factory=list)
    operating: dict[str, float] = field(default_factory=dict)


def _sort(parameters: Sequence[Parameter], values: Values) -> _Variant:
    variant = _Variant()
    for param, value in zip(parameters, values):
        value = float(value)
        if not param.dynamic:
            variant.geometry.append((param, value))
            continue
        kind, name, key = _split(param.target)
        if kind == "inertia":
            variant.inertia[name] = variant.inertia.get(name, 0.0) + value
        elif kind == "mass":
            variant.mass[name] = variant.mass.get(name, 0.0) + value
        elif kind == "ratio":
            variant.ratio[name] = variant.ratio.get(name, 0.0) + value
        elif kind == "operating":
            if not math.isnan(value):  # NaN: the run's default
                variant.operating[name] = value
        elif value:
            variant.description[(kind, name, key)] = (
                variant.description.get((kind, name, key), 0.0) + value
            )
    return variant


def _voltage(base: SweepBase, variant: _Variant) -> float:
    if "duty_percent" in variant.operating:
        return float(duty_map_from(base.description)(variant.operating["duty_percent"]))
    return variant.operating.get("voltage_V", base.options.voltage_V)


def _mass_point(
    model: mujoco.MjModel,
    nominal: mujoco.MjModel,
    part: str,
    geometry: list[tuple[Parameter, float]],
) -> tuple[int, np.ndarray]:
    """Body and body-frame position [m] of a part's frame, moved by the variant's part offsets."""
    frame = parts.find_frame(nominal, part)
    position = np.array(frame.pos, dtype=float)
    for param, value in geometry:
        for target in param.target.split("+"):
            kind, name, axis, _ = _parse_target(target)
            if kind == "part" and name == part:
                along = np.zeros(3)
                along["xyz".index(axis)] = 1.0
                mujoco.mju_rotVecQuat(along, along.copy(), np.asarray(frame.quat, dtype=float))
                position += value * 1e-3 * along
    return frame.body, position


def change_ratios(model: mujoco.MjModel, offsets: dict[str, float]) -> None:
    """Add to the ratio (``polycoef``'s linear term) of linear joint couplings, in place."""
    for name, offset in offsets.items():
        if offset:
            model.eq_data[
                linear_coupling(model, name, f"ratio:{name}", "its ratio cannot be offset"), 1
            ] += offset


def add_point_mass(
    model: mujoco.MjModel, body: int, position_m: np.ndarray, mass_kg: float
) -> None:
    """Merge a point mass into a body's mass, centre of mass and principal inertia (parallel axes)."""
    if mass_kg == 0.0:
        return
    old_mass, old_com = float(model.body_mass[body]), np.array(model.body_ipos[body])
    flat = np.zeros(9)
    mujoco.mju_quat2Mat(flat, model.body_iquat[body])
    rotation = flat.reshape(3, 3)
    tensor = rotation @ np.diag(model.body_inertia[body]) @ rotation.T
    mass = old_mass + mass_kg
    com = (old_mass * old_com + mass_kg * position_m) / mass
    for m, point in ((old_mass, old_com), (mass_kg, position_m)):
        d = point - com
        tensor = tensor + m * (d @ d * np.eye(3) - np.outer(d, d))
    principal, axes = np.linalg.eigh(tensor)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, axes.ravel())
    model.body_mass[body], model.body_ipos[body] = mass, com
    model.body_inertia[body], model.body_iquat[body] = principal, quat


class VariantRunner:
    """One worker's sweep: the base machine's pieces, one model copy edited in place when needed."""

    def __init__(self, base: SweepBase):
        self.base = base
        self.model = copy.deepcopy(base.model)

    def tables(self, variant: _Variant) -> tuple[mujoco.MjModel, LinkageTables]:
        base, state = self.base, self.base.machine_state
        model, tables = base.model, base.tables
        if variant.mass or variant.geometry or any(variant.ratio.values()):
            model = self.model
            for name in (
                "body_pos",
                "eq_data",
                "geom_pos",
                "site_pos",
                "body_mass",
                "body_ipos",
                "body_inertia",
                "body_iquat",
            ):
                getattr(model, name)[:] = getattr(base.model, name)
            for param, value in variant.geometry:
                apply_parameter(model, base.model, param, value)
            change_ratios(model, variant.ratio)
            for part, mass in variant.mass.items():
                body, position = _mass_point(model, base.model, part, variant.geometry)
                add_point_mass(model, body, position, mass)
            tables = compute_tables(
                model,
                state["shaft_joint"],
                state["tool_site"],
                len(base.tables.angle_rad),
                state["frame"].zero_rad,
                state["frame"].direction,
            )
        if any(variant.inertia.values()):
            inertia = tables.inertia_kgm2 + sum(
                added * tables.ratios[joint] ** 2 for joint, added in variant.inertia.items()
            )
            tables = replace(
                tables, inertia_kgm2=inertia, dinertia_drad=periodic_derivative(inertia)
            )
        return model, tables

    def reduced(self, values: Values) -> tuple[ReducedModel, float]:
        variant = _sort(self.base.parameters, values)
        model, tables = self.tables(variant)
        description = (
            edited_description(self.base.description, variant.description)
            if variant.description
            else self.base.description
        )
        layers = int(variant.operating.get("layers", self.base.options.layers))
        machine = _VariantMachine(self.base, model, tables, description, layers)
        return ReducedModel(machine, len(tables.angle_rad)), _voltage(self.base, variant)  # type: ignore[arg-type]

    def __call__(self, values: Values) -> dict[str, Any]:
        try:
            reduced, voltage = self.reduced(values)
            options = self.base.options
            result = reduced.simulate(
                voltage, options.duration_s, sample_rate_hz=options.sample_rate_hz
            )
        except UserError as exc:  # this variant cannot be built or run: say so in its row
            return {**{name: math.nan for name in METRICS}, "note": str(exc)}
        return variant_metrics(result, reduced)


def _run_variant(runner: VariantRunner, values: np.ndarray) -> dict[str, Any]:
    return runner(values)


FULL_GROUP = 8  # variants per rollout call and thread: enough to keep the pool busy, few to hold


@dataclass
class _FullShared:
    base: SweepBase
    threads: int
    one_dof: bool = True


class FullRunner:
    """A worker of a ``--full`` sweep: each group of variants compiled as Machines (~10 ms
    each) and run together in one ``mujoco.rollout`` call on ``threads`` threads."""

    def __init__(self, shared: _FullShared):
        from mechanism.machine.machine import Machine

        self.shared = shared
        self.machine = Machine(shared.base.description, shared.base.config)
        self.reduced_runner = VariantRunner(shared.base)

    def __call__(self, group: Sequence[np.ndarray]) -> list[dict[str, Any]]:
        from mechanism.dynamics.simulation import simulate_batch

        base, options = self.shared.base, self.shared.base.options
        built = [
            variant_machine(
                self.machine, base.parameters, values, options.bearings, options.voltage_V
            )
            for values in group
        ]
        reduced = [self.reduced_runner.reduced(values)[0] for values in group]
        for (variant, _), tables in zip(built, reduced):
            # the same geometry: no second tabulation (~0.1 s) for the tool height
            variant.tables = tables.tables
        results = simulate_batch(
            [m for m, _ in built],
            [v for _, v in built],
            options.duration_s,
            sample_rate_hz=options.sample_rate_hz,
            threads=self.shared.threads,
        )
        rows = []
        for model, result in zip(reduced, results):
            if isinstance(result, UserError):
                rows.append({**{name: math.nan for name in METRICS}, "note": str(result)})
                continue
            row = variant_metrics(result, model)  # break-away from the same tables
            if (
                not self.shared.one_dof
            ):  # the tables are the 1-DOF equation's: no break-away, no tool timing
                row["breakaway_V"] = row["tool_above_plate_ms"] = math.nan
            row.update(bearing_loads(result, options.bearings))
            rows.append(row)
        return rows


def _run_group(runner: FullRunner, group: Sequence[np.ndarray]) -> list[dict[str, Any]]:
    return runner(group)


# -- the batch ------------------------------------------------------------------------------


@dataclass
class SweepResult:
    variants: VariantSet
    rows: list[dict[str, Any]]
    options: SweepOptions
    seconds: float = 0.0
    resumed: int = 0  # rows kept from an interrupted run
    # of the machine: other than 1, the full model ran (the reduced one is 1-DOF)
    degrees_of_freedom: int = 1

    @property
    def model(self) -> str:
        if self.degrees_of_freedom != 1:
            return f"full multibody model (the machine has {self.degrees_of_freedom} degrees of freedom)"
        return "full multibody model" if self.options.full else "reduced 1-DOF model"

    def table(self) -> list[dict[str, Any]]:
        out = []
        for name, values, row in zip(self.variants.names, self.variants.values, self.rows):
            entry: dict[str, Any] = {"variant": name}
            entry.update({p.name: float(v) for p, v in zip(self.variants.parameters, values)})
            entry.update({key: row.get(key, math.nan) for key in METRICS})
            entry.update(
                {key: value for key, value in row.items() if key not in METRICS and key != "note"}
            )
            entry["note"] = row.get("note", "")
            out.append(entry)
        return out


def run_sweep(
    machine: Machine,
    variants: VariantSet,
    options: SweepOptions = SweepOptions(),
    *,
    workers: int = 1,
    backend: Backend = "local",
    ray_address: str | None = None,
    progress: bool = True,
    journal: str | os.PathLike | None = None,
    resume: bool = False,
    on_row: Callable[[int, dict[str, Any]], None] | None = None,
) -> SweepResult:
    """Every variant's metrics, in file order. With ``journal``, each row is appended to that
    file as it completes; ``resume=True`` keeps the rows an interrupted run of the same sweep
    left there and runs only the others. ``on_row(index, row)`` sees each new row."""
    import time

    from mechanism.batch import BatchLost, check_options, run_batch
    from mechanism.batch.runner import item_ranges

    check_options(backend, workers)
    from mechanism.kinematics.pose import degrees_of_freedom

    mobility = degrees_of_freedom(machine.model, machine.reset(0.0))
    if (
        mobility != 1 or not machine.rotates
    ) and not options.full:  # the reduced model is the 1-DOF equation of a
        options = replace(options, full=True)  # shaft that turns: not this machine's
    base = SweepBase.of(machine, variants.parameters, options)
    variants = with_defaults(variants, options)
    check_parameters(base, variants)
    fingerprint = sweep_fingerprint(machine, variants, options)
    start = time.perf_counter()
    with contextlib.ExitStack() as stack:
        if (
            journal is not None
        ):  # one sweep at a time writes a journal: a second one would mix rows in
            from mechanism.files.outputs import output_lock

            # as the journal's own first write does
            Path(journal).parent.mkdir(parents=True, exist_ok=True)
            stack.enter_context(
                output_lock(
                    [journal],
                    wait_s=0,
                    busy=(
                        "sweep journal {path}: another sweep{holder} is writing it (the same --csv); wait for it to "
                        "finish or choose another --csv"
                    ),
                )
            )
        done = read_journal(journal, fingerprint) if journal is not None and resume else {}
        todo = [i for i in range(len(variants)) if i not in done]
        log = (
            stack.enter_context(open_journal(journal, fingerprint, fresh=not done))
            if journal is not None
            else None
        )

        def keep(position: int, row: dict[str, Any]) -> None:
            if log is not None:
                try:
                    log.write(json.dumps({"index": todo[position], "row": row}) + "\n")
                    log.flush()
                except OSError as exc:
                    assert journal is not None  # a log is open only with a journal
                    raise journal_write_error(journal, exc) from None
            if on_row is not None:
                on_row(todo[position], row)

        try:
            if options.full:
                rows = _run_full(
                    base,
                    variants,
                    todo,
                    keep,
                    workers,
                    backend,
                    ray_address,
                    progress,
                    mobility == 1,
                )
            else:
                rows = run_batch(
                    _run_variant,
                    [variants.values[i] for i in todo],
                    shared=base,
                    setup=VariantRunner,
                    workers=workers,
                    backend=backend,
                    ray_address=ray_address,
                    on_result=keep,
                    progress=progress,
                    desc="variants",
                    unit="variant",
                )
        except BatchLost as exc:  # name the variants (rows of the table), and say how to go on
            lost = [todo[i] for i in exc.unfinished if i < len(todo)]
            kept = (
                f"; the finished rows are kept in {journal}: run it again with --resume to continue"
                if journal
                else ""
            )
            raise UserError(
                f"the Ray cluster was lost mid-sweep ({exc.cause}): {len(lost)} of {len(variants)} variants "
                f"did not run (variants {item_ranges(lost)}, numbered from 0 as in the file){kept}"
            ) from None
    done.update(zip(todo, rows))
    return SweepResult(
        variants,
        [done[i] for i in range(len(variants))],
        options,
        time.perf_counter() - start,
        resumed=len(variants) - len(todo),
        degrees_of_freedom=mobility,
    )


def with_defaults(variants: VariantSet, options: SweepOptions) -> VariantSet:
    """Operating points a row leaves out (NaN) filled with the run's: the table shows what ran."""
    values = variants.values.copy()
    for column, param in enumerate(variants.parameters):
        default = {"voltage_V": options.voltage_V, "layers": float(options.layers)}.get(
            param.target
        )
        if default is not None:
            values[np.isnan(values[:, column]), column] = default
    return replace(variants, values=values)


def _run_full(
    base: SweepBase,
    variants: VariantSet,
    todo: list[int],
    keep: Callable[[int, dict[str, Any]], None],
    workers: int,
    backend: Backend,
    ray_address: str | None,
    progress: bool,
    one_dof: bool,
) -> list[dict[str, Any]]:
    """Groups of variants through ``mujoco.rollout``: locally one process whose rollout pool
    has ``workers`` threads; on Ray one thread per task, the cluster's tasks in parallel."""
    from mechanism.batch import BatchLost, run_batch

    local = backend == "local"
    size = FULL_GROUP * (workers if local else 1)
    groups = [todo[i : i + size] for i in range(0, len(todo), size)]
    starts = np.cumsum([0] + [len(g) for g in groups])

    def keep_group(position: int, rows: list[dict[str, Any]]) -> None:
        for offset, row in enumerate(rows):
            keep(int(starts[position]) + offset, row)

    shared = _FullShared(base, workers if local else 1, one_dof)
    try:
        results = run_batch(
            _run_group,
            [[variants.values[i] for i in group] for group in groups],
            shared=shared,
            setup=FullRunner,
            workers=1 if local else workers,
            backend=backend,
            ray_address=ray_address,
            on_result=keep_group,
            progress=progress,
            desc=f"groups of {size} variants",
            unit="group",
        )
    except BatchLost as exc:  # groups lost: the positions (in todo) of their variants
        positions = [int(starts[g]) + k for g in exc.unfinished for k in range(len(groups[g]))]
        raise BatchLost(str(exc), positions, exc.cause) from None
    return [row for rows in results for row in rows]


def plot_sweep(
    result: SweepResult, path: str | os.PathLike, x: str | None = None, group: str | None = None
) -> Path:
    """Speed, ripple, settling time and peak current against one parameter (``x``: default the
    first that varies), one line per value of another (``group``: default the next that varies)."""
    from mechanism.files.plotting import plt, save_figure

    variants = result.variants
    names = [p.name for p in variants.parameters]
    varying = [n for i, n in enumerate(names) if len(np.unique(variants.values[:, i])) > 1]
    for given in (x, group):
        if given is not None and given not in names:
            raise UserError(
                f"--plot parameter {given!r} is not in the variants file; close matches: {close_matches(given, names)}"
            )
    x = x or (varying[0] if varying else names[0])
    group = group or next((n for n in varying if n != x), None)
    table = result.table()
    panels = [
        ("mean_speed_rpm", "mean speed [rpm]"),
        ("ripple_pp_rad_s", "speed ripple p-p [rad/s]"),
        ("settling_s", "settling time [s]"),
        ("peak_current_A", "peak current [A]"),
    ]
    figure, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    groups = sorted({row[group] for row in table}) if group else [None]
    many = len(groups) > 12 or len({row[x] for row in table}) > 200
    for axis, (key, label) in zip(axes.ravel(), panels):
        for value in groups:
            rows = sorted(
                (row for row in table if group is None or row[group] == value),
                key=lambda row: row[x],
            )
            xs, ys = [row[x] for row in rows], [row[key] for row in rows]
            style = (
                dict(marker=".", linestyle="none", markersize=3)
                if many
                else dict(marker="o", markersize=3)
            )
            axis.plot(
                xs, ys, label=None if group is None or many else f"{group} = {value:g}", **style
            )
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    for axis in axes[1]:
        axis.set_xlabel(x)
    if group and not many:
        axes[0, 0].legend(fontsize=8)
    figure.suptitle(f"{len(table)} variants, {result.options.duration_s:g} s from rest each")
    figure.tight_layout()
    save_figure(figure, path)
    return Path(path)


# -- the independent way: a real Machine per variant ------------------------------------------


def variant_machine(
    machine: Machine,
    parameters: Sequence[Parameter],
    values: Values,
    bearings: Sequence[str] = (),
    voltage_V: float = SweepOptions.voltage_V,
) -> tuple[Machine, float]:
    """The variant as a full :class:`Machine` (edited description, the flywheel or mass compiled
    as a welded child body, geometry edited in the compiled model) and its motor voltage:
    slow, independent of the sweep's shortcuts, for checks, for ``--full`` and for a closer look
    at one variant. Every inertia and mass parameter adds its body, zero or not, so that all
    variants of one sweep share a size signature (``mujoco.rollout`` runs them together).
    ``bearings``: joints whose reaction force a ``bearing:<joint>`` force sensor measures (on
    the child body, at the joint's anchor, in the child's frame); ``voltage_V``: the run's
    voltage when the variant sets none."""
    base = SweepBase.of(machine, parameters, SweepOptions(voltage_V=voltage_V))
    variant = _sort(parameters, values)
    if variant.description and (
        machine.config.motor is not None or machine.config.fabric is not None
    ):
        raise UserError(REPLACED_IN_CODE)
    description = (
        edited_description(machine.description, variant.description)
        if variant.description
        else machine.description
    )
    nominal = machine.model
    # every inertia and mass target adds its body, zero or not: one size signature for the whole sweep
    targets = [_split(p.target) for p in parameters if p.dynamic]
    inertias = {
        name: variant.inertia.get(name, 0.0) for kind, name, _ in targets if kind == "inertia"
    }
    masses = {name: variant.mass.get(name, 0.0) for kind, name, _ in targets if kind == "mass"}

    def extend(spec: mujoco.MjSpec) -> None:
        if machine._extend is not None:
            machine._extend(spec)
        for joint, inertia in inertias.items():
            jid = mujoco.mj_name2id(nominal, mujoco.mjtObj.mjOBJ_JOINT, joint)
            holder = spec.body(nominal.body(int(nominal.jnt_bodyid[jid])).name)
            turn = np.zeros(4)  # the disc's own z along the joint axis
            mujoco.mju_quatZ2Vec(turn, np.array(nominal.jnt_axis[jid], dtype=float))
            # a thin disc: the added inertia about the axis, half of it across (only the axial part moves)
            holder.add_body(
                name=f"flywheel:{joint}",
                pos=nominal.jnt_pos[jid],
                ipos=[0.0, 0.0, 0.0],
                quat=turn,
                mass=POINT_MASS_INERTIA_KGM2,
                inertia=[inertia / 2, inertia / 2, inertia],
                explicitinertial=True,
            )
        for part, mass in masses.items():
            body, position = _mass_point(nominal, nominal, part, variant.geometry)
            holder = spec.body(nominal.body(body).name)
            holder.add_body(
                name=f"mass:{part}",
                pos=position,
                ipos=[0.0, 0.0, 0.0],
                mass=mass,
                inertia=[POINT_MASS_INERTIA_KGM2] * 3,
                explicitinertial=True,
            )
        for joint in bearings:
            jid = mujoco.mj_name2id(nominal, mujoco.mjtObj.mjOBJ_JOINT, joint)
            child = spec.body(nominal.body(int(nominal.jnt_bodyid[jid])).name)
            site = child.add_site(name=f"bearing:{joint}", pos=nominal.jnt_pos[jid])
            spec.add_sensor(
                name=f"bearing:{joint}",
                type=mujoco.mjtSensor.mjSENS_FORCE,
                objtype=mujoco.mjtObj.mjOBJ_SITE,
                objname=site.name,
            )

    layers = int(variant.operating.get("layers", machine.config.layers))
    built = Machine(description, replace(machine.config, layers=layers), extend)
    unedited = copy.deepcopy(built.model)
    for param, value in variant.geometry:
        apply_parameter(built.model, unedited, param, value)
    change_ratios(built.model, variant.ratio)
    return built, _voltage(base, variant)


def check_bearings(model: mujoco.MjModel, bearings: Sequence[str]) -> None:
    """Bearing loads are measured on tree joints (a loop's joint is an equality constraint)."""
    joints = parts.joint_names(model)
    for joint in bearings:
        if joint not in joints:
            raise UserError(
                f"--bearings: no joint named {joint!r}; close matches: {close_matches(joint, joints)}"
            )
