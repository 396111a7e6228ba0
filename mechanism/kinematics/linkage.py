"""Linkage tables of a 1-DOF mechanism over one revolution of its shaft, computed by MuJoCo.

Every joint position of a 1-DOF mechanism is a function q(θ) of the shaft angle θ. Over one
revolution :func:`compute_tables` tabulates the effective inertia J(θ) = vᵀ M(q) v
(v = dq/dθ), its derivative, the gravity torque G(θ) = vᵀ g(q), every joint's ratio and
position, and the height of a tool site, from MuJoCo's mass matrix, gravity bias and the
constraint Jacobians. The shaft angle is ``direction * (q_shaft - zero_rad)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mechanism.errors import UserError
from mechanism.kinematics.pose import approach, solve_pose, velocity_ratios

TWO_PI = 2 * np.pi


def periodic_derivative(values: np.ndarray) -> np.ndarray:
    """d/dθ of samples of a smooth 2π-periodic function on a uniform grid (spectral)."""
    n = len(values)
    spectrum = np.fft.rfft(values)
    spectrum *= 1j * np.arange(len(spectrum))
    if n % 2 == 0:
        spectrum[-1] = 0.0  # the Nyquist term has no well-defined derivative
    return np.fft.irfft(spectrum, n)


def periodic_interp(table: np.ndarray, angle) -> np.ndarray:
    """Linear interpolation of samples on a uniform grid over [0, 2π) at any angles."""
    n = len(table)
    grid = np.arange(n + 1) * TWO_PI / n
    return np.interp(np.mod(angle, TWO_PI), grid, np.append(table, table[0]))


@dataclass
class LinkageTables:
    """Shaft-side quantities over one revolution, sampled at ``angle_rad`` (0 = the described zero).

    ``inertia_kgm2`` is the TOTAL effective inertia J(θ) (motor through the belt included);
    ``inertia_variation_kgm2`` is what a constant-inertia (lumped) model leaves out and
    ``reflected_inertia_kgm2`` the constant part.
    """

    angle_rad: np.ndarray
    inertia_kgm2: np.ndarray  # J(θ): effective inertia at the arm, everything included
    dinertia_drad: np.ndarray  # J'(θ)
    gravity_torque_Nm: np.ndarray  # G(θ), positive resisting forward rotation
    ratios: dict[str, np.ndarray]  # dq_j/dθ per one-DOF joint
    positions: dict[str, np.ndarray]  # q_j(θ) per one-DOF joint
    tool_z_m: np.ndarray | None = None  # height of the tool site against gravity [m]
    tool_dz_drad: np.ndarray | None = None
    periodic: bool = True  # one revolution; False: a drive that rocks, sampled from one end of its travel to the other

    def interp(self, values: np.ndarray, angle) -> np.ndarray:
        """Samples of this table's grid at shaft angles [rad] (periodic over a revolution, or
        held at the ends of a rocking drive's travel)."""
        if self.periodic:
            return periodic_interp(values, angle)
        return np.interp(angle, self.angle_rad, values)

    @property
    def mean_inertia_kgm2(self) -> float:
        """The constant part (what a lumped model's J stands for, arm side)."""
        return float(self.inertia_kgm2.mean())

    reflected_inertia_kgm2 = mean_inertia_kgm2

    @property
    def inertia_variation_kgm2(self) -> np.ndarray:
        """J(θ) minus its mean: what a constant-inertia model leaves out."""
        return self.inertia_kgm2 - self.inertia_kgm2.mean()

    def at(self, name: str, angle) -> np.ndarray:
        """Periodic linear interpolation of a tabulated quantity at arm angles [rad]."""
        return self.interp(getattr(self, name), angle)


def up_axis(model: mujoco.MjModel) -> np.ndarray:
    """Unit vector against gravity (world z when the model has no gravity)."""
    g = np.asarray(model.opt.gravity, dtype=float)
    norm = np.linalg.norm(g)
    return -g / norm if norm > 0 else np.array([0.0, 0.0, 1.0])


def compute_tables(
    model: mujoco.MjModel,
    driver: str,
    tool_site: str | None = None,
    n: int = 720,
    zero_rad: float = 0.0,
    direction: float = 1.0,
    span: tuple[float, float] | None = None,
) -> LinkageTables:
    """Tabulate J, J', G, joint ratios and positions over one revolution of ``driver``.

    Sample i is at shaft angle θ_i = 2πi/n, i.e. joint position ``zero_rad + direction θ_i``;
    ratios are per unit of shaft angle. ``tool_z_m`` is the tool site's height against gravity.
    ``span`` (shaft angles [rad], lower first): a drive that rocks, sampled at n points from one
    end of its travel to the other instead of over a revolution."""
    if n < 16:
        raise UserError("at least 16 table samples per revolution are needed")
    data = mujoco.MjData(model)
    angles = np.arange(n) * TWO_PI / n if span is None else np.linspace(span[0], span[1], n)
    one_dof = [
        j
        for j in range(model.njnt)
        if int(model.jnt_type[j])
        in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
    ]
    names = [model.joint(j).name for j in one_dof]
    inertia, gravity = np.zeros(n), np.zeros(n)
    ratios = {name: np.zeros(n) for name in names}
    positions = {name: np.zeros(n) for name in names}
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, tool_site) if tool_site else -1
    up = up_axis(model)
    tool_z, tool_dz = np.zeros(n), np.zeros(n)
    mass = np.zeros((model.nv, model.nv))
    if span is not None:
        approach(model, data, driver, zero_rad + direction * angles[0])
    jac = np.zeros((3, model.nv))
    for i, angle in enumerate(angles):
        solve_pose(model, data, {driver: zero_rad + direction * angle})
        v = direction * velocity_ratios(model, data, driver)
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)  # qM and the bias at zero velocity (gravity only)
        mujoco.mj_fullM(model, data, mass)
        inertia[i] = v @ mass @ v
        gravity[i] = v @ data.qfrc_bias
        for j, name in zip(one_dof, names):
            ratios[name][i] = v[model.jnt_dofadr[j]]
            positions[name][i] = data.qpos[model.jnt_qposadr[j]]
        if site >= 0:
            mujoco.mj_jacSite(model, data, jac, None, site)
            tool_z[i] = up @ data.site_xpos[site]
            tool_dz[i] = up @ jac @ v
    return LinkageTables(
        angle_rad=angles,
        inertia_kgm2=inertia,
        dinertia_drad=periodic_derivative(inertia)
        if span is None
        else np.gradient(inertia, angles),
        gravity_torque_Nm=gravity,
        ratios=ratios,
        positions=positions,
        tool_z_m=tool_z if site >= 0 else None,
        tool_dz_drad=tool_dz if site >= 0 else None,
        periodic=span is None,
    )
