"""Position kinematics of closed-chain mechanisms in MuJoCo models.

MuJoCo integrates dynamics; it has no position solver for a mechanism whose loops are
closed by equality constraints (``loop:*`` connects/welds, ``coupling:*`` joint
couplings). :func:`solve_pose` is that solver: with some joints held at given values it
moves every other degree of freedom until all active equality constraints hold, by
Gauss-Newton on MuJoCo's own constraint residuals and Jacobians (``efc_pos``,
``efc_J``), so it stays exact for whatever constraints the converter wrote.

For a one-degree-of-freedom machine driven by one joint (the sewing machine's
``arm_shaft``), :func:`sweep` gives the poses over a revolution and :func:`velocity_ratios`
the first-order kinematic coefficients dq/dθ at a pose (what every velocity, inertia and
reaction computation needs).
"""

from __future__ import annotations

import contextlib
from typing import Iterable, Mapping

import mujoco
import numpy as np

from mechanism.errors import UserError, close_matches
from mechanism.tolerances import (
    JOINT_RANK_TOLERANCE,
    POSITION_TOLERANCE,
    RELATIVE_POSITION_TOLERANCE,
)


def position_tolerance(model: mujoco.MjModel) -> float:
    """The residual a pose is accepted at when Newton's method stalls above POSITION_TOLERANCE:
    scaled to the model (a 1 m machine's loops close to 10 nm), since a CAD export's rounding
    can leave its loops a little open everywhere."""
    return max(POSITION_TOLERANCE, RELATIVE_POSITION_TOLERANCE * float(model.stat.extent))


class PoseError(UserError):
    """The constraints cannot be satisfied with the given joints fixed."""


def named_joint(joint: str | None) -> str:
    """``joint``, where one is named: the driver a caller may leave out (None) until it is needed."""
    if not joint:
        raise UserError(
            "no joint given: name the joint that drives the mechanism (a machine description's "
            "shaft_joint, or --driver)"
        )
    return joint


def joint_dof(model: mujoco.MjModel, joint: str) -> tuple[int, int]:
    """(qpos address, dof address) of a one-degree-of-freedom joint, by name."""
    joint = named_joint(joint)
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    if jid < 0:
        names = [model.joint(i).name for i in range(model.njnt)]
        raise UserError(
            f"no joint named {joint!r} in the model; close matches: {close_matches(joint, names)}"
        )
    if int(model.jnt_type[jid]) not in (
        int(mujoco.mjtJoint.mjJNT_HINGE),
        int(mujoco.mjtJoint.mjJNT_SLIDE),
    ):
        raise UserError(f"joint {joint!r} is not a hinge or slide joint")
    return int(model.jnt_qposadr[jid]), int(model.jnt_dofadr[jid])


def is_slide(model: mujoco.MjModel, joint: str) -> bool:
    jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    return jid >= 0 and int(model.jnt_type[jid]) == int(mujoco.mjtJoint.mjJNT_SLIDE)


def joint_value_text(model: mujoco.MjModel, joint: str, value: float) -> str:
    """A joint coordinate in the user's units: degrees for a hinge, mm for a slide."""
    return (
        f"{float(value) * 1e3:.4g} mm"
        if is_slide(model, joint)
        else f"{np.degrees(float(value)):.4g} deg"
    )


def describe_positions(model: mujoco.MjModel, fixed: Mapping[str, float]) -> str:
    """'JOINT at 80 deg, SLIDE at 3 mm' (joint coordinates: 0 at the export's assembly pose)."""
    return ", ".join(
        f"{name} at {joint_value_text(model, name, value)}" for name, value in fixed.items()
    )


@contextlib.contextmanager
def position_only(model: mujoco.MjModel):
    """Dense constraint Jacobians, and no contacts: only equality constraints matter here."""
    saved = (model.opt.jacobian, model.opt.disableflags)
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    try:
        yield
    finally:
        model.opt.jacobian, model.opt.disableflags = saved


def equality_residual(model, data) -> tuple[np.ndarray, np.ndarray]:
    mujoco.mj_fwdPosition(model, data)
    rows = data.efc_type[: data.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    jac = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)[rows]
    return data.efc_pos[: data.nefc][rows].copy(), jac.copy()


