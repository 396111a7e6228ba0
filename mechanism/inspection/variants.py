"""Design variants: parameter edits, variant files, and batch clearance checks.

A **parameter** changes one dimension of the machine by an offset from the nominal design.
Its target says what it changes (the same grammar in JSON and as a CSV column name):

``coupling:<name>:<joint>_deg``   advance ``<joint>`` (one of the two joints of the coupling
                                  ``coupling:<name>``) by the value relative to the other:
                                  hook timing. ``_mm`` for a slide joint.
``joint:<name>:<axis>_mm``        move a joint on its parent side: a tree joint's child body
                                  moves (with everything it carries) along ``x``/``y``/``z`` of
                                  the parent body frame, or ``radial``: away from the parent's
                                  own rotation axis (a crank pin: crank radius). A loop joint's
                                  anchors move on its base body (the follower keeps its own).
``body:<name>:<axis>_mm``         move a body in its parent frame (same as its tree joint).
``part:<name>:<axis>_mm``         move one part's geoms, its site and the user frames that lie on
                                  it within their body, along the part frame's axis (a needle set
                                  higher in its bar).

Dynamic targets change what the machine weighs and drives rather than its shape; only
``mechanism sweep`` (:mod:`mechanism.inspection.sweep`) takes them:

``inertia:<joint>_kgm2``          inertia added about the joint's axis on its child body (a flywheel)
``mass:<part>_kg``                a point mass added at the part's frame, moved with the part by
                                  ``part:<name>:<axis>_mm`` (a counterweight)
``ratio:<coupling>``              the ratio of a linear coupling ``coupling:<name>`` (first joint
                                  turns per turn of the second), as an offset: another pulley
``motor:<key>``, ``supply:<key>``, ``tool:<key>``, ``friction:<joint>:<key>``
                                  a numeric value of the machine description, as an offset
``voltage_V``, ``duty_percent``, ``layers``
                                  the operating point, absolute (motor voltage, PWM duty through the
                                  described supply, fabric layers)

Several targets joined by ``+`` change together by the same value. Presets for the sewing
machine's description (``[variant_presets]``) names the usual ones. The edits are made on
the compiled model's fields (``body_pos``, ``eq_data``, ``geom_pos``, ``site_pos``), which are
exactly what the corresponding ``MjSpec`` attributes compile to. Recompiling a spec would not
do: the compiler re-derives every ``connect``/``weld`` anchor on the second body from the
assembly pose, i.e. it closes every loop in the export pose and silently cancels a crank
radius or needle-bar height change. Edited in the model, the anchors keep their nominal
local positions and the pose solver re-assembles the changed linkage.

A **variants file** (JSON, or CSV with one column per parameter) lists the variants; see
:func:`read_variants`. :func:`run_variants` checks every variant's clearances in parallel
(``mechanism.batch``: local processes or a Ray cluster, each worker copying the model and
building the fcl BVHs once).
"""

from __future__ import annotations

import itertools
import math
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

import mujoco
import numpy as np

from mechanism.batch.runner import Backend
from mechanism.machine import parts
from mechanism.errors import UserError, close_matches

if TYPE_CHECKING:  # the clearance checker (fcl) loads only where a clearance batch runs
    from mechanism.inspection.clearance import Pair

FORMAT = "mechanism-variants/1"
MAX_VARIANTS = 1_000_000
CONFIRM_VARIANTS = 100_000  # more than this needs the user's explicit yes (--yes)
EDITED_FIELDS = ("body_pos", "eq_data", "geom_pos", "site_pos")


_TARGET = re.compile(r"(coupling|joint|body|part):([^:]+):([A-Za-z0-9_.-]+?)_(deg|mm)")
_DYNAMIC = re.compile(
    r"inertia:.+_kgm2|mass:.+_kg|ratio:[^:]+|(motor|supply|tool):[A-Za-z0-9_]+"
    r"|friction:[^:]+:[A-Za-z0-9_]+|voltage_V|duty_percent|layers"
)
OPERATING_POINT = ("voltage_V", "duty_percent", "layers")  # absolute values, not offsets


