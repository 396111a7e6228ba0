"""A machine's lumped drive numbers, read from its description and its CAD model.

Identification, diagnosis and the virtual bench scale every bound, start and truth range
from a :class:`~mechanism.dynamics.lumped.DriveNominal`; this builds it for any described
machine: the motor's datasheet, the motor-to-shaft ratio and the mean inertia at the shaft
from the model (motor reflected), and the described friction referred to the shaft; or, where
the description has a ``[lumped]`` section (the whole machine as a lumped model identified it),
those numbers for inertia and friction.
"""

from __future__ import annotations

import numpy as np

from mechanism.dynamics.lumped import DriveNominal, MotorConstants
from mechanism.kinematics.linkage import LinkageTables
from mechanism.machine.machine import Machine

CONSTANT_RATIO = 1e-6  # a shaft geared to the main one keeps its ratio over a turn


def machine_drive_nominal(machine: Machine) -> DriveNominal:
    tables, motor = machine.tables, machine.motor
    ratio = abs(machine.motor_ratio)
    coulomb = viscous = 0.0
    for joint, law in machine.friction.laws.items():
        r = np.abs(tables.ratios[joint]) if joint in tables.ratios else np.zeros(1)
        coulomb += law.coulomb * float(np.mean(r))
        viscous += law.viscous * float(np.mean(r**2))
    others = {}
    for joint, r in tables.ratios.items():
        mean = float(np.mean(r))
        if (
            joint not in (machine.motor_joint, machine.shaft_joint)
            and abs(mean) > 1e-9
            and np.ptp(r) <= CONSTANT_RATIO * abs(mean)
        ):
            others[joint] = abs(mean)
    supply = machine.description.section("supply").get("voltage_V")
    constants = MotorConstants(
        motor.resistance_ohm, motor.torque_constant_Nm_A, motor.back_emf_V_s_rad, ratio
    )
    description = machine.description
    zero = machine.zero_meaning
    inertia = tables.mean_inertia_kgm2
    linkage: LinkageTables | None = tables
    lumped = description.section("lumped")
    # the whole machine as a lumped model identified it (parts the CAD lacks included): its
    # numbers; its inertia replaces the linkage tables, whose shape belongs to the CAD's
    if "inertia_motor_side_kgm2" in lumped:
        inertia, linkage = lumped["inertia_motor_side_kgm2"] * ratio**2, None
    coulomb = lumped.get("coulomb_shaft_Nm", coulomb)
    if "viscous_motor_side_Nm_s_per_rad" in lumped:
        viscous = lumped["viscous_motor_side_Nm_s_per_rad"] * ratio**2
    return DriveNominal(
        constants,
        inertia_kgm2=inertia,
        coulomb_shaft_Nm=coulomb,
        viscous_shaft_Nm_s_per_rad=viscous,
        joint_ratios=tuple(others.items()),
        supply_V=supply,
        tool_in_fabric=machine.fabric_capable,
        zero_meaning=zero,
        travel_rad=machine.shaft_span_rad,
        linkage=linkage,
        roles=(machine.shaft_joint, machine.zero_site),
        model_path=str(machine.model_path),
    )
