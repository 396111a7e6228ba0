"""The reduced 1-DOF form of the multibody machine, computed by MuJoCo from the CAD model.

The machine has one degree of freedom: every joint position is a function q(θ) of
the shaft angle θ. Lagrange's equation projected on θ is exact:

    J(θ) θ'' + ½ J'(θ) θ'² + G(θ) = Q(θ, θ', V)

with J(θ) = vᵀ M(q) v the effective inertia (v = dq/dθ, motor through the belt included),
G(θ) = vᵀ g(q) the gravity torque (positive = resisting forward rotation), and Q the
generalised motor, friction and fabric forces, each joint's force times its ratio v_j.
:func:`mechanism.kinematics.linkage.compute_tables` tabulates these over one revolution with MuJoCo's mass matrix,
gravity bias and the constraint Jacobians (mechanism.kinematics.pose); :class:`ReducedModel`
integrates the equation (RK4, Karnopp stick-slip) in C, thousands of times faster than
the full model, for identification.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field

import numpy as np

from mechanism import native
from mechanism.errors import UserError
from mechanism.physics.friction import STRIBECK_LAWS
from mechanism.physics.inputs import VoltageProfile
from mechanism.kinematics.linkage import LinkageTables, compute_tables, periodic_interp
from mechanism.machine.machine import Machine, MachineConfig
from mechanism.dynamics.simulation import MAX_DURATION_S, SimulationResult, unstable


class _Tables(ctypes.Structure):
    _POINTERS = (
        "inertia",
        "dinertia",
        "gravity",
        "motor_ratio",
        "viscous",
        "cogging",
        "needle_depth",  # the tool's depth and dz/dθ, named as in native/reduced.c
        "needle_dz",
        "friction_ratio",
        "friction_scale",
        "friction_static_scale",
        "friction_params",
    )
    _fields_ = [(name, ctypes.c_void_p) for name in _POINTERS] + [  # type: ignore[assignment]
        ("n", ctypes.c_int),
        ("nfriction", ctypes.c_int),
        ("kt", ctypes.c_double),
        ("ke", ctypes.c_double),
        ("resistance", ctypes.c_double),
        ("supply_V", ctypes.c_double),
        ("series_ohm", ctypes.c_double),
        ("fabric_down", ctypes.c_double),
        ("fabric_up", ctypes.c_double),
        ("fabric_thickness", ctypes.c_double),
        ("fabric_ramp", ctypes.c_double),
        ("stick_velocity", ctypes.c_double),
    ]


@dataclass
class ReducedModel:
    """The machine's 1-DOF equation with everything the full model has except the
    belt/loop constraint compliance and motor inductance (quasi-static current)."""

    machine: Machine
    n: int = 720
    tables: LinkageTables = field(init=False)

    def __post_init__(self):
        motor = self.machine.motor
        if not getattr(self.machine, "rotates", True):
            raise UserError(
                f"the reduced model follows a shaft that turns whole revolutions; {self.machine.shaft_joint} "
                "rocks between hard stops: use the full multibody model (simulate without --reduced, sweep --full)"
            )
        if motor.inductance_H:
            raise UserError("the reduced model uses the quasi-static motor current (no inductance)")
        n = self.n if not motor.cogging_Nm else max(self.n, 4096)
        self.tables = (
            self.machine.tables
            if n == 720
            else compute_tables(
                self.machine.model,
                self.machine.shaft_joint,
                self.machine.tool_site,
                n,
                self.machine.frame.zero_rad,
                self.machine.frame.direction,
            )
        )
        t = self.tables
        self._motor_ratio = t.ratios[self.machine.motor_joint]
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
            cog = (
                self._motor_ratio
                * motor.cogging_Nm
                * np.sin(
                    motor.cogging_poles * t.positions[self.machine.motor_joint]
                    + motor.cogging_phase_rad
                )
            )
        self._cogging = cog
        fabric = self.machine.fabric
        if fabric.layers:
            top = self.machine.plate_top_z + fabric.thickness_m
            self._tool_depth = top - t.tool_z_m
            self._tool_dz = t.tool_dz_drad
        else:
            self._tool_depth = np.full(n, -1.0)
            self._tool_dz = np.zeros(n)

    # -- the right-hand side, in numpy (the reference for the C kernel and its fallback) --
    def motor_current(self, voltage, motor_velocity):
        """Armature current [A], quasi-static, within the supply's limit when described."""
        motor, supply = self.machine.motor, self.machine.supply
        if supply:
            return supply.current(motor, voltage, motor_velocity)
        return (
            np.asarray(voltage) - motor.back_emf_V_s_rad * np.asarray(motor_velocity)
        ) / motor.resistance_ohm

    def static_friction(self, angle):
        """Break-away torque at the shaft [N m] at rest at ``angle`` (a float, or an array for an array)."""
        total = sum(
            (
                abs(periodic_interp(r, angle)) * law.static_level * periodic_interp(s, angle)
                for (r, _, law), s in zip(self._friction, self._static_scales)
            ),
            np.zeros(np.shape(angle)),
        )
        return float(total) if np.ndim(angle) == 0 else total

    def generalized_force(self, angle, velocity, voltage):
        """Everything but inertia: motor - ½J'ω² - G - friction - fabric [N m at the shaft]
        (a float, or an array when any argument is one)."""
        t = self.tables
        motor = self.machine.motor
        rm = periodic_interp(self._motor_ratio, angle)
        force = rm * motor.torque_constant_Nm_A * self.motor_current(voltage, rm * velocity)
        force += (
            periodic_interp(self._cogging, angle) - 0.5 * t.at("dinertia_drad", angle) * velocity**2
        )
        force -= t.at("gravity_torque_Nm", angle) + periodic_interp(self._viscous, angle) * velocity
        for r, s, law in self._friction:
            ratio = periodic_interp(r, angle)
            force -= (
                ratio
                * law.sliding_level(ratio * velocity)
                * periodic_interp(s, angle)
                * np.sign(ratio * velocity)
            )
        if self.machine.fabric.layers:
            dz = periodic_interp(self._tool_dz, angle)
            force += dz * self.machine.fabric.force(
                periodic_interp(self._tool_depth, angle), dz * velocity
            )
        return float(force) if np.ndim(force) == 0 else force

    def simulate(
        self,
        voltage: VoltageProfile | float,
        duration_s: float,
        start_angle_rad: float = 0.0,
        sample_rate_hz: float = 1000.0,
        substeps: int = 2,
        start_velocity_rad_s: float = 0.0,
    ) -> SimulationResult:
        if not 0 < duration_s <= MAX_DURATION_S:
            raise UserError(
                f"duration must be positive and at most {MAX_DURATION_S:g} s, got {duration_s:g}"
            )
        if not isinstance(voltage, VoltageProfile):
            voltage = VoltageProfile.constant(voltage)
        self.machine.check_voltage(voltage)
        if not (
            np.isfinite(start_angle_rad)
            and np.isfinite(start_velocity_rad_s)
            and 10 <= sample_rate_hz <= 100_000
        ):
            raise UserError(
                "start angle and velocity must be finite and the sample rate 10 Hz to 100 kHz"
            )
        nsample = int(round(duration_s * sample_rate_hz))
        dt = 1.0 / (sample_rate_hz * substeps)
        volts = voltage(np.arange(nsample * substeps) * dt)
        if not np.isfinite(volts).all():  # the C kernel indexes tables by angle: NaN would crash it
            raise UserError("voltage must be finite")
        out = np.zeros((nsample, 3))
        library = native.load("reduced")
        if library is not None:
            self._run_native(
                library, volts, dt, substeps, start_angle_rad, start_velocity_rad_s, out
            )
        else:
            self._run_python(volts, dt, substeps, start_angle_rad, start_velocity_rad_s, out)
        bad = ~np.isfinite(out).all(axis=1)
        if bad.any():
            raise unstable((int(np.argmax(bad)) + 1) / sample_rate_hz, "non-finite angle or speed")
        angle, velocity, acceleration = out.T
        t = self.tables
        rm = periodic_interp(self._motor_ratio, angle)
        sample_volts = volts[substeps - 1 :: substeps]
        current = self.motor_current(sample_volts, rm * velocity)
        tool_z = np.full(nsample, np.nan)
        if t.tool_z_m is not None:
            tool_z = self.machine.tool_height_mm(t.at("tool_z_m", angle))
        return SimulationResult(
            time_s=np.arange(1, nsample + 1) / sample_rate_hz,
            voltage_V=sample_volts,
            current_A=current,
            shaft_angle_rad=angle,
            shaft_velocity_rad_s=velocity,
            shaft_acceleration_rad_s2=acceleration,
            tool_z_mm=tool_z,
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

        ratios = (
            np.concatenate([r for r, _, _ in self._friction]) if self._friction else np.zeros(1)
        )
        scales = (
            np.concatenate([s for _, s, _ in self._friction]) if self._friction else np.zeros(1)
        )
        static_scales = np.concatenate(self._static_scales) if self._friction else np.zeros(1)
        params = np.array(
            [
                [
                    law.coulomb,
                    law.static_level,
                    law.stribeck_velocity,
                    STRIBECK_LAWS[law.stribeck],
                    law.tustin_exponent,
                ]
                for _, _, law in self._friction
            ]
            or [[0.0] * 5]
        ).ravel()
        motor, fabric, supply = self.machine.motor, self.machine.fabric, self.machine.supply
        tables = _Tables(
            ptr(t.inertia_kgm2),
            ptr(t.dinertia_drad),
            ptr(t.gravity_torque_Nm),
            ptr(self._motor_ratio),
            ptr(self._viscous),
            ptr(self._cogging),
            ptr(self._tool_depth),
            ptr(self._tool_dz),
            ptr(ratios),
            ptr(scales),
            ptr(static_scales),
            ptr(params),
            n,
            len(self._friction),
            motor.torque_constant_Nm_A,
            motor.back_emf_V_s_rad,
            motor.resistance_ohm,
            supply.supply_V if supply else 0.0,
            supply.series_ohm if supply else 0.0,
            fabric.piercing_force_N if fabric.layers else 0.0,
            fabric.drag_fraction * fabric.piercing_force_N if fabric.layers else 0.0,
            fabric.thickness_m,
            fabric.point_taper_mm * 1e-3,
            self._stick_velocity(),
        )
        volts = np.ascontiguousarray(volts, dtype=np.float64)
        library.mechanism_reduced_run.restype = None
        library.mechanism_reduced_run(
            ctypes.byref(tables),
            volts.ctypes.data_as(ctypes.c_void_p),
            ctypes.c_int(len(volts)),
            ctypes.c_int(substeps),
            ctypes.c_double(dt),
            ctypes.c_double(angle0),
            ctypes.c_double(velocity0),
            out.ctypes.data_as(ctypes.c_void_p),
        )

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


def reduced_model(
    description=None, config: MachineConfig | None = None, n: int = 720
) -> ReducedModel:
    return ReducedModel(Machine(description, config), n)
