"""The driver and the torque laws: drive modes (full, half, microstepping), the phase current
references, both models' torque, and the parameter array the callbacks read (the layout
of ``actuator_user``, mirrored in ``mechanism/native/stepper.c``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from mechanism.errors import UserError
from mechanism.steppers._motor import StepperParams

# Layout of actuator_user, mirrored in mechanism/native/stepper.c.
MARKER = 870048.0
StepperKind = Literal["circuit", "physical"]  # the stepper model: its circuit, or physical
KIND_CODES: dict[StepperKind, int] = {"circuit": 1, "physical": 2}
(
    USER_MARKER,
    USER_KIND,
    USER_POLE_PAIRS,
    USER_DIVISIONS,
    USER_SINE,
    USER_CURRENT,
    USER_RESISTANCE,
    USER_INDUCTANCE,
    USER_FLUX,
    USER_DETENT,
    USER_SUPPLY,
    USER_CHOP_HZ,
    USER_DECAY_MARGIN,
    USER_KT,
    USER_KW,
    USER_SIZE,
) = range(16)
CIRCUIT_ACTDIM = 4  # i_a, i_b, chopper_a, chopper_b
KINDS: tuple[StepperKind, ...] = get_args(StepperKind)


@dataclass(frozen=True)
class DriveMode:
    """How the driver turns a commanded angle into phase currents."""

    name: str
    divisions: int  # positions per full step
    sine: bool  # sine/cosine currents (microstepping) or +-I/0 per phase

    @property
    def offset_rad_electrical(self) -> float:
        """Full stepping energises both phases: its positions sit half a step off the
        one-phase positions."""
        return 0.25 * math.pi if (not self.sine and self.divisions == 1) else 0.0


def drive_mode(name: str) -> DriveMode:
    """``full`` (both phases on), ``half`` or ``microN`` (N = 2..256 sine/cosine
    positions per full step, e.g. ``micro16``)."""
    text = str(name).strip().lower()
    if text == "full":
        return DriveMode("full", 1, False)
    if text == "half":
        return DriveMode("half", 2, False)
    if text.startswith("micro"):
        digits = text[len("micro") :]
        if digits.isdigit() and 2 <= int(digits) <= 256:
            return DriveMode(text, int(digits), True)
    raise UserError(
        f"unknown drive mode '{name}': use full, half or microN with N = 2..256 (e.g. micro16)"
    )


def _drive(u, command_rad):
    """The driver, from an actuator's user array (see :func:`user_data`); arrays or
    scalars. Mirrors ``drive`` in stepper.c."""
    p, n, current = u[USER_POLE_PAIRS], u[USER_DIVISIONS], u[USER_CURRENT]
    sine = u[USER_SINE] != 0
    pitch = 0.5 * math.pi / n
    offset = 0.25 * math.pi if (not sine and n == 1) else 0.0
    phi = offset + np.floor((p * np.asarray(command_rad) - offset) / pitch + 0.5) * pitch
    c, s = np.cos(phi), np.sin(phi)
    if sine:
        return phi, current * c, current * s
    ref_a = np.where(np.abs(c) < 1e-6, 0.0, current * np.sign(c))
    ref_b = np.where(np.abs(s) < 1e-6, 0.0, current * np.sign(s))
    return phi, ref_a, ref_b


def _physical_current(u, omega):
    """Thesis eq. 25: i = (Vs - Kw |w|) / R, not below zero."""
    return np.maximum(0.0, (u[USER_SUPPLY] - u[USER_KW] * np.abs(omega)) / u[USER_RESISTANCE])


def _circuit_torque(u, theta, current_a, current_b):
    """Thesis eq. 17 with the detent term of period one full step."""
    p = u[USER_POLE_PAIRS]
    return -p * u[USER_FLUX] * (
        current_a * np.sin(p * theta) + current_b * np.sin(p * theta - 0.5 * np.pi)
    ) - u[USER_DETENT] * np.sin(4 * p * theta)


def _physical_torque(u, theta, omega, command_rad):
    """Thesis eq. 21 with eq. 25's current; the spring scales with the driver's current
    vector (two phases on = 1, one phase or microstepping = 1/sqrt 2)."""
    phi, ref_a, ref_b = _drive(u, command_rad)
    magnitude = np.hypot(ref_a, ref_b) / (math.sqrt(2) * u[USER_CURRENT])
    return (
        u[USER_KT]
        * _physical_current(u, omega)
        * magnitude
        * np.sin(phi - u[USER_POLE_PAIRS] * np.asarray(theta))
    )


def drive(params: StepperParams, mode: DriveMode, command_rad):
    """The driver: rounded electrical angle and the phase current references [A] for a
    commanded shaft angle [rad] (arrays or scalars)."""
    return _drive(user_data(params, "circuit", mode), command_rad)


def physical_torque(params: StepperParams, mode: DriveMode, theta, omega, command_rad):
    """The physical model's torque [N m] at rotor angle and speed for a command."""
    return _physical_torque(user_data(params, "physical", mode), theta, omega, command_rad)


def rest_angle_rad(params: StepperParams, mode: DriveMode, steps=0.0):
    """The equilibrium shaft angle of a commanded position in full steps (unloaded)."""
    return mode.offset_rad_electrical / params.pole_pairs + np.asarray(steps) * params.step_rad


def linear_stiffness(
    params: StepperParams, kind: StepperKind, mode: DriveMode, steps: float = 0.0
) -> float:
    """dT/dtheta [N m/rad] at rest at the commanded position (unloaded, standstill):
    the linearised model whose ringing frequency is sqrt(K / J)."""
    phi, ref_a, ref_b = drive(params, mode, rest_angle_rad(params, mode, steps))
    p = params.pole_pairs
    if kind == "circuit":
        current_vector = float(np.hypot(ref_a, ref_b))
        return (
            p * p * params.flux_linkage_Vs * current_vector
            + 4 * p * params.detent_torque_Nm * math.cos(4 * float(phi))
        )
    magnitude = float(np.hypot(ref_a, ref_b)) / (math.sqrt(2) * params.rated_current_A)
    return p * params.physical_kt_Nm_A * params.supply_V / params.resistance_ohm * magnitude


def user_data(params: StepperParams, kind: StepperKind, mode: DriveMode) -> list[float]:
    if kind not in KIND_CODES:
        raise UserError(f"unknown stepper model '{kind}': use {' or '.join(KINDS)}")
    u = [0.0] * USER_SIZE
    u[USER_MARKER] = MARKER
    u[USER_KIND] = KIND_CODES[kind]
    u[USER_POLE_PAIRS] = params.pole_pairs
    u[USER_DIVISIONS] = mode.divisions
    u[USER_SINE] = 1.0 if mode.sine else 0.0
    u[USER_CURRENT] = params.rated_current_A
    u[USER_RESISTANCE] = params.resistance_ohm
    u[USER_INDUCTANCE] = params.inductance_H
    u[USER_FLUX] = params.flux_linkage_Vs
    u[USER_DETENT] = params.detent_torque_Nm
    u[USER_SUPPLY] = params.supply_V
    u[USER_CHOP_HZ] = params.chopper_hz
    u[USER_DECAY_MARGIN] = params.decay_margin
    u[USER_KT] = params.physical_kt_Nm_A
    u[USER_KW] = params.physical_kw_V_s_rad
    return u
