"""The ``multibody`` baseline: the lumped drive with the CAD model's linkage inside.

The reduced 1-DOF form of the multibody machine (:func:`mechanism.dynamics.reduced.linkage_tables`)
gives, over one arm revolution, the effective inertia J(theta) (motor through the belt
included), its derivative and the gravity torque G(theta), all on the arm side. This
baseline keeps their shapes and fits what the CAD cannot know: a constant inertia
correction (parts missing from the export, the rotor's real inertia), factors on the
angle-dependent inertia and on gravity (masses the export gets wrong; 1 = as exported),
viscous and Coulomb friction, the winding lag. The motor is the same datasheet DC motor as
in the lumped baseline. A ``linkage_dynamics`` finding on top of it means the linkage's
*shape* differs from the CAD's.
"""

from __future__ import annotations


from mechanism.dynamics.lumped import Drive, Signals
from mechanism.sysid.lumped_baseline import LumpedBaseline
from mechanism.sysid.parameters import Parameter


class MultibodyBaseline(LumpedBaseline):
    name = "multibody"
    linear = ("inertia_correction_motor_side_kgm2", "viscous_motor_side_Nm_s_per_rad", "coulomb_arm_Nm",
              "cad_inertia_variation_scale", "cad_gravity_scale")
    meaning = "the CAD model's reduced 1-DOF dynamics (angle-dependent inertia and gravity) with viscous and Coulomb friction"

    def __init__(self, nominal, free: tuple[str, ...] = (), model_path=None):
        super().__init__(nominal, free)
        from mechanism.kinematics.linkage import compute_tables
        from mechanism.machine.machine import resolve_description
        from mechanism.machine.models import load_model

        roles = resolve_description(None)  # the shipped machine's roles; model_path swaps its MJCF
        self.tables = compute_tables(load_model(model_path), roles.shaft_joint, roles.zero_site)
        n = nominal.ratio
        mean_motor_side = self.tables.mean_inertia_kgm2 / n**2
        lumped = {p.name: p for p in self.parameters}
        self.parameters = (
            Parameter("inertia_correction_motor_side_kgm2", 0.0, -0.9 * mean_motor_side, 5e-4,
                      f"constant inertia added to the CAD model's (its mean is {mean_motor_side:.3g} kg m^2 motor side)",
                      scale=1e-5),
            lumped["viscous_motor_side_Nm_s_per_rad"],
            lumped["coulomb_arm_Nm"],
            lumped["electrical_time_constant_s"],
            Parameter("cad_inertia_variation_scale", 1.0, 0.0, 4.0,
                      "factor on the CAD's angle-dependent inertia (masses of moving parts the export may get wrong)", scale=1.0),
            Parameter("cad_gravity_scale", 1.0, 0.0, 4.0, "factor on the CAD's gravity torque", scale=1.0),
            *[p for p in self.parameters if p.name.startswith("motor_")],
        )

    def drive(self, values: dict[str, float], signals: Signals) -> Drive:
        n = signals.ratio
        cache = signals._cache
        if "multibody_tables" not in cache:
            angle = signals.drive_angle_rad
            cache["multibody_tables"] = (self.tables.mean_inertia_kgm2, self.tables.at("inertia_variation_kgm2", angle),
                                         0.5 * self.tables.at("dinertia_drad", angle),
                                         self.tables.at("gravity_torque_Nm", angle))
        mean, variation, half_dj, gravity = cache["multibody_tables"]
        drive = Drive.constant(signals, signals.voltage_V, 0.0, values["viscous_motor_side_Nm_s_per_rad"] * n**2,
                               values["coulomb_arm_Nm"])
        k = values["cad_inertia_variation_scale"]
        drive.inertia_kgm2 = mean + values["inertia_correction_motor_side_kgm2"] * n**2 + k * variation
        drive.quadratic_Nm_s2 = k * half_dj
        drive.tau_arm_Nm = values["cad_gravity_scale"] * gravity
        return drive
