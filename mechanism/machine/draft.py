"""A first machine description drafted from a model: what ``mechanism init`` writes.

The roles are guessed (:mod:`mechanism.machine.roles`) and marked ``GUESS``; what a model
cannot say (the motor's datasheet, the friction) gets placeholders marked ``TODO``. The
draft is valid: every verb runs on it at once, and gets better as the TODOs are filled in.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from mechanism.kinematics.linkage import compute_tables
from mechanism.machine import parts
from mechanism.machine.roles import guess_roles

# A small permanent-magnet DC motor, so that a draft simulates before its datasheet is in.
PLACEHOLDER_MOTOR = {"resistance_ohm": 2.0, "torque_constant_Nm_per_A": 0.03, "back_emf_V_s_per_rad": 0.03}


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _plate_guess(model: mujoco.MjModel, tool_site: str | None) -> str | None:
    """The fixed part right under the tool (its top nearest below the tool's lowest point)."""
    if tool_site is None:
        return None
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    site = model.site(tool_site)
    tool_body = int(model.site_bodyid[site.id])
    best, best_gap = None, np.inf
    for part in parts.part_names(model):
        geoms = parts.part_geoms(model, part)
        body = int(model.geom_bodyid[geoms[0]])
        if model.body_weldid[body] != 0 or body == tool_body:
            continue
        centre = data.geom_xpos[geoms[0]]
        gap = float(np.linalg.norm(centre[:2] - data.site_xpos[site.id][:2]))
        if gap < best_gap:
            best, best_gap = part, gap
    return best


def draft_description(model_path: str | os.PathLike, model_reference: str, name: str) -> tuple[str, list[str]]:
    """(TOML text, summary lines) of a draft description of the model at ``model_path``;
    ``model_reference`` is what the draft's ``model`` key says (a path relative to it)."""
    from mechanism.machine.models import load_model

    model = load_model(model_path)
    guess = guess_roles(model)
    joints = parts.joint_names(model)
    shaft, motor, zero = guess.shaft_joint, guess.motor_joint, guess.zero_site
    travel = None
    if zero:
        tables = compute_tables(model, shaft, zero, n=72)
        assert tables.tool_z_m is not None
        travel = float(np.ptp(tables.tool_z_m)) * 1e3
    plate = _plate_guess(model, zero)
    ratio = guess.ratios.get(motor, 1.0)
    summary = [
        f"model: {model.nbody - 1} bodies, {len(joints)} joints, {model.neq} equality constraints (loops, couplings)",
        "joints turning whole revolutions, turns per shaft turn: "
        + ", ".join(f"{j} {guess.ratios[j]:+.4g}" for j in guess.revolving),
        f"shaft (GUESS): {shaft}",
        f"motor (GUESS): {motor} ({abs(ratio):.4g}:1 to the shaft)",
        f"zero site (GUESS): {zero or 'none found'}" + (f" (rises and falls {travel:.3f} mm)" if travel else ""),
        f"plate (GUESS): {plate or 'none found'}",
        *guess.notes,
    ]
    lines = [
        f"# Draft machine description written by `mechanism init` from {Path(model_path).name}.",
        "# Values marked GUESS were guessed from the model: check them. Values marked TODO are",
        "# placeholders: the model cannot know them (motor datasheet, friction).",
        *[f"# {line}" for line in summary],
        "",
        "[machine]",
        f"name = {_toml_string(name)}",
        f"model = {_toml_string(model_reference)}",
        "",
        "[drive]",
        f"motor_joint = {_toml_string(motor)}   # GUESS: the joint turning fastest ({abs(ratio):.4g} turns per shaft turn)",
        f"shaft_joint = {_toml_string(shaft)}   # GUESS: the slowest shaft turning whole revolutions on the frame",
    ]
    if zero:
        lines.append(f"zero_site = {_toml_string(zero)}   # GUESS: the site that rises and falls most; shaft angle 0 where it is highest")
    else:
        lines.append(f"zero_site = {_toml_string('TODO')}   # TODO: no site rises and falls with the shaft; name one")
    lines += [
        "",
        "[motor]   # TODO: the motor's datasheet (placeholders of a small DC motor)",
        'type = "dc"',
        *[f"{key} = {value}   # TODO" for key, value in PLACEHOLDER_MOTOR.items()],
        "",
        f"[friction.{_toml_string(shaft)}]   # TODO: measure (break-away torque, a speed-voltage curve)",
        "coulomb_Nm = 0.0",
        "viscous_Nm_s_per_rad = 0.0",
    ]
    if zero:
        lines += ["", "[tool]", f"site = {_toml_string(zero)}   # GUESS"]
        if plate:
            lines.append(f"plate = {_toml_string(plate)}   # GUESS: the fixed part nearest under the tool")
        else:
            lines.append("# plate = \"PART\"   # could not guess the part the tool works against")
    return "\n".join(lines) + "\n", summary
