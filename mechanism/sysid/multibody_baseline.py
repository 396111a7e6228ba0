"""The ``multibody`` baseline: the lumped drive with the CAD model's linkage inside.

The reduced 1-DOF form of the multibody machine (:func:`mechanism.dynamics.reduced.linkage_tables`)
gives, over one arm revolution, the effective inertia J(theta) (motor through the belt
included), its derivative and the gravity torque G(theta), all on the arm side. This
baseline keeps their shapes and fits what the CAD cannot know: a constant inertia
correction (parts missing from the export, the rotor's real inertia), factors on the
angle-dependent inertia and on gravity (masses the export gets wrong; 1 = as exported),
viscous and Coulomb friction, the winding lag. The motor is the same datasheet DC motor as
in the lumped baseline. The two factors are priors with the CAD's stated tolerances
(:mod:`mechanism.tolerances`): the fit is regularised towards 1 and bounded away from zero,
so a recording the CAD does not describe shows as a poor fit, not as masses that vanish.
The tables are the machine's of ``--machine`` (its model and joints), never the shipped one's
unless no machine is given. A ``linkage_dynamics`` finding on top of it means the linkage's
*shape* differs from the CAD's.
"""

from __future__ import annotations


from mechanism.dynamics.lumped import Drive, Signals
from mechanism.sysid.lumped_baseline import Baseline, LumpedBaseline
from mechanism.sysid.parameters import Parameter
from mechanism.tolerances import (
    CAD_GRAVITY_TOLERANCE,
    CAD_INERTIA_TOLERANCE,
    MOTOR_DATASHEET_TOLERANCE,
    PRIOR_BOUND_SIGMAS,
)


