"""A first machine description drafted from a model: what ``mechanism init`` writes.

The roles are guessed (:mod:`mechanism.machine.roles`) and marked ``GUESS``; what a model
cannot say (the motor's datasheet, the friction) gets placeholders marked ``TODO``. The
draft is valid: every verb runs on it at once, and gets better as the TODOs are filled in.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import mujoco
import numpy as np

from mechanism.kinematics.linkage import compute_tables
from mechanism.kinematics.pose import is_slide
from mechanism.machine import parts
from mechanism.machine.roles import guess_roles

# A small permanent-magnet DC motor, so that a draft simulates before its datasheet is in.
PLACEHOLDER_MOTOR = {
    "resistance_ohm": 2.0,
    "torque_constant_Nm_per_A": 0.03,
    "back_emf_V_s_per_rad": 0.03,
}


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


def _ground_guess(model: mujoco.MjModel) -> str | None:
    """The heaviest part fixed to the world (the export's ground, else the part the converter fixed)."""
    best, mass = None, -1.0
    for part in parts.part_names(model):
        geoms = parts.part_geoms(model, part)
        body = int(model.geom_bodyid[geoms[0]])
        if model.body_weldid[body] != 0:
            continue
        weight = float(model.body_mass[body])
        if weight > mass:
            best, mass = part, weight
    return best


def draft_description(
    model_path: str | os.PathLike,
    model_reference: str,
    name: str,
    up: str | None = None,
    up_reason: str = "",
) -> tuple[str, list[str]]:
    """(TOML text, summary lines) of a draft description of the model at ``model_path``;
    ``model_reference`` is what the draft's ``model`` key says (a path relative to it); ``up``, the
    export's up axis the model was converted with (None: an MJCF's own gravity), and why."""
    from mechanism.machine.models import load_model

    model = load_model(model_path)
    guess = guess_roles(model)
    joints = parts.joint_names(model)
    shaft, motor, zero = guess.shaft_joint, guess.motor_joint, guess.zero_site
    unknown = list(guess.unknown)
    travel = None
    if zero and shaft:
        tables = compute_tables(model, shaft, zero, n=72, span=guess.travel)
        assert tables.tool_z_m is not None
        travel = float(np.ptp(tables.tool_z_m)) * 1e3
    elif shaft:
        unknown.append(
            "the zero site: no site rises and falls with the shaft (zero_angle_deg = 0 written: the export's pose)"
        )
    slide = shaft is not None and is_slide(model, shaft)
    plate = _plate_guess(model, zero)
    if zero and not plate:
        unknown.append("the plate: no fixed part under the tool")
    ground = _ground_guess(model)
    if ground is None:
        unknown.append("the ground: no part is fixed to the world")
    ratio = guess.ratios.get(motor or "", 1.0)
    if guess.travel is not None and shaft:
        low, high = guess.travel
        travel_text = (
            f"{low * 1e3:.4g} to {high * 1e3:.4g} mm"
            if slide
            else f"{math.degrees(low):.4g} to {math.degrees(high):.4g} deg"
        )
        motion = f"travel of the shaft (GUESS): {travel_text} (where the mechanism assembles, 1 % short of its dead points)"
    else:
        motion = "joints turning whole revolutions, turns per shaft turn: " + ", ".join(
            f"{j} {guess.ratios[j]:+.4g}" for j in guess.revolving
        )
    summary = [
        f"model: {model.nbody - 1} bodies, {len(joints)} joints, {model.neq} equality constraints (loops, couplings)",
        f"up axis: {up or 'as the model says'}; {up_reason or 'the MJCF gravity'}",
        f"ground (GUESS): {ground or 'none found'}",
        motion,
        f"shaft (GUESS): {shaft or 'none found'}",
        f"motor (GUESS): {motor or 'none found'}"
        + (f" ({abs(ratio):.4g}:1 to the shaft)" if motor else ""),
        f"zero site (GUESS): {zero or 'none found'}"
        + (f" (rises and falls {travel:.3f} mm)" if travel else ""),
        f"plate (GUESS): {plate or 'none found'}",
        *guess.notes,
        *[f"could not guess {item}" for item in unknown],
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
        *(
            [f"up = {_toml_string(up)}   # {up_reason}"]
            if up and up_reason.startswith("given")
            else [f"# up = {_toml_string(up)}   # {up_reason}"]
            if up
            else []
        ),
        *(
            [
                f"# ground = {_toml_string(ground)}   # GUESS: the part fixed to the world (the export's ground, else its "
                "heaviest part); set ground to fix another"
            ]
            if ground
            else []
        ),
        "",
        "[drive]",
    ]
    if guess.travel is None and shaft:
        lines += [
            f"motor_joint = {_toml_string(motor or shaft)}   # GUESS: the joint turning fastest ({abs(ratio):.4g} turns per shaft turn)",
            f"shaft_joint = {_toml_string(shaft)}   # GUESS: the slowest shaft turning whole revolutions on the frame",
        ]
    elif shaft:
        lines += [
            f"motor_joint = {_toml_string(motor or shaft)}   # GUESS: no joint turns whole revolutions; the motor on the shaft",
            f"shaft_joint = {_toml_string(shaft)}   # GUESS: the joint on the frame with the widest travel (it rocks)",
        ]
    else:
        lines += [
            f"motor_joint = {_toml_string('TODO')}   # TODO: could not guess: {unknown[0]}",
            f"shaft_joint = {_toml_string('TODO')}   # TODO",
        ]
    if zero:
        lines.append(
            f"zero_site = {_toml_string(zero)}   # GUESS: the site that rises and falls most; shaft angle 0 where it is highest"
        )
    else:
        lines.append(
            "zero_angle_deg = 0.0   # GUESS: no site rises and falls with the shaft; 0 at the export's pose"
        )
    lines += [
        "",
        "[motor]   # TODO: the motor's datasheet (placeholders of a small DC motor)",
        'type = "dc"',
        *[f"{key} = {value}   # TODO" for key, value in PLACEHOLDER_MOTOR.items()],
    ]
    if shaft:
        lines += [
            "",
            f"[friction.{_toml_string(shaft)}]   # TODO: measure (break-away torque, a speed-voltage curve)",
            "coulomb_Nm = 0.0",
            "viscous_Nm_s_per_rad = 0.0",
        ]
    if guess.travel is not None and shaft:
        low, high = guess.travel
        unit, scale = ("mm", 1e3) if slide else ("deg", 180.0 / math.pi)
        lines += [
            "",
            f"[limits.{_toml_string(shaft)}]   # GUESS: where the mechanism assembles; set the real hard stops",
            f"lower_{unit} = {low * scale:.6g}",
            f"upper_{unit} = {high * scale:.6g}",
        ]
    if zero:
        lines += ["", "[tool]", f"site = {_toml_string(zero)}   # GUESS"]
        if plate:
            lines.append(
                f"plate = {_toml_string(plate)}   # GUESS: the fixed part nearest under the tool"
            )
        else:
            lines.append('# plate = "PART"   # could not guess the part the tool works against')
    return "\n".join(lines) + "\n", summary
