"""The lumped baseline as a fittable model: the drive of :mod:`mechanism.dynamics.lumped`
with typed parameters (starting values and bounds from the described drive)."""

from __future__ import annotations

from typing import Callable, Literal, get_args

import numpy as np

from mechanism.dynamics.lumped import Drive, DriveNominal, MotorConstants, Signals, lagged_voltage
from mechanism.sysid.parameters import Parameter
from mechanism.tolerances import (
    CAD_GRAVITY_TOLERANCE,
    CAD_MEAN_INERTIA_TOLERANCE,
    PRIOR_BOUND_SIGMAS,
)


MOTOR_PARAMETER_NAMES = {
    "R": "resistance_ohm",
    "Kt": "torque_constant_Nm_per_A",
    "Ke": "back_emf_V_s_per_rad",
}


def fitted_motor(described: MotorConstants, values: dict[str, float]) -> MotorConstants:
    """The motor constants a model's ``values`` give: the described ones, with those fitted."""
    changes = {
        key: values[f"motor_{key}"]
        for key in MOTOR_PARAMETER_NAMES.values()
        if f"motor_{key}" in values
    }
    return MotorConstants(**{**described.__dict__, **changes}) if changes else described


def motor_parameters(motor: MotorConstants, free: tuple[str, ...] = ()) -> list[Parameter]:
    """The motor constants named in ``free`` as fittable parameters (datasheet nominal, +-50 %)."""
    out = []
    for short in free:
        key = MOTOR_PARAMETER_NAMES[short]
        value = getattr(motor, key)
        out.append(
            Parameter(
                f"motor_{key}",
                value,
                0.5 * value,
                1.5 * value,
                f"motor {short} (datasheet {value:g})",
                log=True,
            )
        )
    return out


Baseline = Literal["lumped", "multibody"]
"""The baseline model identification and diagnosis fit: this lumped drive, or the machine's
reduced multibody model (:class:`~mechanism.sysid.multibody_baseline.MultibodyBaseline`)."""
BASELINES: tuple[Baseline, ...] = get_args(Baseline)