def solve_pose(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    fixed: Mapping[str, float],
    tolerance: float | None = None,
    max_iterations: int = 60,
) -> float:
    """Set ``data.qpos`` so that every active equality constraint holds, with the joints in
    ``fixed`` (name -> position in rad or m) held at their values. The current ``data.qpos``
    is the starting guess (warm-start from a nearby pose for speed and branch continuity).

    Returns the final residual norm; raises :class:`PoseError` if it does not converge.
    Velocities are left untouched; derived quantities (xpos, site_xpos, ...) are up to date.
    """
    accept = max(position_tolerance(model), tolerance or 0.0)
    tolerance = POSITION_TOLERANCE if tolerance is None else tolerance
    addresses = {name: joint_dof(model, name) for name in fixed}
    free = np.ones(model.nv, dtype=bool)
    for name, (qadr, dadr) in addresses.items():
        data.qpos[qadr] = fixed[name]
        free[dadr] = False
    with position_only(model):
        residual, jac = equality_residual(model, data)
        norm = float(np.linalg.norm(residual, np.inf)) if residual.size else 0.0
        step = np.zeros(model.nv)
        for _ in range(max_iterations):
            if norm < tolerance:
                break
            step[:] = 0.0
            step[free] = -np.linalg.lstsq(jac[:, free], residual, rcond=None)[0]
            # Backtrack when a full Newton step overshoots (far from the solution).
            trial_scale = 1.0
            start = data.qpos.copy()
            while True:
                data.qpos[:] = start
                mujoco.mj_integratePos(model, data.qpos, step, trial_scale)
                residual, jac = equality_residual(model, data)
                trial = float(np.linalg.norm(residual, np.inf)) if residual.size else 0.0
                if trial < norm or trial_scale < 1e-3:
                    break
                trial_scale *= 0.5
            if trial < accept and trial > 0.5 * norm:
                norm = trial
                break  # rounding-limited: no more progress to be had, and closed well enough
            norm = trial
        if norm >= accept:
            raise PoseError(
                f"cannot assemble the mechanism with {describe_positions(model, fixed)}: the loops stay "
                f"{norm * 1e3:.3g} mm open (they cannot close there, or the fixed joints over-determine them)"
            )
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
    return norm


# a rocker walks from the export's pose to where a sweep starts in 5 deg steps
APPROACH_STEP_RAD = np.radians(5.0)
APPROACH_STEP_M = 2e-3


def approach(model: mujoco.MjModel, data: mujoco.MjData, driver: str, value: float) -> None:
    """Assemble the mechanism with ``driver`` at ``value``, walking there from the export's own
    pose in small steps so that it stays on the export's branch (a jump to the far end of a
    rocker's travel could land on the other assembly)."""
    qadr, _ = joint_dof(model, driver)
    data.qpos[:] = model.qpos0
    step = APPROACH_STEP_M if is_slide(model, driver) else APPROACH_STEP_RAD
    start = float(model.qpos0[qadr])
    count = max(1, int(np.ceil(abs(value - start) / step)))
    for target in np.linspace(start, value, count + 1)[1:]:
        solve_pose(model, data, {driver: float(target)})


def velocity_ratios(model: mujoco.MjModel, data: mujoco.MjData, driver: str) -> np.ndarray:
    """dq/dθ: the joint velocities (length nv) for a unit velocity of ``driver`` at the
    current pose, such that every equality constraint stays satisfied (J v = 0)."""
    _, dadr = joint_dof(model, driver)
    with position_only(model):
        _, jac = equality_residual(model, data)
    velocity = np.zeros(model.nv)
    velocity[dadr] = 1.0
    if jac.size:
        free = np.ones(model.nv, dtype=bool)
        free[dadr] = False
        velocity[free] = -np.linalg.lstsq(jac[:, free], jac[:, dadr], rcond=None)[0]
    return velocity


def passive_joints(model: mujoco.MjModel, data: mujoco.MjData, driven: Iterable[str]) -> list[str]:
    """The named joints that can still move at the current pose with the ``driven`` joints held:
    those the equality constraints (loops, couplings) leave free (a pendulum, a ball on a beam,
    the undriven joints of an arm)."""
    fixed = np.zeros(model.nv, dtype=bool)
    for name in driven:
        fixed[joint_dof(model, name)[1]] = True
    with position_only(model):
        _, jac = equality_residual(model, data)
    free = np.flatnonzero(~fixed)
    if not free.size:
        return []
    if jac.size:
        _, singular, vt = np.linalg.svd(jac[:, free])
        rank = int(
            np.sum(
                singular > JOINT_RANK_TOLERANCE * max(singular[0] if singular.size else 0.0, 1e-300)
            )
        )
        null = vt[rank:].T
    else:
        null = np.eye(free.size)
    if not null.size:
        return []
    motion = np.zeros(model.nv)
    motion[free] = np.linalg.norm(null, axis=1)
    out = []
    for j in range(model.njnt):
        name = model.joint(j).name
        width = {int(mujoco.mjtJoint.mjJNT_FREE): 6, int(mujoco.mjtJoint.mjJNT_BALL): 3}.get(
            int(model.jnt_type[j]), 1
        )
        dof = int(model.jnt_dofadr[j])
        if name and np.max(motion[dof : dof + width]) > 1e-6:
            out.append(name)
    return out


def degrees_of_freedom(model: mujoco.MjModel, data: mujoco.MjData) -> int:
    """The mechanism's mobility at the current pose: joint velocities minus the rank of the
    equality constraints' Jacobian (loops, couplings)."""
    with position_only(model):
        _, jac = equality_residual(model, data)
    if not jac.size:
        return int(model.nv)
    singular = np.linalg.svd(jac, compute_uv=False)
    rank = int(np.sum(singular > JOINT_RANK_TOLERANCE * max(singular[0], 1e-300)))
    return int(model.nv) - rank


def sweep(
    model: mujoco.MjModel,
    angles: Iterable[float],
    driver: str,
    data: mujoco.MjData | None = None,
) -> np.ndarray:
    """Poses (n, nq) of the mechanism with ``driver`` at each of ``angles`` (rad), each
    warm-started from the previous one so the assembly stays on one branch."""
    data = data or mujoco.MjData(model)
    poses = []
    for angle in angles:
        solve_pose(model, data, {driver: float(angle)})
        poses.append(data.qpos.copy())
    return np.asarray(poses)
