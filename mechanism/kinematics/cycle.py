"""The kinematic cycle: a one-degree-of-freedom machine driven at constant speed.

A designer's first question about a linkage is what it does over one revolution of its
input at a steady speed, before any motor or friction is known. For that cycle the motion
is pure kinematics (:mod:`mechanism.kinematics.pose` gives the poses and dq/dθ), and the loads
follow from rigid-body inverse dynamics with the driver supplying whatever torque keeps
its speed constant.

MuJoCo's own ``mj_inverse`` cannot give those loads in a closed-loop machine: it derives
constraint forces from the soft-constraint model (``f = -D (J qacc - aref)``), and along
a consistent trajectory ``J qacc - aref`` is zero up to round-off, so the loop-closing
forces come out as noise while the tree joints carry everything. :func:`set_state`
instead solves the rigid equations of motion

    M qacc + c(q, qvel) - qfrc_passive = e_driver τ + J_eqᵀ λ

for the driver torque τ and the equality-constraint forces λ (least squares; where the
constraints are redundant, e.g. the two ``connect`` constraints of one revolute loop
joint share the load along the axis, the minimum-norm split is taken, which is also what
MuJoCo's regularised solver converges to). λ is written to ``efc_force`` and MuJoCo's
``mj_sensorAcc`` then evaluates every acceleration and force sensor of the model
(``mj_rnePostConstraint`` turns ``connect``/``weld`` forces into body forces), so probes
read the same sensors in a kinematic cycle as in a dynamic simulation. Friction is not
part of the cycle (ideal joints); the dynamic simulation has it.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mechanism.kinematics.pose import position_only, joint_dof, solve_pose, velocity_ratios

DEFAULT_SPEED_RPM = 600.0  # a mid-range household sewing speed (10 stitches per second)
DEFAULT_RESOLUTION_DEG = 0.5
# central difference of dq/dθ: truncation ~1e-10, round-off ~1e-8 (relative)
DERIVATIVE_STEP_RAD = 1e-5


def cycle_angles(
    revolutions: float = 1.0, resolution_deg: float = DEFAULT_RESOLUTION_DEG, start_deg: float = 0.0
) -> np.ndarray:
    """Driver angles [rad] covering ``revolutions`` turns at ``resolution_deg`` steps (end excluded)."""
    count = max(1, int(round(360.0 * revolutions / resolution_deg)))
    return np.radians(start_deg + resolution_deg * np.arange(count))


@dataclass
class CycleStates:
    """Joint states along a constant-speed cycle (arrays indexed by sample)."""

    driver: str
    speed_rad_s: float
    angle: np.ndarray  # driver angle [rad]
    time: np.ndarray  # [s], 0 at the first sample
    qpos: np.ndarray  # (n, nq)
    qvel: np.ndarray  # (n, nv)
    qacc: np.ndarray  # (n, nv)


def kinematic_cycle(
    model: mujoco.MjModel,
    angles: np.ndarray,
    speed_rad_s: float,
    driver: str,
    data: mujoco.MjData | None = None,
) -> CycleStates:
    """Poses, velocities and accelerations with ``driver`` turning at a constant speed.

    qvel = ω dq/dθ and qacc = ω² d²q/dθ², with dq/dθ from the constraint Jacobian and
    d²q/dθ² from a central difference of dq/dθ (relative error below 1e-7).
    """
    data = data or mujoco.MjData(model)
    angles = np.asarray(angles, dtype=float)
    qpos = np.empty((len(angles), model.nq))
    qvel = np.empty((len(angles), model.nv))
    qacc = np.empty((len(angles), model.nv))
    h = DERIVATIVE_STEP_RAD
    for i, angle in enumerate(angles):
        solve_pose(model, data, {driver: float(angle)})
        pose = data.qpos.copy()
        qpos[i] = pose
        qvel[i] = speed_rad_s * velocity_ratios(model, data, driver)
        if speed_rad_s:
            ahead = _ratios_at(model, data, driver, angle + h)
            data.qpos[:] = pose
            behind = _ratios_at(model, data, driver, angle - h)
            qacc[i] = speed_rad_s**2 * (ahead - behind) / (2 * h)
        else:
            qacc[i] = 0.0
        data.qpos[:] = pose  # warm start for the next angle on the same branch
    time = (angles - angles[0]) / speed_rad_s if speed_rad_s else np.zeros_like(angles)
    return CycleStates(driver, float(speed_rad_s), angles, time, qpos, qvel, qacc)


def _ratios_at(model, data, driver, angle):
    solve_pose(model, data, {driver: float(angle)})
    return velocity_ratios(model, data, driver)


def set_state(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    qpos: np.ndarray,
    qvel: np.ndarray,
    qacc: np.ndarray,
    driver: str,
) -> float:
    """Put a cycle state into ``data`` with rigid inverse-dynamics loads, evaluate all
    sensors, and return the driver torque [N·m] (or force [N] for a slide) that holds it.

    After the call, ``sensordata``, ``efc_force`` (equality rows; other rows zero),
    ``cfrc_int``/``cfrc_ext`` and the kinematic quantities are consistent with the state.
    """
    _, dadr = joint_dof(model, driver)
    data.qpos[:] = qpos
    data.qvel[:] = qvel
    data.qacc[:] = qacc
    with position_only(model):
        mujoco.mj_fwdPosition(model, data)
        mujoco.mj_sensorPos(model, data)
        mujoco.mj_fwdVelocity(model, data)
        mujoco.mj_sensorVel(model, data)
        nefc = data.nefc
        rows = np.flatnonzero(data.efc_type[:nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
        jac = data.efc_J[: nefc * model.nv].reshape(nefc, model.nv)
        inertial = np.empty(model.nv)
        mujoco.mj_mulM(model, data, inertial, data.qacc)
        required = inertial + data.qfrc_bias - data.qfrc_passive
        system = np.zeros((model.nv, 1 + rows.size))
        system[dadr, 0] = 1.0
        system[:, 1:] = jac[rows].T
        solution = np.linalg.lstsq(system, required, rcond=None)[0]
        data.efc_force[:nefc] = 0.0
        data.efc_force[rows] = solution[1:]
        data.qfrc_constraint[:] = jac.T @ data.efc_force[:nefc]
        data.qfrc_inverse[:] = 0.0
        data.qfrc_inverse[dadr] = solution[0]
        data.flg_rnepost = 0
        mujoco.mj_sensorAcc(model, data)
    return float(solution[0])