class LumpedBaseline:
    """The thesis's lumped model without ripple: constant inertia, viscous and Coulomb
    friction, DC motor through the belt (ratio from the nominal drive). Parameters in the
    thesis's conventions (inertia and viscous motor side, Coulomb on the described shaft,
    keys kept from the sewing machine's ``arm``); starting values are the description's,
    bounds a wide factor around them.

    One addition to eq. 15-16: the winding's electrical time constant L/R. The thesis
    neglects it (L dI/dt is small against the mechanical time constant), but at a voltage
    step the arm accelerates at about 1000 rad/s^2, so a 1 ms current lag is a 1 rad/s
    velocity error right after every step, larger than most effects the diagnosis looks
    for. It also absorbs when a logged voltage sample takes effect (a half-sample timing
    convention is a 0.5 ms lag)."""

    name: Baseline = "lumped"
    linear: tuple[str, ...] = (
        "inertia_motor_side_kgm2",
        "viscous_motor_side_Nm_s_per_rad",
        "coulomb_arm_Nm",
    )
    meaning = "constant inertia, viscous and Coulomb friction, DC motor (datasheet constants, winding lag L/R) through the belt"
    # the same inertia at every sample (an elastic belt's split is exact on any part)
    varies_inertia = False

    # bounds as factors of the description's values: wide enough for a machine 14x lighter or
    # 18x heavier than described, and friction from none to an order of magnitude more
    INERTIA_RANGE = (0.072, 18.0)
    VISCOUS_UPPER = 200 / 11
    COULOMB_UPPER = 100 / 9

    def __init__(
        self,
        nominal: DriveNominal,
        free: tuple[str, ...] = (),
        *,
        offset: bool = False,
        gravity: bool = False,
        notes: tuple[str, ...] = (),
    ):
        """``offset``: a constant torque on the shaft (a positioning axis's cable or spring, an
        unbalance) is fitted; it needs a shaft that turns both ways (one way only, it is the
        Coulomb level). ``gravity``: the model's gravity torque G(theta) acts on the shaft,
        scaled by a factor with the CAD's stated tolerance as its prior (never free to vanish).
        ``notes``: why the terms were chosen, for the JSON."""
        self.nominal = nominal
        self.offset, self.gravity = offset, gravity
        self.notes = tuple(notes)
        j, d, fc = (
            nominal.inertia_motor_side_kgm2,
            nominal.viscous_motor_side,
            nominal.torque_scale_Nm,
        )
        lo, hi = self.INERTIA_RANGE
        # the inertia is the model's: a prior, not a free factor
        described = nominal.linkage is not None
        self.parameters = (
            Parameter(
                "inertia_motor_side_kgm2",
                j,
                lo * j,
                hi * j,
                f"total inertia seen by the motor (described {j:.3g})",
                log=True,
                prior_sd=CAD_MEAN_INERTIA_TOLERANCE if described else 0.0,
            ),
            Parameter(
                "viscous_motor_side_Nm_s_per_rad",
                d,
                0.0,
                self.VISCOUS_UPPER * d,
                f"viscous friction on the motor side (described {d:.3g})",
                scale=10 / 11 * d,
            ),
            Parameter(
                "coulomb_arm_Nm",
                fc,
                0.0,
                self.COULOMB_UPPER * fc,
                f"kinetic (Coulomb) friction on the described shaft (described {fc:.3g})",
                scale=10 / 9 * fc,
            ),
            Parameter(
                "electrical_time_constant_s",
                5e-4,
                1e-5,
                0.03,
                "winding inductance over resistance, L/R (neglected in the thesis)",
                log=True,
            ),
            *motor_parameters(nominal.motor, free),
        )
        if offset:
            self.parameters += (
                Parameter(
                    "offset_torque_arm_Nm",
                    0.0,
                    -self.COULOMB_UPPER * fc,
                    self.COULOMB_UPPER * fc,
                    "constant torque on the described shaft, resisting forward motion (a cable, a "
                    "spring preload, an unbalance, a current sensor's offset)",
                    scale=fc,
                ),
            )
            self.linear = (*self.linear, "offset_torque_arm_Nm")
        if gravity:
            sd = CAD_GRAVITY_TOLERANCE
            self.parameters += (
                Parameter(
                    "gravity_scale",
                    1.0,
                    max(1.0 - PRIOR_BOUND_SIGMAS * sd, 0.1),
                    1.0 + PRIOR_BOUND_SIGMAS * sd,
                    f"factor on the model's gravity torque G(theta) (prior 1 +/- {sd:.0%}: the CAD's "
                    f"masses and centres of mass)",
                    scale=1.0,
                    prior_sd=sd,
                ),
            )
        self.free = tuple(free)

    @property
    def terms(self) -> dict:
        """Which terms this baseline carries and why (for the JSON)."""
        return {
            "constant_offset_torque": self.offset,
            "model_gravity_torque": self.gravity,
            "why": list(self.notes),
        }

    def shaft_torque(self, values: dict[str, float], signals: Signals):
        """The offset and the model's gravity torque at the measured angle (resisting; arm side), or None."""
        torque = None
        if self.gravity:
            # one table per model: baselines of two models may share the signals
            linkage = self.nominal.linkage
            if linkage is None:  # baseline_terms asks for gravity only where the tables are
                raise ValueError(
                    "a gravity torque needs the machine model's linkage tables (nominal.linkage)"
                )
            # the entry holds the linkage itself: while it is cached its id cannot be reused by
            # another model's linkage (an id alone outlives a collected object)
            held, table = signals.memo(
                "model_gravity_Nm",
                id(linkage),
                lambda: (linkage, linkage.at("gravity_torque_Nm", signals.drive_angle_rad)),
            )
            if held is not linkage:
                table = linkage.at("gravity_torque_Nm", signals.drive_angle_rad)
            torque = values["gravity_scale"] * table
        if self.offset:
            torque = values["offset_torque_arm_Nm"] + (
                torque if torque is not None else np.zeros(len(signals))
            )
        return torque

    def motor(self, values: dict[str, float]) -> MotorConstants:
        return fitted_motor(self.nominal.motor, values)

    def drive(self, values: dict[str, float], signals: Signals) -> Drive:
        n = signals.ratio
        drive = Drive.constant(
            signals,
            signals.voltage_V,
            values["inertia_motor_side_kgm2"] * n**2,
            values["viscous_motor_side_Nm_s_per_rad"] * n**2,
            values["coulomb_arm_Nm"],
        )
        torque = self.shaft_torque(values, signals)
        if torque is not None:
            drive.tau_arm_Nm = torque  # a fresh array: effects add to it in place
        return drive

    def finish(
        self,
        values: dict[str, float],
        signals: Signals,
        drive: Drive,
        lagged: Callable[[float], np.ndarray] | None = None,
    ) -> None:
        """After the effects: the winding lag acts on what drives the current, the voltage the
        motor finally sees (``lagged(tau)``: the applied voltage behind a lag ``tau``; default the
        logged voltage's) and the back-emf (L di/dt = V - R i - Ke w: the current lags both).
        The back-emf's lag is taken on the measured speed, as a torque: the kernel's own
        back-emf damping acts on the simulated speed unlagged, and the difference, Ke (w_lag - w)
        in torque, is what the winding holds back (it matters where the mechanical time
        constant is not much longer than L/R: a light, fast rocker)."""
        tau = values["electrical_time_constant_s"]
        drive.voltage_V = (lagged or signals.lagged)(tau)
        if tau > 0.02 * signals.dt:
            # a filter over the past: on the whole recording, read at these samples
            lag = signals.lag_filtered(
                "lagged_speed",
                tau,
                tau,
                lambda whole: whole.velocity_rad_s,
                lambda w: lagged_voltage(w, tau, signals.dt) - w,
            )
            drive.tau_motor_Nm = drive.tau_motor_Nm + self.motor(values).emf_damping_arm * lag
