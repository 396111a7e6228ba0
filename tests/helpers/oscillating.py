"""Synthetic recordings of machines that swing back and forth, never a whole revolution:
a geared servo holding a pendulum (tests/models/geared_pendulum.*) and a positioning axis
with a constant offset force, both under a position loop (the logged voltage is the loop's
output). An independent truth: explicit integration at 0.1 ms of the physics written here
(smooth Coulomb friction, a gravity torque m g l sin theta, the winding's current), not the
library's drive kernel."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mechanism.dynamics.lumped import DriveNominal, MotorConstants
from mechanism.sysid.recording import make_recording


@dataclass(frozen=True)
class Servo:
    resistance_ohm: float
    torque_constant: float
    back_emf: float
    ratio: float
    inertia_kgm2: float  # at the output, rotor reflected
    viscous_Nm_s: float  # at the output
    coulomb_Nm: float  # at the output
    offset_Nm: float = 0.0  # constant torque resisting forward motion
    gravity_Nm: float = 0.0  # m g l: the gravity torque is gravity_Nm sin(theta)
    inductance_H: float = 0.0
    supply_V: float = 6.0
    counts_per_rev: int = 4096
    gear_driving: float = 0.0  # gearbox friction per unit motor torque, motor driving the load
    gear_backdriving: float = 0.0  # ... load driving the motor back

    def nominal(self, **changes) -> DriveNominal:
        n = self.ratio
        motor = MotorConstants(self.resistance_ohm, self.torque_constant, self.back_emf, n)
        values = dict(
            inertia_kgm2=self.inertia_kgm2,
            coulomb_shaft_Nm=self.coulomb_Nm,
            viscous_shaft_Nm_s_per_rad=self.viscous_Nm_s,
        )
        values.update(changes)
        return DriveNominal(motor, **values)


# the servo of tests/models/geared_pendulum.* (its numbers, and its model's m g l = 0.25 * 9.81 * 0.12)
PENDULUM_SERVO = Servo(
    2.0,
    0.01,
    0.01,
    50.0,
    inertia_kgm2=0.00611,
    viscous_Nm_s=0.0025,
    coulomb_Nm=0.03,
    gravity_Nm=0.25 * 9.81 * 0.12,
    inductance_H=1e-3,
    supply_V=6.0,
)
# a direct-drive positioning axis with a constant offset torque (a cable, a spring preload)
AXIS = Servo(
    1.0,
    0.05,
    0.05,
    1.0,
    inertia_kgm2=2e-3,
    viscous_Nm_s=1e-3,
    coulomb_Nm=0.05,
    offset_Nm=0.03,
    inductance_H=5e-4,
    supply_V=12.0,
    counts_per_rev=20000,
)


def reference(t: np.ndarray, amplitude: float, seed: int) -> np.ndarray:
    """A multisine position target (0.2-2 Hz), a few random phases."""
    rng = np.random.default_rng(seed)
    out = np.zeros_like(t)
    for f in (0.23, 0.51, 0.87, 1.4, 2.1):
        out += np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi)) / f
    return amplitude * out / np.max(np.abs(out))


def record(
    servo: Servo,
    duration_s: float = 6.0,
    fs: float = 200.0,
    amplitude_rad: float = 1.0,
    seed: int = 0,
    kp: float = 8.0,
    kd: float = 0.4,
    noise_V: float = 0.0,
    hold_s: float = 0.0,
):
    """A recording under a PD position loop sampled at ``fs``: the controller's output is
    the logged voltage (held over a sample), the angle is the quantised encoder's."""
    sub = 10e-5
    n_sub = int(round(1.0 / fs / sub))
    n = int(round(duration_s * fs)) + 1
    t = np.arange(n) / fs
    ref = reference(t, amplitude_rad, seed)
    if hold_s:
        ref = np.where(t < hold_s, 0.0, ref)
    rng = np.random.default_rng(seed + 1)
    step = 2 * math.pi / servo.counts_per_rev
    theta = w = current = 0.0
    angles, volts = np.zeros(n), np.zeros(n)
    k, r, ke = (
        servo.ratio * servo.torque_constant,
        servo.resistance_ohm,
        servo.back_emf * servo.ratio,
    )
    for i in range(n):
        measured = math.floor(theta / step) * step
        u = (
            kp * (ref[i] - measured)
            - kd * w
            + (noise_V * rng.standard_normal() if noise_V else 0.0)
        )
        u = min(max(u, -servo.supply_V), servo.supply_V)
        angles[i], volts[i] = measured, u
        for _ in range(n_sub):
            if servo.inductance_H > 0:
                current += sub * (u - r * current - ke * w) / servo.inductance_H
            else:
                current = (u - ke * w) / r
            motor = k * current
            friction = servo.coulomb_Nm + abs(motor) * (
                servo.gear_driving if motor * w >= 0 else servo.gear_backdriving
            )
            torque = (
                motor
                - servo.viscous_Nm_s * w
                - friction * math.tanh(w / 0.02)
                - servo.offset_Nm
                - servo.gravity_Nm * math.sin(theta)
            )
            w += sub * torque / servo.inertia_kgm2
            theta += sub * w
    return make_recording(t, volts, angles, source=f"synthetic servo seed {seed}")