@dataclass(frozen=True)
class Parameter:
    """One named dimension of the design, as an offset from nominal."""

    name: str
    target: str

    def check(self, model: mujoco.MjModel) -> None:
        """Raise UserError if the target does not exist in ``model``."""
        if self.dynamic:
            raise UserError(
                f"parameter {self.name}: {self.target!r} is a dynamic target (mass, inertia, a "
                "description value, the operating point): `mechanism sweep` takes it, geometric checks do not"
            )
        apply_parameter(model, model, self, 0.0, check_only=True)

    @property
    def dynamic(self) -> bool:
        """A dynamic target (mass, inertia, description value, operating point): for sweeps only."""
        return bool(_DYNAMIC.fullmatch(self.target))


def _parse_target(target: str) -> tuple[str, str, str, str]:
    match = _TARGET.fullmatch(target.strip())
    if not match:
        raise UserError(
            f"parameter target {target!r}: expected coupling:<name>:<joint>_deg, joint:<name>:<x|y|z|radial>_mm, "
            "body:<name>:<x|y|z>_mm or part:<name>:<x|y|z>_mm, a dynamic target (inertia:<joint>_kgm2, "
            "mass:<part>_kg, ratio:<coupling>, motor:<key>, supply:<key>, tool:<key>, friction:<joint>:<key>, voltage_V, "
            "duty_percent, "
            "layers), or a preset of the machine's description"
        )
    return match.group(1), match.group(2), match.group(3), match.group(4)


def parameter(
    name: str, target: str | None = None, presets: dict[str, str] | None = None
) -> Parameter:
    """A parameter from a target string (several joined by ``+`` change together) or a
    preset name."""
    target = (target or (presets or {}).get(name, name)).strip()
    if _DYNAMIC.fullmatch(target):
        return Parameter(name, target)
    if ":" not in target and presets is not None:  # a bare name: a preset, perhaps misspelt
        known = [*presets, *OPERATING_POINT]
        raise UserError(
            f"parameter {target!r} is neither a preset of the machine's description nor a target; "
            f"close matches: {close_matches(target, known)}"
        )
    for single in target.split("+"):
        _parse_target(single)
    return Parameter(name, target)


_AXES = {"x": 0, "y": 1, "z": 2}


def _axis(axis: str, allowed: str) -> np.ndarray:
    if axis not in allowed:
        raise UserError(f"axis {axis!r}: expected one of {', '.join(allowed)}")
    vector = np.zeros(3)
    vector[_AXES[axis]] = 1.0
    return vector


def _rotate(quat, vector) -> np.ndarray:
    out = np.zeros(3)
    mujoco.mju_rotVecQuat(out, np.asarray(vector, dtype=float), np.asarray(quat, dtype=float))
    return out


def apply_parameter(
    model: mujoco.MjModel,
    nominal: mujoco.MjModel,
    param: Parameter,
    value: float,
    check_only: bool = False,
) -> None:
    """Add ``value`` (deg or mm) of ``param`` to ``model``, starting from ``nominal``'s fields."""
    for target in param.target.split("+"):
        _apply_target(model, nominal, param.name, target, value, check_only)


