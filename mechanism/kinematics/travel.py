"""A driven joint's travel: whole revolutions, or a range between two hard stops.

A crank turns whole revolutions; a rocker, a servo arm or a slide moves between two limits.
Inspection's cycle is one revolution for the first and the travel between the limits for the
second. :class:`Travel` holds the travel in the joint's own coordinate (0 at the pose the export
was assembled in, as MuJoCo's ``qpos``: radians for a hinge, metres for a slide).
:func:`find_travel` finds, for a joint with no described limits, whether the mechanism
assembles over a whole revolution of it, and else the range it assembles in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from mechanism.errors import UserError
from mechanism.kinematics.pose import PoseError, is_slide, joint_dof, joint_value_text, solve_pose

TWO_PI = 2 * math.pi
SCAN_STEP_DEG = 5.0  # the whole-revolution check: a pose every 5 deg, warm-started (a branch change shows as a failure)
SCAN_STEP_M = 1e-3  # a slide's search for its travel: 1 mm steps, then bisection
BISECT_STEPS = 24  # the end of a travel to 2^-24 of a step
END_MARGIN = 0.01  # a travel found by search stops 1 % of its length short of the dead points (singular there)
SLIDE_SEARCH_M = 10.0  # a slide is searched at most 10 m each way


@dataclass(frozen=True)
class Travel:
    """Where a joint moves: ``rotates`` (whole revolutions) or between ``lower`` and ``upper``
    (joint coordinate, rad or m). ``source`` says where the range came from (for messages)."""

    joint: str
    lower: float
    upper: float
    rotates: bool
    slide: bool = False
    source: str = ""

    @property
    def span(self) -> float:
        return TWO_PI if self.rotates else self.upper - self.lower

    def samples(self, resolution: float, cycles: float = 1.0) -> np.ndarray:
        """Joint coordinates of an inspection cycle: ``cycles`` revolutions from 0 every
        ``resolution`` rad (end excluded) for a rotating joint; the travel from its lower to its
        upper end at about ``resolution`` (both ends included) for one that rocks or slides."""
        if self.rotates:
            count = max(1, int(round(TWO_PI * cycles / resolution)))
            return resolution * np.arange(count)
        count = max(2, int(math.ceil(self.span / resolution)) + 1)
        return np.linspace(self.lower, self.upper, count)

    def text(self, model: mujoco.MjModel | None = None) -> str:
        if self.rotates:
            return f"{self.joint} turning whole revolutions"
        unit = (
            (lambda v: f"{v * 1e3:.4g} mm")
            if self.slide
            else (lambda v: f"{math.degrees(v):.4g} deg")
        )
        return f"{self.joint} between {unit(self.lower)} and {unit(self.upper)}"


def model_limits(model: mujoco.MjModel, joint: str) -> tuple[float, float] | None:
    """The joint's range when the model limits it."""
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    if jid < 0 or not model.jnt_limited[jid]:
        return None
    low, high = (float(v) for v in model.jnt_range[jid])
    return (low, high) if high > low else None


def _assembles(model: mujoco.MjModel, data: mujoco.MjData, joint: str, value: float) -> bool:
    try:
        solve_pose(model, data, {joint: float(value)})
        return True
    except PoseError:
        return False


def _reach(model: mujoco.MjModel, joint: str, sign: float, step: float, limit: float) -> float:
    """How far the mechanism assembles from 0 in direction ``sign`` (up to ``limit``), walking in
    steps and bisecting the last one."""
    data = mujoco.MjData(model)
    qadr, _ = joint_dof(model, joint)
    if not _assembles(model, data, joint, 0.0):
        raise UserError(f"the mechanism does not assemble at the export's own pose ({joint} at 0)")
    reached = 0.0
    while reached < limit:
        good = data.qpos.copy()
        if _assembles(model, data, joint, sign * min(reached + step, limit)):
            reached = min(reached + step, limit)
            continue
        low, high = reached, reached + step
        for _ in range(BISECT_STEPS):
            data.qpos[:] = good
            middle = 0.5 * (low + high)
            if _assembles(model, data, joint, sign * middle):
                low, good = middle, data.qpos.copy()
            else:
                high = middle
        return low
    return limit


def turns_whole_revolutions(model: mujoco.MjModel, joint: str) -> bool:
    """Does the mechanism assemble over a whole revolution of ``joint`` (a hinge), both ways?"""
    if is_slide(model, joint):
        return False
    return _reach(model, joint, 1.0, math.radians(SCAN_STEP_DEG), TWO_PI) >= TWO_PI


def assembling_range(model: mujoco.MjModel, joint: str) -> tuple[float, float]:
    """The range of ``joint`` (rad or m) about the export's pose in which the mechanism assembles,
    a margin short of its dead points."""
    slide = is_slide(model, joint)
    step, limit = (SCAN_STEP_M, SLIDE_SEARCH_M) if slide else (math.radians(SCAN_STEP_DEG), TWO_PI)
    low, high = -_reach(model, joint, -1.0, step, limit), _reach(model, joint, 1.0, step, limit)
    margin = END_MARGIN * (high - low)
    return low + (margin if low > -limit else 0.0), high - (margin if high < limit else 0.0)


def find_travel(
    model: mujoco.MjModel, joint: str, limits: tuple[float, float] | None = None, source: str = ""
) -> Travel:
    """The travel of ``joint``: ``limits`` when given (a description's), else the model's joint
    range, else whole revolutions where the mechanism assembles over one, else the range it
    assembles in (found by search)."""
    joint_dof(model, joint)  # a hinge or slide of the model
    slide = is_slide(model, joint)
    if limits is not None:
        return Travel(
            joint,
            float(limits[0]),
            float(limits[1]),
            False,
            slide,
            source or "the description's limits",
        )
    ranged = model_limits(model, joint)
    if ranged is not None:
        return Travel(joint, *ranged, rotates=False, slide=slide, source="the model's joint range")
    if not slide and turns_whole_revolutions(model, joint):
        return Travel(joint, 0.0, TWO_PI, True, False, "whole revolutions")
    low, high = assembling_range(model, joint)
    if not high > low:
        raise UserError(
            f"the mechanism does not move when {joint} moves: it assembles only at "
            f"{joint_value_text(model, joint, 0.0)}"
        )
    return Travel(joint, low, high, False, slide, "the range the mechanism assembles in")
