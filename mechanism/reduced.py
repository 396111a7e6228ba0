"""The reduced 1-DOF form of the multibody machine, computed by MuJoCo from the CAD model.

The sewing machine has one degree of freedom: every joint position is a function q(θ) of
the arm angle θ. Lagrange's equation projected on θ is exact:

    J(θ) θ'' + ½ J'(θ) θ'² + G(θ) = Q(θ, θ', V)

with J(θ) = vᵀ M(q) v the effective inertia (v = dq/dθ, motor through the belt included),
G(θ) = vᵀ g(q) the gravity torque (positive = resisting forward rotation), and Q the
generalised motor, friction and fabric forces, each joint's force times its ratio v_j.
:func:`linkage_tables` tabulates these over one revolution with MuJoCo's mass matrix,
gravity bias and the constraint Jacobians (mechanism.kinematics); :class:`ReducedModel`
integrates the equation (RK4, Karnopp stick-slip) in C, thousands of times faster than
the full model, for identification.
"""

from __future__ import annotations

import ctypes
import functools
import os
from dataclasses import dataclass, field

import mujoco
import numpy as np

from mechanism import native
from mechanism.errors import UserError
from mechanism.friction import STRIBECK_LAWS, FrictionLaw
from mechanism.inputs import VoltageProfile
from mechanism.kinematics import solve_pose, velocity_ratios
from mechanism.machine import ARM, MOTOR, NEEDLE_SITE, Machine, MachineConfig
from mechanism.simulation import MAX_DURATION_S, SimulationResult

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
    """Arm-side quantities over one revolution, sampled at ``angle_rad`` (0 = needle TDC).

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
    needle_z_m: np.ndarray | None = None  # world height of the needle point
    needle_dz_drad: np.ndarray | None = None

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
        return periodic_interp(getattr(self, name), angle)


def compute_tables(model: mujoco.MjModel, n: int = 720, driver: str = ARM) -> LinkageTables:
    """Tabulate J, J', G, joint ratios and positions over one revolution of ``driver``."""
    if n < 16:
        raise UserError("at least 16 table samples per revolution are needed")
    data = mujoco.MjData(model)
    angles = np.arange(n) * TWO_PI / n
    one_dof = [j for j in range(model.njnt)
               if int(model.jnt_type[j]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))]
    names = [model.joint(j).name for j in one_dof]
    inertia, gravity = np.zeros(n), np.zeros(n)
    ratios = {name: np.zeros(n) for name in names}
    positions = {name: np.zeros(n) for name in names}
    has_needle = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, NEEDLE_SITE) >= 0
    needle_z, needle_dz = np.zeros(n), np.zeros(n)
    mass = np.zeros((model.nv, model.nv))
    jac = np.zeros((3, model.nv))
    for i, angle in enumerate(angles):
        solve_pose(model, data, {driver: angle})
        v = velocity_ratios(model, data, driver)
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)  # qM and the bias at zero velocity (gravity only)
        mujoco.mj_fullM(model, data, mass)
        inertia[i] = v @ mass @ v
        gravity[i] = v @ data.qfrc_bias
        for j, name in zip(one_dof, names):
            ratios[name][i] = v[model.jnt_dofadr[j]]
            positions[name][i] = data.qpos[model.jnt_qposadr[j]]
        if has_needle:
            site = model.site(NEEDLE_SITE).id
            mujoco.mj_jacSite(model, data, jac, None, site)
            needle_z[i] = data.site_xpos[site][2]
            needle_dz[i] = jac[2] @ v
    return LinkageTables(
        angle_rad=angles,
        inertia_kgm2=inertia,
        dinertia_drad=periodic_derivative(inertia),
        gravity_torque_Nm=gravity,
        ratios=ratios,
        positions=positions,
        needle_z_m=needle_z if has_needle else None,
        needle_dz_drad=needle_dz if has_needle else None,
    )


@functools.lru_cache(maxsize=8)
def _cached_tables(path: str, mtime: float, n: int) -> LinkageTables:
    from mechanism.models import load_model

    return compute_tables(load_model(path), n)


def linkage_tables(model_path: str | os.PathLike | None = None, n: int = 720) -> LinkageTables:
    """Tables of the converted MJCF (default: the shipped sewing machine), cached per file."""
    from mechanism.models import model_path as resolve

    path = resolve(model_path)
    return _cached_tables(str(path), path.stat().st_mtime, n)