def _apply_target(model, nominal, label: str, target: str, value: float, check_only: bool) -> None:
    kind, name, detail, unit = _parse_target(target)
    if kind == "coupling":
        eq = linear_coupling(nominal, name, f"parameter {label}", "its offset cannot be shifted")
        joints = [
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, model.eq_obj1id[eq]),
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, model.eq_obj2id[eq]),
        ]
        if detail not in joints:
            raise UserError(
                f"parameter {label}: coupling {name!r} joins {joints[0]} and {joints[1]}, not {detail!r}"
            )
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, detail)
        slide = model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_SLIDE
        if unit != ("mm" if slide else "deg"):
            raise UserError(
                f"parameter {label}: joint {detail!r} is a {'slide' if slide else 'hinge'}: use _{'mm' if slide else 'deg'}"
            )
        if check_only:
            return
        delta = value / 1000.0 if slide else np.radians(value)
        # q1 = c0 + c1 q2: advancing joint1 adds to c0; advancing joint2 by d needs c0 - c1 d
        model.eq_data[eq, 0] = nominal.eq_data[eq, 0] + (
            delta if detail == joints[0] else -nominal.eq_data[eq, 1] * delta
        )
        return
    if unit != "mm":
        raise UserError(f"parameter {label}: {kind} offsets are lengths: use _mm")
    meters = value / 1000.0
    if kind == "part":
        geoms = parts.part_geoms(model, name)
        frame = parts.find_frame(model, name)
        direction = _rotate(frame.quat, _axis(detail, "xyz"))
        if check_only:
            return
        for g in geoms:
            model.geom_pos[g] = nominal.geom_pos[g] + meters * direction
        for s in _part_sites(nominal, name, frame.body):
            model.site_pos[s] = nominal.site_pos[s] + meters * direction
        return
    if kind == "body":
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        if body <= 0:
            names = [
                mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i) or ""
                for i in range(1, model.nbody)
            ]
            raise UserError(
                f"parameter {label}: no body named {name!r}; close matches: {close_matches(name, names)}"
            )
        direction = _body_direction(model, body, detail)
        if not check_only:
            model.body_pos[body] = nominal.body_pos[body] + meters * direction
        return
    # joint
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if jid >= 0:
        body = int(model.jnt_bodyid[jid])
        direction = _body_direction(model, body, detail, joint=jid)
        if not check_only:
            model.body_pos[body] = nominal.body_pos[body] + meters * direction
        return
    loops = parts.loop_equalities(model, name)
    if not loops:
        candidates = parts.joint_names(model) + parts.loop_joint_names(model)
        raise UserError(
            f"parameter {label}: no joint named {name!r}; close matches: {close_matches(name, candidates)}"
        )
    if detail == "radial":
        raise UserError(
            f"parameter {label}: radial offsets need a tree joint; {name!r} closes a loop: use x, y or z of its base body"
        )
    direction = _axis(detail, "xyz")
    if check_only:
        return
    for eq in loops:  # connect: anchor on body2 (the base) is eq_data[3:6] in body2's frame
        model.eq_data[eq, 3:6] = nominal.eq_data[eq, 3:6] + meters * direction


def linear_coupling(model: mujoco.MjModel, name: str, where: str, why: str) -> int:
    """The equality of the joint coupling ``coupling:<name>``, which must be linear (``why`` says
    what a polynomial one would prevent)."""
    eq = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, f"coupling:{name}")
    if eq < 0 or model.eq_type[eq] != mujoco.mjtEq.mjEQ_JOINT:
        names = [
            n[len("coupling:") :]
            for n in (
                mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, i) or ""
                for i in range(model.neq)
            )
            if n.startswith("coupling:")
        ]
        raise UserError(
            f"{where}: no coupling named {name!r}; close matches: {close_matches(name, names)}"
        )
    if np.any(model.eq_data[eq, 2:5]):
        raise UserError(f"{where}: coupling {name!r} is not linear; {why}")
    return eq


def _body_direction(model, body: int, axis: str, joint: int | None = None) -> np.ndarray:
    """A unit vector in the parent frame of ``body``: an axis, or radially away from the
    parent's own hinge axis through the joint's anchor."""
    if axis != "radial":
        return _axis(axis, "xyz")
    parent = int(model.body_parentid[body])
    hinges = [
        j
        for j in range(model.njnt)
        if model.jnt_bodyid[j] == parent and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]
    if not hinges:
        raise UserError(
            f"radial offset: the parent of body {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)!r} does not rotate on a hinge"
        )
    axis_vec, origin = model.jnt_axis[hinges[0]], model.jnt_pos[hinges[0]]
    anchor = model.body_pos[body] + _rotate(
        model.body_quat[body], model.jnt_pos[joint] if joint is not None else np.zeros(3)
    )
    radial = anchor - origin
    radial -= np.dot(radial, axis_vec) * axis_vec
    length = np.linalg.norm(radial)
    if length < 1e-9:
        raise UserError("radial offset: the joint lies on its parent's rotation axis")
    return radial / length


