"""The motor: a stepper's data (:class:`StepperParams`) and the shipped machine's PM25S-048."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from mechanism.errors import UserError


@dataclass(frozen=True)
class StepperParams:
    """Motor, driver and load of one stepper (SI units). See :func:`pm25s048` for the
    values and where each comes from."""

    step_angle_deg: float
    pole_pairs: int
    holding_torque_Nm: float  # two phases on at the rated current, detent excluded
    detent_torque_Nm: float  # Tdm, amplitude of the unpowered cogging torque
    rated_current_A: float  # chopper set (peak) current per phase
    resistance_ohm: float  # per phase
    inductance_H: float  # per phase
    supply_V: float  # chopper supply
    chopper_hz: float  # chopper oscillator frequency
    rotor_inertia_kg_m2: float
    damping_Nm_s_rad: float  # c, viscous, thesis eq. 21
    load_inertia_kg_m2: float = 0.0  # reflected to the motor shaft
    load_torque_Nm: float = 0.0  # Tl of eq. 19 as a Coulomb friction load (joint frictionloss)
    decay_margin: float = 0.05  # current overshoot (x rated) above which the chopper decays fast

    def __post_init__(self):
        steps = 360.0 / self.step_angle_deg
        if not math.isclose(steps, 4 * self.pole_pairs):
            raise UserError(
                f"a two-phase motor with {self.pole_pairs} pole pairs has {4 * self.pole_pairs} steps/rev, "
                f"not {steps:g} ({self.step_angle_deg:g} degrees per step)"
            )
        for name in (
            "holding_torque_Nm",
            "rated_current_A",
            "resistance_ohm",
            "inductance_H",
            "supply_V",
            "chopper_hz",
            "rotor_inertia_kg_m2",
        ):
            if not getattr(self, name) > 0:
                raise UserError(
                    f"stepper parameter {name} must be positive, got {getattr(self, name)}"
                )
        for name in (
            "detent_torque_Nm",
            "damping_Nm_s_rad",
            "load_inertia_kg_m2",
            "load_torque_Nm",
            "decay_margin",
        ):
            if not getattr(self, name) >= 0:
                raise UserError(
                    f"stepper parameter {name} must not be negative, got {getattr(self, name)}"
                )

    def replace(self, **changes) -> "StepperParams":
        return dataclasses.replace(self, **changes)

    @property
    def step_rad(self) -> float:
        return math.radians(self.step_angle_deg)

    @property
    def inertia_kg_m2(self) -> float:
        return self.rotor_inertia_kg_m2 + self.load_inertia_kg_m2

    @property
    def flux_linkage_Vs(self) -> float:
        """psi_m such that two phases at the rated current give the holding torque:
        |T| = p psi_m sqrt(2) I."""
        return self.holding_torque_Nm / (math.sqrt(2) * self.pole_pairs * self.rated_current_A)

    @property
    def physical_kt_Nm_A(self) -> float:
        """The physical model's Kt: its standstill torque Kt Vs / R equals the holding torque
        (the thesis had no value; this ties both models to the same data-sheet number)."""
        return self.holding_torque_Nm * self.resistance_ohm / self.supply_V

    @property
    def physical_kw_V_s_rad(self) -> float:
        """The physical model's K_omega = Kt: eq. 23 times i is then a power balance
        (Vs i = R i^2 + K_omega w i, the last term being the mechanical power Kt i w)."""
        return self.physical_kt_Nm_A


def pm25s048(**overrides) -> StepperParams:
    """The PM25S-048 of the Sapphire 870 on a 24 V chopper drive: the shipped machine's
    ``[stepper]`` (``assets/machines/sapphire870.toml``; a test keeps the
    thesis's numbers there equal to the reference file's).

    ================  ============  =========================================================
    parameter         value         source
    ================  ============  =========================================================
    step angle        7.5 deg       thesis (data sheet)
    pole pairs p      12            thesis eq. 17 (48 steps/rev = 4 p)
    holding torque    25 mN m       typical 25 mm PM can-stack motor, two phases on (assumed)
    detent torque     1.25 mN m     5 % of holding (assumed)
    rated current     0.5 A         typical chopper winding of a 25 mm PM motor (assumed)
    resistance        10 ohm        idem, a 5 V winding (assumed)
    inductance        12 mH         L/R = 1.2 ms, typical PM motor (assumed)
    flux linkage      2.95 mV s     derived: holding / (sqrt 2 p I)  (the thesis estimates it
                                    from the open-circuit voltage, eq. 18)
    supply            24 V          assumed (the thesis's bench supply, appendix E)
    chopper           20 kHz        typical fixed-frequency chopper IC (assumed)
    rotor inertia     0.5 g cm^2    ~3.5 g magnet ring, 10 mm OD x 9 mm (assumed; the thesis
                                    computed it in Pro/E but gives no number)
    damping c         3e-5 N m s    about 14 % of critical (assumed; thesis: estimated,
                                    never verified)
    Kt (physical)     10.4 mN m/A   derived: Kt Vs / R = holding torque
    K_omega           = Kt          derived: power balance of eq. 23
    ================  ============  =========================================================
    """
    return described_stepper(None, **overrides)


# the description's [stepper] keys that are StepperParams fields (the rest: type, step rate)
PARAMETER_KEYS = (
    "step_angle_deg",
    "pole_pairs",
    "holding_torque_Nm",
    "detent_torque_Nm",
    "rated_current_A",
    "resistance_ohm",
    "inductance_H",
    "supply_V",
    "chopper_hz",
    "rotor_inertia_kg_m2",
    "damping_Nm_s_rad",
)


def described_section(machine, section: str) -> tuple[dict, str]:
    """A section of a machine's description (a Machine, a MachineDescription, a TOML path, a
    shipped machine's name, or None: the shipped default) and where it is, for messages."""
    from mechanism.machine.machine import resolve_description

    description = getattr(machine, "description", machine)
    description = resolve_description(description)
    return description.section(section), description.where(section)


def described_stepper(machine=None, **overrides) -> StepperParams:
    """The stepper of a described machine (its ``[stepper]`` section; default: the shipped
    machine, see :func:`pm25s048`), with ``overrides`` (e.g. a load) applied."""
    stepper, where = described_section(machine, "stepper")
    if not stepper:
        raise UserError(f"{where}: the machine description has no stepper")
    values = {key: stepper[key] for key in PARAMETER_KEYS}
    values.update(overrides)
    return StepperParams(**values)


def described_step_rate(machine=None) -> float:
    """The described drive's usual slew rate [full steps/s] (``[stepper] step_rate_steps_s``)."""
    stepper, where = described_section(machine, "stepper")
    if "step_rate_steps_s" not in stepper:
        raise UserError(f"{where} step_rate_steps_s: not given; pass a step rate")
    return float(stepper["step_rate_steps_s"])