class MultibodyBaseline(LumpedBaseline):
    name: Baseline = "multibody"
    linear = (
        "inertia_correction_motor_side_kgm2",
        "viscous_motor_side_Nm_s_per_rad",
        "coulomb_arm_Nm",
    )
    meaning = "the CAD model's reduced 1-DOF dynamics (angle-dependent inertia and gravity) with viscous and Coulomb friction"
    varies_inertia = True

    def __init__(
        self,
        nominal,
        free: tuple[str, ...] = (),
        model_path=None,
        *,
        offset: bool = False,
        notes: tuple[str, ...] = (),
    ):
        super().__init__(nominal, free, offset=offset, notes=notes)
        self.gravity = True
        self.tables = linkage_tables(nominal, model_path)
        n = nominal.ratio
        mean_motor_side = self.tables.mean_inertia_kgm2 / n**2
        lumped = {p.name: p for p in self.parameters}
        g, j = CAD_GRAVITY_TOLERANCE, CAD_INERTIA_TOLERANCE
        self.parameters = (
            Parameter(
                "inertia_correction_motor_side_kgm2",
                0.0,
                -0.9 * mean_motor_side,
                max(5e-4, 10 * mean_motor_side),
                f"constant inertia added to the CAD model's (its mean is {mean_motor_side:.3g} kg m^2 motor side)",
                scale=max(1e-5, 0.1 * mean_motor_side),
            ),
            lumped["viscous_motor_side_Nm_s_per_rad"],
            lumped["coulomb_arm_Nm"],
            lumped["electrical_time_constant_s"],
            Parameter(
                "cad_inertia_variation_scale",
                1.0,
                max(1.0 - PRIOR_BOUND_SIGMAS * j, 0.1),
                1.0 + PRIOR_BOUND_SIGMAS * j,
                f"factor on the CAD's angle-dependent inertia (prior 1 +/- {j:.0%}: masses of moving parts the export "
                f"may get wrong)",
                scale=1.0,
                prior_sd=j,
            ),
            Parameter(
                "cad_gravity_scale",
                1.0,
                max(1.0 - PRIOR_BOUND_SIGMAS * g, 0.1),
                1.0 + PRIOR_BOUND_SIGMAS * g,
                f"factor on the CAD's gravity torque (prior 1 +/- {g:.0%})",
                scale=1.0,
                prior_sd=g,
            ),
            *[
                p
                for p in self.parameters
                if p.name.startswith("motor_") or p.name == "offset_torque_arm_Nm"
            ],
        )
        kt = "motor_torque_constant_Nm_per_A"
        if getattr(nominal, "travel_rad", None) is not None and kt not in {
            p.name for p in self.parameters
        }:
            # A shaft that rocks spends its time accelerating, stopping and holding against
            # gravity: the CAD's inertia and gravity fix the torque scale, so the motor's torque
            # per volt is seen (on a turning machine's steady speeds only its ratio to friction
            # is). It is fitted within the datasheet's tolerance (3 sigma; as a soft prior it held
            # the fit off the optimum on the bench's rocker recordings).
            value, bound = (
                nominal.motor.torque_constant_Nm_per_A,
                PRIOR_BOUND_SIGMAS * MOTOR_DATASHEET_TOLERANCE,
            )
            self.parameters += (
                Parameter(
                    kt,
                    value,
                    value * (1.0 - bound),
                    value * (1.0 + bound),
                    f"motor Kt (datasheet {value:g}, within +/- {bound:.0%}: the shaft rocks, so the "
                    f"CAD's inertia and gravity fix the torque per volt)",
                    log=True,
                ),
            )
            self.notes = (
                *self.notes,
                "the motor's torque constant is fitted within the datasheet's tolerance: the shaft "
                "rocks, so the CAD's inertia and gravity fix the torque scale",
            )

    def drive(self, values: dict[str, float], signals: Signals) -> Drive:
        n = signals.ratio
        cache = signals._cache
        if "multibody_tables" not in cache:
            angle = signals.drive_angle_rad
            cache["multibody_tables"] = (
                self.tables.mean_inertia_kgm2,
                self.tables.at("inertia_variation_kgm2", angle),
                0.5 * self.tables.at("dinertia_drad", angle),
                self.tables.at("gravity_torque_Nm", angle),
            )
        mean, variation, half_dj, gravity = cache["multibody_tables"]
        drive = Drive.constant(
            signals,
            signals.voltage_V,
            0.0,
            values["viscous_motor_side_Nm_s_per_rad"] * n**2,
            values["coulomb_arm_Nm"],
        )
        k = values["cad_inertia_variation_scale"]
        drive.inertia_kgm2 = (
            mean + values["inertia_correction_motor_side_kgm2"] * n**2 + k * variation
        )
        drive.quadratic_Nm_s2 = k * half_dj
        drive.tau_arm_Nm = values["cad_gravity_scale"] * gravity + values.get(
            "offset_torque_arm_Nm", 0.0
        )
        return drive


def linkage_tables(nominal, model_path=None):
    """The linkage tables of the described machine: its own (``nominal.linkage``, from
    ``--machine``), or those of the MJCF at ``model_path`` with the machine's roles (the
    shaft joint and zero site of ``--machine``; without it, the shipped machine's)."""
    from mechanism.errors import UserError
    from mechanism.kinematics.linkage import compute_tables
    from mechanism.machine.models import load_model

    if model_path is None and nominal.linkage is not None:
        return nominal.linkage
    if nominal.roles is not None:
        shaft, zero = nominal.roles
    else:
        from mechanism.machine.machine import resolve_description

        roles = resolve_description(None)
        shaft, zero = roles.shaft_joint, roles.zero_site
    model = load_model(model_path or getattr(nominal, "model_path", None))
    joints = [model.joint(i).name for i in range(model.njnt)]
    if shaft not in joints:
        raise UserError(
            f"the model {model_path or 'of the machine'} has no joint {shaft!r} (its joints: "
            f"{', '.join(joints) or 'none'}); give the machine's description with --machine, which names "
            f"its shaft joint and zero site"
        )
    sites = [model.site(i).name for i in range(model.nsite)]
    return compute_tables(model, shaft, zero if zero in sites else None)