def _part_sites(model, part: str, body: int) -> list[int]:
    """The part's own site and the user-named frames on it: sites of the same body that
    lie within the part's bounding box (in the body frame). Call with the nominal model so
    that membership does not depend on edits already made."""
    geoms = parts.part_geoms(model, part)
    own = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, part)
    boxes = [
        (model.geom_pos[g] - model.geom_rbound[g], model.geom_pos[g] + model.geom_rbound[g])
        for g in geoms
    ]
    found = [own] if own >= 0 else []
    for s in range(model.nsite):
        if s == own or model.site_bodyid[s] != body:
            continue
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or ""
        if name in parts.part_names(model) or name.startswith("probe:"):
            continue
        if any(
            np.all(model.site_pos[s] >= lo - 1e-6) and np.all(model.site_pos[s] <= hi + 1e-6)
            for lo, hi in boxes
        ):
            found.append(s)
    return found


# -- variants -------------------------------------------------------------------------------


@dataclass
class VariantSet:
    parameters: list[Parameter]
    names: list[str]
    values: np.ndarray  # (variants, parameters), offsets from nominal
    source: str = "<variants>"

    def __len__(self) -> int:
        return len(self.names)

    def check(self, model: mujoco.MjModel) -> None:
        for p in self.parameters:
            try:
                p.check(model)
            except UserError as exc:
                raise UserError(f"{self.source}: {exc}") from None


