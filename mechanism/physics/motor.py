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

from dataclasses import dataclass

import mujoco
import numpy as np

from mechanism.errors import UserError
from mechanism.physics._numeric import numeric_block

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

    def __post_init__(self):
        # NaN passes every comparison: check finite ranges, each number by name
        from mechanism.files.limits import check_number

        check_number(self.resistance_ohm, "motor resistance_ohm", 1e-6, 1e3, "ohm")
        check_number(
            self.torque_constant_Nm_A, "motor torque_constant_Nm_per_A", 1e-6, 100, "N m/A"
        )
        check_number(self.back_emf_V_s_rad, "motor back_emf_V_s_per_rad", 1e-6, 100, "V s/rad")
        check_number(self.inductance_H, "motor inductance_H", 0, 1, "H")
        check_number(self.cogging_Nm, "motor cogging_Nm", 0, 10, "N m")
        check_number(self.cogging_phase_rad, "motor cogging_phase_rad", -1e3, 1e3, "rad")
        poles = check_number(self.cogging_poles, "motor cogging periods per turn", 1, 1000)
        if isinstance(self.cogging_poles, bool) or not poles.is_integer():
            raise UserError(
                f"motor cogging periods per turn must be an integer from 1 to 1000, got {self.cogging_poles!r}"
            )
        if self.thermal is not None:
            check_number(
                self.thermal.resistance_K_W,
                "motor thermal resistance_K_W",
                0,
                1e4,
                "K/W",
                low_open=True,
            )
            check_number(
                self.thermal.time_constant_s,
                "motor thermal time_constant_s",
                0,
                1e6,
                "s",
                low_open=True,
            )
            check_number(self.thermal.tempcoef_per_K, "motor thermal tempcoef_per_K", 0, 1, "1/K")
            check_number(self.thermal.ambient_C, "motor thermal ambient_C", -50, 100, "degC")

    @property
    def _ratio(self) -> float:
        return self.back_emf_V_s_rad / self.torque_constant_Nm_A

    def add_to_spec(self, spec: mujoco.MjSpec, joint: str, name: str) -> None:
        """Add the ``<dcmotor>`` (ctrl = terminal voltage in V) driving ``joint``."""
        ratio = self._ratio
        thermal = [0.0] * 6
        if self.thermal:
            t = self.thermal
            thermal = [
                t.resistance_K_W * ratio,
                0.0,
                t.time_constant_s,
                t.tempcoef_per_K,
                t.ambient_C,
                t.ambient_C,
            ]
        actuator = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_dcmotor(
            motorconst=[self.back_emf_V_s_rad, self.back_emf_V_s_rad],
            resistance=self.resistance_ohm * ratio,
            inductance=[self.inductance_H * ratio, 0.0],
            cogging=[
                self.cogging_Nm,
                float(self.cogging_poles) if self.cogging_Nm else 0.0,
                self.cogging_phase_rad,
            ],
            thermal=thermal,
        )

    def stall_torque_Nm(self, default_voltage_V: float) -> float:
        return self.torque_constant_Nm_A * default_voltage_V / self.resistance_ohm

    def no_load_speed_rad_s(self, default_voltage_V: float) -> float | None:
        return default_voltage_V / self.back_emf_V_s_rad

    def torque(self, voltage, motor_velocity, temperature_rise_K=0.0):
        """Quasi-static electromagnetic torque (no inductance): thesis eq. 5."""
        resistance = self.resistance_ohm * (
            1 + (self.thermal.tempcoef_per_K if self.thermal else 0) * temperature_rise_K
        )
        return (
            self.torque_constant_Nm_A
            / resistance
            * (np.asarray(voltage) - self.back_emf_V_s_rad * np.asarray(motor_velocity))
        )


def motor_current(
    model: mujoco.MjModel, data: mujoco.MjData, motor: DCMotor, actuator: str
) -> float:
    """The real armature current [A] (see the module note on the Kt != Ke mapping)."""
    aid = model.actuator(actuator).id
    torque = data.actuator_force[aid]
    if motor.cogging_Nm:
        qadr = model.jnt_qposadr[model.actuator_trnid[aid, 0]]
        torque -= motor.cogging_Nm * np.sin(
            motor.cogging_poles * data.qpos[qadr] + motor.cogging_phase_rad
        )
    return float(torque / motor.torque_constant_Nm_A)


