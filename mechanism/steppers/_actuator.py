"""The stepper as a MuJoCo actuator: adding it to a spec, and a bare motor model."""

from __future__ import annotations

import math
import warnings

from mechanism.errors import UserError
from mechanism.steppers._drive import (
    CIRCUIT_ACTDIM,
    KIND_CODES,
    KINDS,
    USER_SIZE,
    DriveMode,
    StepperKind,
    drive_mode,
    linear_stiffness,
    user_data,
)
from mechanism.steppers._motor import StepperParams


def add_stepper(
    spec,
    joint: str,
    params: StepperParams,
    kind: StepperKind = "circuit",
    mode: str | DriveMode = "full",
    name: str = "stepper",
    gear: float = 1.0,
):
    """Add a stepper actuator on ``joint`` of an ``mujoco.MjSpec`` (``gear`` = motor turns
    per joint turn). The chopper's switch state needs the activation to advance by one
    Euler step (Euler and implicit integrators do that); an RK4 model is switched to Euler.
    The model's timestep must resolve the chopper (see :func:`default_timestep`)."""
    import mujoco

    mode = drive_mode(mode) if isinstance(mode, str) else mode
    spec.nuser_actuator = max(int(spec.nuser_actuator), USER_SIZE)
    if kind == "circuit" and spec.option.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        warnings.warn(
            "the circuit stepper model needs an Euler or implicit integrator: switching the model from RK4 to Euler"
        )
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    actuator = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.gear[0] = gear
    actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    actuator.gainprm[0] = 0.0  # all of the torque is the user bias
    actuator.biastype = mujoco.mjtBias.mjBIAS_USER
    if kind == "circuit":
        actuator.dyntype = mujoco.mjtDyn.mjDYN_USER
        actuator.actdim = CIRCUIT_ACTDIM
    actuator.userdata = user_data(params, kind, mode)
    return actuator


def default_timestep(params: StepperParams, kind: StepperKind) -> float:
    """Ten steps per chopper period for the circuit model; the physical model has no
    electrical dynamics and needs only to resolve the rotor's ringing."""
    if kind == "circuit":
        return 0.1 / params.chopper_hz
    natural_hz = math.sqrt(
        linear_stiffness(params, "physical", drive_mode("full")) / params.inertia_kg_m2
    ) / (2 * math.pi)
    return min(2e-5, 0.02 / natural_hz)


def build_model(
    params: StepperParams,
    kind: StepperKind = "circuit",
    mode: str | DriveMode = "full",
    timestep: float | None = None,
):
    """A bare motor: one rotor (inertia rotor + load) on a hinge ``rotor`` with the viscous
    damping c and the load torque as Coulomb friction, the actuator ``stepper`` and a
    torque sensor."""
    import mujoco

    if kind not in KIND_CODES:
        raise UserError(f"unknown stepper model '{kind}': use {' or '.join(KINDS)}")
    spec = mujoco.MjSpec()
    spec.modelname = f"stepper_{kind}"
    spec.option.timestep = timestep or default_timestep(params, kind)
    spec.option.gravity = [0, 0, 0]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    body = spec.worldbody.add_body(name="rotor")
    body.mass = 0.01
    body.inertia = [params.inertia_kg_m2] * 3
    body.explicitinertial = True
    joint = body.add_joint(
        name="rotor",
        type=mujoco.mjtJoint.mjJNT_HINGE,
        axis=[0, 0, 1],
        damping=params.damping_Nm_s_rad,
        frictionloss=params.load_torque_Nm,
    )
    # MuJoCo's default friction time constant (20 ms) is far slower than this rotor's dynamics
    joint.solref_friction = [4 * spec.option.timestep, 1.0]
    add_stepper(spec, "rotor", params, kind, mode)
    spec.add_sensor(
        name="torque",
        type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
        objname="stepper",
    )
    return spec.compile()