def read_variants(
    path: str | os.PathLike, presets: dict[str, str] | None = None, confirmed: bool = True
) -> VariantSet:
    """A variants file.

    JSON::

        {"format": "mechanism-variants/1",
         "parameters": {"timing": "coupling:hook_worm_gear:hook_deg", "crank_radius_mm": null},
         "sweep":    {"timing": [-10, 0, 10]},                      # full factorial grid, or
                     {"timing": {"start": -10, "stop": 10, "num": 5}},
         "samples":  {"count": 100, "seed": 1,                      # Monte Carlo tolerances,
                      "tolerances": {"crank_radius_mm": {"dist": "normal", "std": 0.02},
                                     "timing": {"dist": "uniform", "low": -1, "high": 1}}},
         "variants": [{"name": "late hook", "timing": 30}]}          # explicit variants

    ``parameters`` maps each name to its target (``null`` for a preset name); every value
    is an offset from nominal in the target's unit. Rows: the nominal design first, then
    the explicit variants, then every grid point combined with every Monte Carlo sample
    (grid only, samples only, or grid x samples). ``"method": "lhs"`` in ``samples`` draws a
    Latin hypercube instead of independent samples. A seed is required: a study must be
    repeatable. CSV: a header of parameter names (presets or targets) and one row per
    variant; an optional ``name`` column labels the rows. Without ``confirmed``, more than
    ``CONFIRM_VARIANTS`` variants are refused (the CLI's ``--yes``), before any is built.
    """
    path = Path(path)
    label = f"variants file {path}"
    from mechanism.files.limits import read_bounded

    data = read_bounded(path, "variants file", 64 * 2**20)  # by bytes read: a pipe claims size 0
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise UserError(f"{label}: not UTF-8 text") from None
    if path.suffix.lower() == ".json" or text.lstrip().startswith("{"):
        try:
            document = json.loads(text)
        except json.JSONDecodeError as exc:
            raise UserError(f"{label}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
        variants = _from_json(
            document, label, presets, MAX_VARIANTS if confirmed else CONFIRM_VARIANTS
        )
    else:
        variants = _from_csv(text, label, presets)
    variants.source = label
    _check_count(len(variants), label, MAX_VARIANTS if confirmed else CONFIRM_VARIANTS)
    return variants


def variants_from_document(
    document: dict,
    presets: dict[str, str] | None = None,
    confirmed: bool = True,
    label: str = "variants",
) -> VariantSet:
    """A variants document already in memory (the JSON form of :func:`read_variants`)."""
    variants = _from_json(document, label, presets, MAX_VARIANTS if confirmed else CONFIRM_VARIANTS)
    variants.source = label
    return variants


def _check_count(count: int, label: str, allowed: int) -> None:
    if count > MAX_VARIANTS:
        raise UserError(f"{label}: {count} variants requested, at most {MAX_VARIANTS} allowed")
    if count > allowed:
        raise UserError(
            f"{label}: {count} variants requested; more than {allowed} need --yes to confirm"
        )


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise UserError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _from_json(
    document, label: str, presets: dict[str, str] | None = None, allowed: int = MAX_VARIANTS
) -> VariantSet:
    if not isinstance(document, dict):
        raise UserError(f"{label}: expected a JSON object")
    if document.get("format", FORMAT) != FORMAT:
        raise UserError(f"{label}: format {document.get('format')!r} is not {FORMAT!r}")
    unknown = set(document) - {
        "format",
        "parameters",
        "sweep",
        "samples",
        "variants",
        "description",
    }
    if unknown:
        raise UserError(f"{label}: unknown key(s) {', '.join(sorted(unknown))}")
    declared = document.get("parameters") or {}
    if not isinstance(declared, dict):
        raise UserError(f"{label}: 'parameters' must map names to targets")
    params: dict[str, Parameter] = {}

    def param(name: str, where: str) -> Parameter:
        if name not in params:
            target = declared.get(name)
            if target is not None and not isinstance(target, str):
                raise UserError(f"{label}: {where}: target of {name!r} must be a string")
            try:
                params[name] = parameter(name, target, presets)
            except UserError as exc:
                raise UserError(f"{label}: {where}: {exc}") from None
        return params[name]

    for name in declared:
        param(name, "parameters")
    sweep = document.get("sweep") or {}
    if not isinstance(sweep, dict):
        raise UserError(f"{label}: 'sweep' must map parameter names to value lists")
    grid_axes = []
    for name, spec in sweep.items():
        param(name, "sweep")
        grid_axes.append((name, _sweep_values(spec, f"{label}: sweep {name}")))
    samples = document.get("samples")
    draws: list[dict[str, float]] = []
    if samples is not None:
        draws = _draw_samples(samples, f"{label}: samples", param)
    explicit = document.get("variants") or []
    if not isinstance(explicit, list):
        raise UserError(f"{label}: 'variants' must be a list of objects")
    rows: list[tuple[str, dict[str, float]]] = [("nominal", {})]
    for i, item in enumerate(explicit):
        where = f"{label}: variants[{i}]"
        if not isinstance(item, dict):
            raise UserError(f"{where}: expected an object")
        name = str(item.get("name", f"variant {i + 1}"))
        values = {}
        for key, value in item.items():
            if key != "name":
                param(key, where)
                values[key] = _number(value, f"{where}.{key}")
        rows.append((name, values))
    count = (
        len(rows) + math.prod(len(v) for _, v in grid_axes) * max(len(draws), 1)
        if grid_axes
        else len(rows) + len(draws)
    )
    _check_count(count, label, allowed)  # from the request, before the grid is built
    grid = (
        [
            dict(zip([n for n, _ in grid_axes], combo))
            for combo in itertools.product(*[v for _, v in grid_axes])
        ]
        if grid_axes
        else []
    )
    if grid and draws:
        combined = [
            ({**g, **{k: g.get(k, 0.0) + v for k, v in d.items()}}) for g in grid for d in draws
        ]
    else:
        combined = grid or draws
    for i, values in enumerate(combined):
        tag = "sample" if draws and not grid else "grid" if not draws else "grid+sample"
        rows.append((f"{tag} {i + 1}", values))
    names = list(params)
    if not names:
        raise UserError(f"{label}: no parameters")
    # an operating point left out of a row is the run's default (NaN), not an offset of 0
    missing = [math.nan if params[n].target in OPERATING_POINT else 0.0 for n in names]
    table = np.array(
        [[row.get(n, gap) for n, gap in zip(names, missing)] for _, row in rows], dtype=float
    )
    return VariantSet([params[n] for n in names], [r[0] for r in rows], table)


def _sweep_values(spec, where: str) -> list[float]:
    if isinstance(spec, list):
        if not spec:
            raise UserError(f"{where}: empty list")
        return [_number(v, where) for v in spec]
    if isinstance(spec, dict) and set(spec) == {"start", "stop", "num"}:
        num = spec["num"]
        if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= 100_000:
            raise UserError(f"{where}: num must be an integer between 1 and 100000")
        return list(np.linspace(_number(spec["start"], where), _number(spec["stop"], where), num))
    raise UserError(f"{where}: expected a list of values or {{start, stop, num}}")


def _draw_samples(samples, where: str, param) -> list[dict[str, float]]:
    if not isinstance(samples, dict) or set(samples) - {"count", "seed", "tolerances", "method"}:
        raise UserError(f"{where}: expected {{count, seed, tolerances, method}}")
    count = samples.get("count")
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_VARIANTS:
        raise UserError(f"{where}: count must be an integer between 1 and {MAX_VARIANTS}")
    method = samples.get("method", "random")
    if method not in ("random", "lhs"):
        raise UserError(
            f"{where}: method must be 'random' (independent draws) or 'lhs' (Latin hypercube)"
        )
    tolerances = samples.get("tolerances")
    if not isinstance(tolerances, dict) or not tolerances:
        raise UserError(f"{where}: 'tolerances' must map parameter names to distributions")
    laws = {}
    for name, dist in tolerances.items():
        param(name, where)
        laws[name] = _distribution(dist, f"{where}: {name}")
    seed = samples.get("seed")
    if seed is None:
        raise UserError(
            f'{where}: a seed is required ("seed": 1, say), so that the same file gives the same variants'
        )
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"{where}: seed must be a non-negative integer")
    rng = np.random.default_rng(seed)
    if method == "lhs":
        from scipy.stats import qmc

        uniform = qmc.LatinHypercube(d=len(laws), rng=rng).random(count)
    else:
        uniform = rng.random((count, len(laws)))
    columns = {name: law(uniform[:, i]) for i, (name, law) in enumerate(laws.items())}
    return [{name: float(values[i]) for name, values in columns.items()} for i in range(count)]