SUPPLY_NUMERIC = "mechanism_supply"


@dataclass(frozen=True)
class SupplyLimit:
    """The supply cannot put more than ``supply_V - series_ohm * I`` on the motor terminals
    (a PWM switch's on-resistance and the wiring at full duty): the armature current is the
    smaller of the commanded one and ``(supply_V - Ke w) / (R + series_ohm)``. A commanded
    voltage within the supply's reach under load is unaffected. Quasi-static in the current
    (the winding's inductance is not part of the limit)."""

    supply_V: float
    series_ohm: float

    def __post_init__(self):
        from mechanism.files.limits import check_number

        check_number(self.supply_V, "supply voltage", 0, 1e3, "V", low_open=True)
        check_number(self.series_ohm, "supply series resistance", 0, 1e3, "ohm")

    def current(self, motor: DCMotor, voltage, motor_velocity) -> np.ndarray:
        """Armature current [A] (numpy twin of native/machine.c and native/reduced.c)."""
        emf = motor.back_emf_V_s_rad * np.asarray(motor_velocity, dtype=float)
        commanded = (np.asarray(voltage, dtype=float) - emf) / motor.resistance_ohm
        high = (self.supply_V - emf) / (motor.resistance_ohm + self.series_ohm)
        low = (-self.supply_V - emf) / (motor.resistance_ohm + self.series_ohm)
        current = np.where((commanded > high) & (commanded > 0), high, commanded)
        return np.where((current < low) & (current < 0), low, current)

    def apply_to_spec(self, spec: mujoco.MjSpec) -> None:
        spec.add_numeric(name=SUPPLY_NUMERIC, data=np.zeros(8))

    def bind(self, model: mujoco.MjModel, motor: DCMotor, actuator: int, dof: int) -> None:
        model.numeric(SUPPLY_NUMERIC).data[:] = [
            1.0,
            float(actuator),
            float(dof),
            self.supply_V,
            self.series_ohm,
            motor.resistance_ohm,
            motor.torque_constant_Nm_A,
            motor.back_emf_V_s_rad,
        ]


