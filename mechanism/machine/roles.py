"""Guesses of a machine's roles from its model alone, for a first description.

A converted model knows its joints and couplings but not which joint the motor turns or
which shaft the cycle refers to. For a one-degree-of-freedom mechanism these are guessed:

- the shaft: among the joints that turn through whole revolutions in a bearing on the
  frame (shafts; geared ones first), the one with the smallest speed: every other joint's
  motion repeats once per its turn, as a tool's does;
- the motor: the joint with the largest speed ratio to the shaft;
- the zero site: a site on the tool, the user-named site that rises and falls most.

Every guess is a guess: ``mechanism init`` marks them in the draft it writes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from mechanism.errors import UserError
from mechanism.kinematics.linkage import compute_tables, up_axis
from mechanism.kinematics.pose import PoseError
from mechanism.tolerances import REVOLVING_RATIO_TOLERANCE

RATIO_SAMPLES = 72


def _hinges(model: mujoco.MjModel) -> list[str]:
    return [
        model.joint(j).name
        for j in range(model.njnt)
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and model.joint(j).name
    ]


def _tables_from(model: mujoco.MjModel, driver: str, site: str | None = None):
    try:
        return compute_tables(model, driver, site, n=RATIO_SAMPLES)
    except PoseError:
        return None  # this joint cannot turn a whole revolution (a rocker)


@dataclass
class RoleGuess:
    shaft_joint: str | None
    motor_joint: str | None
    zero_site: str | None
    ratios: dict[str, float] = field(default_factory=dict)  # mean turns per shaft turn
    revolving: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    # a shaft that rocks: the range it assembles in (joint coordinate)
    travel: tuple[float, float] | None = None
    unknown: list[str] = field(default_factory=list)  # what could not be guessed


def _on_frame(model: mujoco.MjModel, joint: str) -> bool:
    """Does the joint turn its body in a bearing fixed to the frame (the world)?"""
    body = model.jnt_bodyid[model.joint(joint).id]
    return int(model.body_weldid[model.body_parentid[body]]) == 0


def guess_driver(model: mujoco.MjModel) -> str:
    """The joint to turn through a cycle when nobody said: the guessed shaft."""
    guess = guess_roles(model)
    if guess.shaft_joint is None:
        raise UserError(f"no joint to drive: {guess.unknown[0]}")
    return guess.shaft_joint


def _one_dof_joints(model: mujoco.MjModel) -> list[str]:
    kinds = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    return [
        model.joint(j).name
        for j in range(model.njnt)
        if int(model.jnt_type[j]) in kinds and model.joint(j).name
    ]


def _rocking_guess(model: mujoco.MjModel) -> RoleGuess:
    """No joint turns whole revolutions: the shaft is the joint on the frame with the widest
    travel (a hinge before a slide), driven by the motor directly; its travel is where the
    mechanism assembles."""
    from mechanism.kinematics.travel import assembling_range, model_limits

    joints = _one_dof_joints(model)
    if not joints:
        return RoleGuess(
            None,
            None,
            None,
            notes=["the model has no hinge or slide joint: nothing moves"],
            unknown=["the shaft and the motor: the model has no hinge or slide joint"],
        )
    ranges = {}
    for name in joints:
        try:
            ranges[name] = model_limits(model, name) or assembling_range(model, name)
        except UserError:
            continue
    if not ranges:
        return RoleGuess(
            None,
            None,
            None,
            notes=["the mechanism does not move at the export's pose"],
            unknown=[
                "the shaft and the motor: no joint moves the mechanism from the export's pose"
            ],
        )
    hinges = set(_hinges(model))

    def preference(name: str):
        low, high = ranges[name]
        return (
            not _on_frame(model, name),
            name not in hinges,
            -round(high - low, 9),
            joints.index(name),
        )

    shaft = min(ranges, key=preference)
    guess = RoleGuess(shaft, shaft, None, {shaft: 1.0}, [], travel=ranges[shaft])
    guess.notes.append(
        f"no joint turns whole revolutions: the shaft {shaft} rocks (GUESS), the motor is guessed on it"
    )
    guess.zero_site = _moving_site(model, shaft, ranges[shaft])
    return guess


def guess_roles(model: mujoco.MjModel) -> RoleGuess:
    hinges = _hinges(model)
    for start in hinges:
        tables = _tables_from(model, start)
        if tables is not None:
            break
    else:
        return _rocking_guess(model)
    revolving = [
        name
        for name in hinges
        if name in tables.ratios
        and (
            np.all(tables.ratios[name] > REVOLVING_RATIO_TOLERANCE)
            or np.all(tables.ratios[name] < -REVOLVING_RATIO_TOLERANCE)
        )
    ]
    speeds = {name: float(np.mean(np.abs(tables.ratios[name]))) for name in revolving}

    def preference(name: str):
        ratio = tables.ratios[name]
        geared = np.ptp(ratio) <= 1e-6 * abs(float(np.mean(ratio)))
        return (not _on_frame(model, name), not geared, round(speeds[name], 6), hinges.index(name))

    shaft = min(revolving, key=preference)
    scale = speeds[shaft]
    ratios = {
        name: float(np.mean(tables.ratios[name])) / float(np.mean(tables.ratios[shaft]))
        for name in revolving
    }
    motor = max(revolving, key=lambda name: (round(abs(ratios[name]), 9), -hinges.index(name)))
    guess = RoleGuess(shaft, motor, None, ratios, revolving)
    if motor == shaft:
        guess.notes.append(
            "no joint turns faster than the shaft: the motor is guessed on the shaft itself"
        )
    guess.zero_site = _moving_site(model, shaft)
    if scale == 0:
        guess.notes.append("the shaft does not move")
    return guess


def _moving_site(
    model: mujoco.MjModel, shaft: str, travel: tuple[float, float] | None = None
) -> str | None:
    """A tool point: a site that rises and falls once per shaft turn (or moves up and down over
    the ``travel`` of a shaft that rocks), preferring a body that translates without turning (a
    needle bar, a ram), a user-named frame over a part's own site, a larger travel and, among
    equals, the lowest point (a tool's working end)."""
    from mechanism.kinematics.pose import approach, solve_pose

    up = up_axis(model)
    data = mujoco.MjData(model)
    geoms = {model.geom(i).name for i in range(model.ngeom)}
    # a first-generation subsystem's massless RootPart frame is an exporter artefact, not a point of the tool
    sites = [
        model.site(i).name
        for i in range(model.nsite)
        if model.site(i).name and not model.site(i).name.endswith("RootPart")
    ]
    if not sites:
        return None
    heights = np.zeros((RATIO_SAMPLES, len(sites)))
    turn = np.zeros(len(sites))
    first = None
    angles = (
        np.arange(RATIO_SAMPLES) * 2 * np.pi / RATIO_SAMPLES
        if travel is None
        else np.linspace(*travel, RATIO_SAMPLES)
    )
    if travel is not None:
        approach(model, data, shaft, float(angles[0]))
    for i, angle in enumerate(angles):
        solve_pose(model, data, {shaft: angle})
        heights[i] = [up @ data.site(name).xpos for name in sites]
        frames = np.array([data.site(name).xmat.reshape(3, 3) for name in sites])
        first = frames if first is None else first
        cosine = (np.einsum("kij,kij->k", frames, first) - 1.0) / 2.0
        turn = np.maximum(turn, np.arccos(np.clip(cosine, -1.0, 1.0)))
    periodic = travel is None
    travel = np.ptp(heights, axis=0)
    rising = np.diff(np.vstack([heights, heights[:1]]), axis=0) > 0
    # rising then not: one maximum each
    peaks = np.sum(rising & ~np.roll(rising, -1, axis=0), axis=0)
    floor = 1e-6 * max(float(model.stat.extent), 1e-3)
    candidates = [
        k for k in range(len(sites)) if travel[k] > floor and (peaks[k] == 1 or not periodic)
    ]
    if not candidates:
        return None

    def preference(k: int):
        translating = turn[k] < np.radians(1.0)
        user_named = sites[k] not in geoms and f"{sites[k]}_visual" not in geoms
        return (
            not translating,
            not user_named,
            -round(float(travel[k]) * 1e6),
            float(heights[:, k].min()),
        )

    return sites[min(candidates, key=preference)]


def drive_lines(model_path, degrees_of_freedom: int | None) -> list[str]:
    """Moving mass and, for a one-degree-of-freedom machine, the inertia reflected to its
    guessed shaft over one revolution and to its fastest joint (the motor behind its belt)."""
    from mechanism.machine.models import load_model

    try:
        model = load_model(model_path)
    except Exception as exc:  # noqa: BLE001 - the model is written; a summary extra must not end the command
        return [f"moving mass: not computed ({' '.join(str(exc).split())[:120]})"]
    moving = float(
        sum(model.body_mass[b] for b in range(1, model.nbody) if model.body_weldid[b] != 0)
    )
    lines = [f"moving mass: {moving:.6g} kg"]
    if degrees_of_freedom != 1:
        return lines
    try:
        guess = guess_roles(model)
        if guess.shaft_joint is None:
            return lines
        tables = compute_tables(model, guess.shaft_joint, n=180, span=guess.travel)
    except Exception as exc:  # noqa: BLE001 - numerical trouble in an odd export only loses this line
        return lines + [f"reflected inertia: not computed ({' '.join(str(exc).split())[:120]})"]
    inertia = tables.inertia_kgm2
    over = "a revolution" if guess.travel is None else "its travel"
    lines.append(
        f"reflected inertia at {guess.shaft_joint}: {inertia.mean():.4g} kg*m^2 mean over {over} "
        f"({inertia.min():.4g} to {inertia.max():.4g})"
    )
    ratio = abs(guess.ratios.get(guess.motor_joint or "", 1.0))
    if guess.motor_joint != guess.shaft_joint and ratio > 1:
        lines.append(
            f"  = {inertia.mean() / ratio**2:.4g} kg*m^2 referred to {guess.motor_joint} (ratio {ratio:g}:1)"
        )
    return lines
