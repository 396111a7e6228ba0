"""The main motor as MuJoCo 4's native ``<dcmotor>`` actuator (voltage input).

The datasheet (R, Kt, Ke) comes from the machine description. ``<dcmotor>`` has one motor
constant K = sqrt(Kt·Ke) and would compute torque K/R·(V - K·ω): with the Sapphire 870's
Kt = 0.017, Ke = 0.021 that is 11 % too strong and 10 % too weak in back-EMF, and the
thesis's Table 2 speeds come out 17 % fast. We keep Kt != Ke exactly by giving
``<dcmotor>`` motorconst = Ke and resistance R' = R·Ke/Kt:

    torque = Ke/R'·(V - Ke·ω) = Kt/R·(V - Ke·ω)          (exact thesis eq. 5)

The actuator's internal current is then i' = Kt/Ke·i, so the real current is recovered as
torque/Kt (reported by :func:`motor_current`). Inductance keeps the electrical time
constant (L' = L·Ke/Kt), and the thermal option keeps the heating (R_th' = R_th·Ke/Kt,
same time constant), so every optional feature stays physical.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from mechanism.errors import UserError

COPPER_TEMPCOEF_PER_K = 0.00393


@dataclass(frozen=True)
class Thermal:
    """Winding temperature model (resistance rises with temperature)."""

    resistance_K_W: float = 8.0  # winding to ambient; typical for a ~60 W brushed motor
    time_constant_s: float = 600.0
    tempcoef_per_K: float = COPPER_TEMPCOEF_PER_K
    ambient_C: float = 22.0


@dataclass(frozen=True)
class DCMotor:
    resistance_ohm: float
    torque_constant_Nm_A: float
    back_emf_V_s_rad: float
    inductance_H: float = 0.0
    cogging_Nm: float = 0.0
    cogging_poles: int = 12
    cogging_phase_rad: float = 0.0
    thermal: Thermal | None = None

    def with_options(self, **overrides) -> "DCMotor":
        return replace(self, **overrides)

    def __post_init__(self):
        if min(self.resistance_ohm, self.torque_constant_Nm_A, self.back_emf_V_s_rad) <= 0:
            raise UserError("motor resistance and constants must be positive")
        if self.inductance_H < 0 or self.cogging_Nm < 0:
            raise UserError("motor inductance and cogging amplitude must be non-negative")

    @property
    def _ratio(self) -> float:
        return self.back_emf_V_s_rad / self.torque_constant_Nm_A

    def add_to_spec(self, spec: mujoco.MjSpec, joint: str, name: str) -> None:
        """Add the ``<dcmotor>`` (ctrl = terminal voltage in V) driving ``joint``."""
        ratio = self._ratio
        thermal = [0.0] * 6
        if self.thermal:
            t = self.thermal
            thermal = [t.resistance_K_W * ratio, 0.0, t.time_constant_s, t.tempcoef_per_K, t.ambient_C, t.ambient_C]
        actuator = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_dcmotor(
            motorconst=[self.back_emf_V_s_rad, self.back_emf_V_s_rad],
            resistance=self.resistance_ohm * ratio,
            inductance=[self.inductance_H * ratio, 0.0],
            cogging=[self.cogging_Nm, float(self.cogging_poles) if self.cogging_Nm else 0.0, self.cogging_phase_rad],
            thermal=thermal,
        )

    def torque(self, voltage, motor_velocity, temperature_rise_K=0.0):
        """Quasi-static electromagnetic torque (no inductance): thesis eq. 5."""
        resistance = self.resistance_ohm * (1 + (self.thermal.tempcoef_per_K if self.thermal else 0) * temperature_rise_K)
        return self.torque_constant_Nm_A / resistance * (np.asarray(voltage) - self.back_emf_V_s_rad * np.asarray(motor_velocity))


def motor_current(model: mujoco.MjModel, data: mujoco.MjData, motor: DCMotor, actuator: str) -> float:
    """The real armature current [A] (see the module note on the Kt != Ke mapping)."""
    aid = model.actuator(actuator).id
    torque = data.actuator_force[aid]
    if motor.cogging_Nm:
        qadr = model.jnt_qposadr[model.actuator_trnid[aid, 0]]
        torque -= motor.cogging_Nm * np.sin(motor.cogging_poles * data.qpos[qadr] + motor.cogging_phase_rad)
    return float(torque / motor.torque_constant_Nm_A)
