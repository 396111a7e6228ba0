"""Machines for tests: the shipped one, the toy, and the thesis's motor (tests may read the thesis)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from mechanism.data.reference import thesis
from mechanism.machine.description import read_description
from mechanism.machine.models import DEFAULT_DESCRIPTION
from mechanism.physics.motor import DCMotor

MODELS = Path(__file__).resolve().parent.parent / "models"
TOY = MODELS / "toy_sewing_machine.xml"
TOY_MACHINE = MODELS / "toy_sewing_machine.toml"


def shipped_description():
    return read_description(DEFAULT_DESCRIPTION)


def with_model(model_path):
    """The shipped description on another MJCF with the same names."""
    return replace(shipped_description(), model=Path(model_path))


def thesis_motor(**options) -> DCMotor:
    """The thesis's Domel 482.501 (Table 3 / section 3.1.1), independent of any description."""
    data = thesis()["main_motor"]
    return DCMotor(
        resistance_ohm=data["resistance_ohm"],
        torque_constant_Nm_A=data["torque_constant_Nm_per_A"],
        back_emf_V_s_rad=data["back_emf_constant_V_s_per_rad"],
        **options,
    )


def velocities_with_passive(
    machine, passive, control, seconds: float, every: int = 2
) -> list[float]:
    """Shaft velocities every ``every`` steps of ``machine`` from rest at angle 0 with the
    passive-force callback ``passive`` installed instead of the compiled one; ``control(t)``
    is the motor voltage. Puts the compiled callback back afterwards."""
    import mujoco

    from mechanism.machine import machine as machine_module

    model, data = machine.model, machine.reset(0.0)
    mujoco.set_mjcb_passive(passive)
    try:
        velocities = []
        for step in range(int(seconds / model.opt.timestep)):
            data.ctrl[machine.actuator] = control(step * model.opt.timestep)
            mujoco.mj_step(model, data)
            if (step + 1) % every == 0:
                velocities.append(data.qvel[machine.shaft_dof])
        return velocities
    finally:
        machine_module._CALLBACK_INSTALLED = False
        machine_module.install_callbacks()