class _Tables(ctypes.Structure):
    _fields_ = [(name, ctypes.c_void_p) for name in (
        "inertia", "dinertia", "gravity", "motor_ratio", "viscous", "cogging",
        "needle_depth", "needle_dz", "friction_ratio", "friction_scale", "friction_static_scale",
        "friction_params")] + [
        ("n", ctypes.c_int), ("nfriction", ctypes.c_int),
        ("kt", ctypes.c_double), ("ke", ctypes.c_double), ("resistance", ctypes.c_double),
        ("fabric_down", ctypes.c_double), ("fabric_up", ctypes.c_double),
        ("fabric_thickness", ctypes.c_double), ("fabric_ramp", ctypes.c_double),
        ("stick_velocity", ctypes.c_double)]


@dataclass
class ReducedModel:
    """The machine's 1-DOF equation with everything the full model has except the
    belt/loop constraint compliance and motor inductance (quasi-static current)."""

    machine: Machine
    n: int = 720
    tables: LinkageTables = field(init=False)

    def __post_init__(self):
        motor = self.machine.motor
        if motor.inductance_H:
            raise UserError("the reduced model uses the quasi-static motor current (no inductance)")
        n = self.n if not motor.cogging_Nm else max(self.n, 4096)
        self.tables = compute_tables(self.machine.model, n)
        t = self.tables
        self._motor_ratio = t.ratios[MOTOR]
        self._friction = []
        self._static_scales = []
        viscous = np.zeros(n)
        for name, law in self.machine.friction.laws.items():
            ratio = t.ratios[name]
            viscous += law.viscous * ratio**2
            angle = t.positions[law.position_joint or name]
            scale = law.position_scale(angle) * np.ones(n)
            static_scale = law.position_scale(angle, law.static_amplitude) * np.ones(n)
            self._friction.append((ratio, scale, law))
            self._static_scales.append(static_scale)
        self._viscous = viscous
        cog = np.zeros(n)
        if motor.cogging_Nm:
            cog = self._motor_ratio * motor.cogging_Nm * np.sin(
                motor.cogging_poles * t.positions[MOTOR] + motor.cogging_phase_rad)
        self._cogging = cog
        fabric = self.machine.fabric
        if fabric.layers:
            top = self.machine.plate_top_z + fabric.thickness_m
            self._needle_depth = top - t.needle_z_m
            self._needle_dz = t.needle_dz_drad
        else:
            self._needle_depth = np.full(n, -1.0)
            self._needle_dz = np.zeros(n)

    # -- the right-hand side, in numpy (the reference for the C kernel and its fallback) --
    def static_friction(self, angle) -> float:
        """Break-away torque at the arm [N m] at rest at ``angle``."""
        return float(sum(abs(periodic_interp(r, angle)) * law.static_level * periodic_interp(s, angle)
                         for (r, _, law), s in zip(self._friction, self._static_scales)))

    def generalized_force(self, angle, velocity, voltage) -> float:
        """Everything but inertia: motor - ½J'ω² - G - friction - fabric [N m at the arm]."""
        t = self.tables
        motor = self.machine.motor
        rm = periodic_interp(self._motor_ratio, angle)
        force = rm * motor.torque_constant_Nm_A / motor.resistance_ohm * (voltage - motor.back_emf_V_s_rad * rm * velocity)
        force += periodic_interp(self._cogging, angle) - 0.5 * t.at("dinertia_drad", angle) * velocity**2
        force -= t.at("gravity_torque_Nm", angle) + periodic_interp(self._viscous, angle) * velocity
        for r, s, law in self._friction:
            ratio = periodic_interp(r, angle)
            force -= ratio * law.sliding_level(ratio * velocity) * periodic_interp(s, angle) * np.sign(ratio * velocity)
        if self.machine.fabric.layers:
            dz = periodic_interp(self._needle_dz, angle)
            force += dz * self.machine.fabric.force(periodic_interp(self._needle_depth, angle), dz * velocity)
        return float(force)

    def simulate(self, voltage: VoltageProfile | float, duration_s: float, start_angle_rad: float = 0.0,
                 sample_rate_hz: float = 1000.0, substeps: int = 2, start_velocity_rad_s: float = 0.0) -> SimulationResult:
        if not 0 < duration_s <= MAX_DURATION_S:
            raise UserError(f"duration must be positive and at most {MAX_DURATION_S:g} s, got {duration_s:g}")
        if not isinstance(voltage, VoltageProfile):
            voltage = VoltageProfile.constant(voltage)
        nsample = int(round(duration_s * sample_rate_hz))
        dt = 1.0 / (sample_rate_hz * substeps)
        volts = voltage(np.arange(nsample * substeps) * dt)
        out = np.zeros((nsample, 3))
        library = native.load("reduced")
        if library is not None:
            self._run_native(library, volts, dt, substeps, start_angle_rad, start_velocity_rad_s, out)
        else:
            self._run_python(volts, dt, substeps, start_angle_rad, start_velocity_rad_s, out)
        angle, velocity, acceleration = out.T
        t = self.tables
        motor = self.machine.motor
        rm = periodic_interp(self._motor_ratio, angle)
        sample_volts = volts[substeps - 1 :: substeps]
        current = (sample_volts - motor.back_emf_V_s_rad * rm * velocity) / motor.resistance_ohm
        needle = np.full(nsample, np.nan)
        if t.needle_z_m is not None:
            needle = self.machine.needle_z_mm(t.at("needle_z_m", angle))
        return SimulationResult(
            time_s=np.arange(1, nsample + 1) / sample_rate_hz,
            voltage_V=sample_volts,
            current_A=current,
            arm_angle_rad=angle,
            arm_velocity_rad_s=velocity,
            arm_acceleration_rad_s2=acceleration,
            needle_z_mm=needle,
            motor_velocity_rad_s=rm * velocity,
            metadata={"model": "reduced", "native": library is not None, "substep_s": dt},
        )

    def _stick_velocity(self) -> float:
        return 1e-6

    def _run_native(self, library, volts, dt, substeps, angle0, velocity0, out) -> None:
        t = self.tables
        n = len(t.angle_rad)
        keep = []

        def ptr(array):
            array = np.ascontiguousarray(array, dtype=np.float64)
            keep.append(array)
            return array.ctypes.data

        ratios = np.concatenate([r for r, _, _ in self._friction]) if self._friction else np.zeros(1)
        scales = np.concatenate([s for _, s, _ in self._friction]) if self._friction else np.zeros(1)
        static_scales = np.concatenate(self._static_scales) if self._friction else np.zeros(1)
        params = np.array([[law.coulomb, law.static_level, law.stribeck_velocity, STRIBECK_LAWS[law.stribeck],
                            law.tustin_exponent] for _, _, law in self._friction] or [[0.0] * 5]).ravel()
        motor, fabric = self.machine.motor, self.machine.fabric
        tables = _Tables(
            ptr(t.inertia_kgm2), ptr(t.dinertia_drad), ptr(t.gravity_torque_Nm), ptr(self._motor_ratio),
            ptr(self._viscous), ptr(self._cogging), ptr(self._needle_depth), ptr(self._needle_dz),
            ptr(ratios), ptr(scales), ptr(static_scales), ptr(params), n, len(self._friction),
            motor.torque_constant_Nm_A, motor.back_emf_V_s_rad, motor.resistance_ohm,
            fabric.piercing_force_N if fabric.layers else 0.0,
            fabric.drag_fraction * fabric.piercing_force_N if fabric.layers else 0.0,
            fabric.thickness_m, fabric.point_taper_mm * 1e-3, self._stick_velocity())
        volts = np.ascontiguousarray(volts, dtype=np.float64)
        library.mechanism_reduced_run.restype = None
        library.mechanism_reduced_run(
            ctypes.byref(tables), volts.ctypes.data_as(ctypes.c_void_p), ctypes.c_int(len(volts)),
            ctypes.c_int(substeps), ctypes.c_double(dt), ctypes.c_double(angle0), ctypes.c_double(velocity0),
            out.ctypes.data_as(ctypes.c_void_p))

    def _run_python(self, volts, dt, substeps, angle0, velocity0, out) -> None:
        """Same scheme as native/reduced.c, in Python (slow; machines without a compiler)."""
        theta, omega = float(angle0), float(velocity0)
        t = self.tables

        def acc(th, om, v):
            return self.generalized_force(th, om, v) / t.at("inertia_kgm2", th)

        for k in range(len(out)):
            start = omega
            for s in range(substeps):
                v = volts[k * substeps + s]
                if omega == 0.0:
                    drive = self.generalized_force(theta, 0.0, v)
                    if abs(drive) <= self.static_friction(theta):
                        continue
                    omega = np.sign(drive) * self._stick_velocity()
                k1 = acc(theta, omega, v)
                k2 = acc(theta + 0.5 * dt * omega, omega + 0.5 * dt * k1, v)
                k3 = acc(theta + 0.5 * dt * (omega + 0.5 * dt * k1), omega + 0.5 * dt * k2, v)
                k4 = acc(theta + dt * (omega + 0.5 * dt * k2), omega + dt * k3, v)
                new_theta = theta + dt * omega + dt * dt / 6 * (k1 + k2 + k3)
                new_omega = omega + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                if omega * new_omega < 0:  # came to rest within the step
                    new_omega = 0.0
                theta, omega = new_theta, new_omega
            out[k] = theta, omega, (omega - start) / (dt * substeps)


def reduced_model(model_path=None, config: MachineConfig | None = None, n: int = 720) -> ReducedModel:
    return ReducedModel(Machine(model_path, config), n)