def _distribution(dist, at: str) -> Callable[[np.ndarray], np.ndarray]:
    """The inverse cumulative distribution of a tolerance: uniform [0, 1) draws -> values."""
    if not isinstance(dist, dict) or dist.get("dist") not in ("normal", "uniform"):
        raise UserError(
            f'{at}: expected {{"dist": "normal", "std": ...}} or {{"dist": "uniform", "low": ..., "high": ...}}'
        )
    if dist["dist"] == "normal":
        if set(dist) - {"dist", "mean", "std"} or "std" not in dist:
            raise UserError(f"{at}: a normal distribution takes mean (default 0) and std")
        mean, std = _number(dist.get("mean", 0.0), at), _number(dist["std"], at)
        if std < 0:
            raise UserError(f"{at}: std must be >= 0")
        from scipy.special import ndtri

        return lambda u: mean + std * ndtri(np.clip(u, 1e-12, 1 - 1e-12))
    if set(dist) != {"dist", "low", "high"}:
        raise UserError(f"{at}: a uniform distribution takes low and high")
    low, high = _number(dist["low"], at), _number(dist["high"], at)
    if high < low:
        raise UserError(f"{at}: high must be >= low")
    return lambda u: low + (high - low) * u


def _from_csv(text: str, label: str, presets: dict[str, str] | None = None) -> VariantSet:
    import csv
    import io

    from mechanism.files.tables import parse_table

    lines = [
        line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise UserError(f"{label}: empty (no header line)")
    header = [h.strip() for h in next(csv.reader(io.StringIO(lines[0])))]
    names = [h for h in header if h != "name"]
    if not names:
        raise UserError(f"{label}: the header names no parameters")
    params = []
    for name in names:
        try:
            params.append(parameter(name, presets=presets))
        except UserError as exc:
            raise UserError(f"{label}: column {name!r}: {exc}") from None
    table = parse_table(text, required=names, label=label)
    rows = len(table)
    labels = [f"row {i + 1}" for i in range(rows)]
    if "name" in header:
        column = header.index("name")
        body = [
            row
            for row in csv.reader(io.StringIO("\n".join(lines[1:])))
            if any(c.strip() for c in row)
        ]
        labels = [row[column].strip() or labels[i] for i, row in enumerate(body)]
    values = np.column_stack([table[n] for n in names])
    nominal = [math.nan if p.target in OPERATING_POINT else 0.0 for p in params]
    return VariantSet(params, ["nominal", *labels], np.vstack([nominal, values]))


# -- batch evaluation -----------------------------------------------------------------------


@dataclass
class BatchConfig:
    """Everything a worker needs to rebuild the check (picklable)."""

    model: mujoco.MjModel
    pairs: list[Pair]
    parameters: list[Parameter]
    driver: str | None = None
    revolutions: float = 1.0
    resolution_deg: float = 0.5
    required_mm: float = 0.0
    travel: Any = None  # mechanism.kinematics.travel.Travel of a driver that rocks
    frame: Any = None  # the described shaft's frame (angles reported as the shaft angle)


class VariantChecker:
    """Compiles nothing per variant: one model copy, one set of fcl BVHs, fields edited in place."""

    def __init__(self, config: BatchConfig):
        from mechanism.inspection.clearance import ClearanceSweep

        self.config = config
        self.nominal = config.model
        self.model = _copy_model(config.model)
        self.sweep = ClearanceSweep(
            self.model,
            config.pairs,
            config.driver,
            config.revolutions,
            config.resolution_deg,
            config.travel,
            config.frame,
        )

    def __call__(self, values: Sequence[float] | np.ndarray) -> dict:
        for name in EDITED_FIELDS:
            getattr(self.model, name)[:] = getattr(self.nominal, name)
        for param, value in zip(self.config.parameters, values):
            apply_parameter(self.model, self.nominal, param, float(value))
        row: dict = {}
        passed = True
        try:
            results = self.sweep.run()
        except UserError as exc:  # this variant cannot be assembled over the cycle
            for pair in self.config.pairs:
                row.update(
                    {
                        f"{pair.column}_min_mm": float("nan"),
                        f"{pair.column}_angle_deg": float("nan"),
                        f"{pair.column}_pass": 0,
                    }
                )
            row["pass"] = 0
            row["note"] = str(exc)
            return row
        for result in results:
            ok = result.passes(self.config.required_mm)
            passed &= ok
            row[f"{result.pair.column}_min_mm"] = result.min_distance_mm
            row[f"{result.pair.column}_angle_deg"] = result.angle_deg
            row[f"{result.pair.column}_pass"] = int(ok)
        row["pass"] = int(passed)
        row["note"] = ""
        return row


def _copy_model(model: mujoco.MjModel) -> mujoco.MjModel:
    import copy

    return copy.deepcopy(model)


def _check(checker: VariantChecker, values: np.ndarray) -> dict:
    return checker(values)


@dataclass
class BatchResult:
    variants: VariantSet
    rows: list[dict]
    pairs: list[Pair]
    required_mm: float
    workers: int
    backend: Backend
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)

    def table(self) -> list[dict]:
        out = []
        for name, values, row in zip(self.variants.names, self.variants.values, self.rows):
            entry: dict = {"variant": name}
            entry.update({p.name: float(v) for p, v in zip(self.variants.parameters, values)})
            entry.update(row)
            out.append(entry)
        return out

    @property
    def failed(self) -> int:
        return sum(1 for row in self.rows if not row["pass"])