def python_supply_limit(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """The supply-limit part of native/machine.c in Python (fallback without a compiler)."""
    p = numeric_block(model, SUPPLY_NUMERIC)
    if p is None:
        return
    act, dof = int(p[1]), int(p[2])
    vs, rs, r, kt, ke = p[3:8]
    motor = DCMotor(resistance_ohm=r, torque_constant_Nm_A=kt, back_emf_V_s_rad=ke)
    commanded = (data.ctrl[act] - ke * data.qvel[dof]) / r
    limited = float(SupplyLimit(vs, rs).current(motor, data.ctrl[act], data.qvel[dof]))
    data.qfrc_passive[dof] += kt * (limited - commanded)


SERVO_NUMERIC = "mechanism_servo"
SERVO_FIELDS = 9  # per servo: actuator, dof, qpos address, voltage limit, kp, kd, R, Kt, Ke


@dataclass(frozen=True)
class ServoDrive:
    """A DC motor behind a position loop (a hobby or smart servo): the driver puts

        V = clip(kp (goal - q) - kd q', -duty_limit supply_V, +duty_limit supply_V)

    on the motor, whose torque is Kt/R (V - Ke q') (quasi-static current). ``ctrl`` is the goal
    angle [rad] in the joint's own coordinate. MuJoCo's actuator carries the unsaturated law
    (gain Kt kp/R on the goal, bias -Kt kp/R q - Kt (kd + Ke)/R q', so the loop's damping is
    integrated implicitly); the passive callback takes back what the voltage limit removes:
    Kt/R (V - V_unsaturated)."""

    motor: DCMotor
    supply_V: float
    kp_V_rad: float
    kd_V_s_rad: float = 0.0
    duty_limit: float = 1.0

    @property
    def limit_V(self) -> float:
        return self.duty_limit * self.supply_V

    @property
    def torque_constant_Nm_A(self) -> float:
        return self.motor.torque_constant_Nm_A

    def add_to_spec(self, spec: mujoco.MjSpec, joint: str, name: str) -> None:
        m = self.motor
        gain = m.torque_constant_Nm_A * self.kp_V_rad / m.resistance_ohm
        damping = m.torque_constant_Nm_A * (self.kd_V_s_rad + m.back_emf_V_s_rad) / m.resistance_ohm
        actuator = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        actuator.gainprm = [gain] + [0.0] * 9
        actuator.biasprm = [0.0, -gain, -damping] + [0.0] * 7

    def voltage(self, goal, position, velocity) -> np.ndarray:
        wanted = self.kp_V_rad * (
            np.asarray(goal) - np.asarray(position)
        ) - self.kd_V_s_rad * np.asarray(velocity)
        return np.clip(wanted, -self.limit_V, self.limit_V)

    def current(self, goal, position, velocity) -> np.ndarray:
        m = self.motor
        return (
            self.voltage(goal, position, velocity) - m.back_emf_V_s_rad * np.asarray(velocity)
        ) / m.resistance_ohm

    def stall_torque_Nm(self, default_voltage_V: float) -> float:
        return self.motor.torque_constant_Nm_A * self.limit_V / self.motor.resistance_ohm

    def no_load_speed_rad_s(self, default_voltage_V: float) -> float | None:
        return self.limit_V / self.motor.back_emf_V_s_rad

    def fields(self, actuator: int, dof: int, qadr: int) -> list[float]:
        m = self.motor
        return [
            float(actuator),
            float(dof),
            float(qadr),
            self.limit_V,
            self.kp_V_rad,
            self.kd_V_s_rad,
            m.resistance_ohm,
            m.torque_constant_Nm_A,
            m.back_emf_V_s_rad,
        ]


@dataclass(frozen=True)
class CurrentDrive:
    """A current (torque) amplifier: torque Kt i with i the current command [A] (``ctrl``),
    clipped at ``max_current_A`` where one is given."""

    torque_constant_Nm_A: float
    max_current_A: float | None = None

    def add_to_spec(self, spec: mujoco.MjSpec, joint: str, name: str) -> None:
        actuator = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        actuator.biastype = mujoco.mjtBias.mjBIAS_NONE
        actuator.gainprm = [self.torque_constant_Nm_A] + [0.0] * 9
        if self.max_current_A is not None:
            actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            actuator.ctrlrange = [-self.max_current_A, self.max_current_A]

    def current(self, command) -> np.ndarray:
        command = np.asarray(command, dtype=float)
        return (
            command
            if self.max_current_A is None
            else np.clip(command, -self.max_current_A, self.max_current_A)
        )

    def stall_torque_Nm(self, default_current_A: float) -> float:
        return self.torque_constant_Nm_A * (self.max_current_A or default_current_A)

    def no_load_speed_rad_s(self, default_voltage_V: float) -> float | None:
        return None  # a current drive has no back-EMF limit on its speed


def apply_servos_to_spec(spec: mujoco.MjSpec, count: int) -> None:
    spec.add_numeric(name=SERVO_NUMERIC, data=np.zeros(2 + SERVO_FIELDS * count))


def bind_servos(model: mujoco.MjModel, blocks: list[list[float]]) -> None:
    model.numeric(SERVO_NUMERIC).data[:] = [1.0, float(len(blocks))] + [
        v for block in blocks for v in block
    ]


def python_servo_limit(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """The servo voltage limit of native/machine.c in Python (fallback without a compiler)."""
    p = numeric_block(model, SERVO_NUMERIC)
    if p is None:
        return
    for k in range(int(p[1])):
        act, dof, qadr, limit, kp, kd, r, kt, _ = p[
            2 + SERVO_FIELDS * k : 2 + SERVO_FIELDS * (k + 1)
        ]
        wanted = kp * (data.ctrl[int(act)] - data.qpos[int(qadr)]) - kd * data.qvel[int(dof)]
        data.qfrc_passive[int(dof)] += kt / r * (min(max(wanted, -limit), limit) - wanted)
