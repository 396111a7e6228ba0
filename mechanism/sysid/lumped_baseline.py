"""The lumped baseline as a fittable model: the drive of :mod:`mechanism.dynamics.lumped`
with typed parameters (starting values and bounds from the described drive)."""

from __future__ import annotations

from mechanism.dynamics.lumped import Drive, DriveNominal, MotorConstants, Signals, lagged_voltage
from mechanism.sysid.parameters import Parameter


MOTOR_PARAMETER_NAMES = {
    "R": "resistance_ohm",
    "Kt": "torque_constant_Nm_per_A",
    "Ke": "back_emf_V_s_per_rad",
}


def motor_parameters(motor: MotorConstants, free: tuple[str, ...] = ()) -> list[Parameter]:
    """The motor constants named in ``free`` as fittable parameters (datasheet nominal, +-50 %)."""
    out = []
    for short in free:
        key = MOTOR_PARAMETER_NAMES[short]
        value = getattr(motor, key)
        out.append(Parameter(f"motor_{key}", value, 0.5 * value, 1.5 * value, f"motor {short} (datasheet {value:g})", log=True))
    return out


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

    name = "lumped"
    linear = ("inertia_motor_side_kgm2", "viscous_motor_side_Nm_s_per_rad", "coulomb_arm_Nm")
    meaning = "constant inertia, viscous and Coulomb friction, DC motor (datasheet constants, winding lag L/R) through the belt"

    # bounds as factors of the description's values: wide enough for a machine 14x lighter or
    # 18x heavier than described, and friction from none to an order of magnitude more
    INERTIA_RANGE = (0.072, 18.0)
    VISCOUS_UPPER = 200 / 11
    COULOMB_UPPER = 100 / 9

    def __init__(self, nominal: DriveNominal, free: tuple[str, ...] = ()):
        self.nominal = nominal
        j, d, fc = nominal.inertia_motor_side_kgm2, nominal.viscous_motor_side, nominal.torque_scale_Nm
        lo, hi = self.INERTIA_RANGE
        self.parameters = (
            Parameter("inertia_motor_side_kgm2", j, lo * j, hi * j,
                      f"total inertia seen by the motor (described {j:.3g})", log=True),
            Parameter("viscous_motor_side_Nm_s_per_rad", d, 0.0, self.VISCOUS_UPPER * d,
                      f"viscous friction on the motor side (described {d:.3g})", scale=10 / 11 * d),
            Parameter("coulomb_arm_Nm", fc, 0.0, self.COULOMB_UPPER * fc,
                      f"kinetic (Coulomb) friction on the described shaft (described {fc:.3g})", scale=10 / 9 * fc),
            Parameter("electrical_time_constant_s", 5e-4, 1e-5, 0.03,
                      "winding inductance over resistance, L/R (neglected in the thesis)", log=True),
            *motor_parameters(nominal.motor, free),
        )
        self.free = tuple(free)

    def motor(self, values: dict[str, float]) -> MotorConstants:
        base = self.nominal.motor
        changes = {key: values[f"motor_{key}"] for key in MOTOR_PARAMETER_NAMES.values() if f"motor_{key}" in values}
        return MotorConstants(**{**base.__dict__, **changes}) if changes else base

    def drive(self, values: dict[str, float], signals: Signals) -> Drive:
        n = signals.ratio
        return Drive.constant(signals, signals.voltage_V, values["inertia_motor_side_kgm2"] * n**2,
                              values["viscous_motor_side_Nm_s_per_rad"] * n**2, values["coulomb_arm_Nm"])

    def finish(self, values: dict[str, float], signals: Signals, drive: Drive) -> None:
        """After the effects: the winding lag acts on the voltage the motor finally sees."""
        tau = values["electrical_time_constant_s"]
        if drive.voltage_V is signals.voltage_V:  # unmodified: remember it per time constant
            drive.voltage_V = signals.memo("lagged", tau, lambda: lagged_voltage(drive.voltage_V, tau, signals.dt))
        else:
            drive.voltage_V = lagged_voltage(drive.voltage_V, tau, signals.dt)