def run_variants(
    model: mujoco.MjModel,
    variants: VariantSet,
    pairs: Sequence[Pair],
    required_mm: float = 0.0,
    driver: str | None = None,
    revolutions: float = 1.0,
    resolution_deg: float = 0.5,
    workers: int = 1,
    backend: Backend = "local",
    progress: bool = True,
    ray_address: str | None = None,
    on_row: Callable[[int, dict], None] | None = None,
    description=None,
) -> BatchResult:
    """Check every variant's clearances; one result row per variant, in file order. Each
    worker builds one :class:`VariantChecker` (model copy, fcl BVHs) from the config it
    receives once (``mechanism.batch``); ``on_row(index, row)`` sees rows as they complete."""
    import time

    from mechanism.batch import check_options, run_batch

    check_options(backend, workers)
    variants.check(model)
    from mechanism.machine.machine import inspection_frame, inspection_travel

    if driver is None:
        raise UserError("clearance variants need the joint that drives the cycle (driver)")
    travel = inspection_travel(model, driver, description)
    config = BatchConfig(
        model,
        list(pairs),
        variants.parameters,
        driver,
        revolutions,
        resolution_deg,
        required_mm,
        None if travel.rotates else travel,
        inspection_frame(model, driver, description, travel),
    )
    start = time.perf_counter()
    rows = run_batch(
        _check,
        list(variants.values),
        shared=config,
        setup=VariantChecker,
        workers=workers,
        backend=backend,
        ray_address=ray_address,
        on_result=on_row,
        progress=progress,
        desc="variants",
        unit="variant",
    )
    return BatchResult(
        variants, rows, list(pairs), required_mm, workers, backend, time.perf_counter() - start
    )
