"""Friction laws per joint, and where each one lives in the simulation.

| law                                  | where it is computed                                      |
| ------------------------------------ | --------------------------------------------------------- |
| viscous  d·ω                         | MuJoCo joint ``damping`` (native, implicit integration)     |
| static / break-away level Fs         | MuJoCo joint ``frictionloss``: the constraint solver holds |
|                                      | the joint exactly until the drive exceeds Fs (stiction)     |
| kinetic Coulomb Fc < Fs              | compiled ``mjcb_passive`` (native/machine.c): while        |
| Stribeck: Tustin, Hess-Soom          | sliding it adds back (Fs - F_kin(ω)) in the direction of   |
|                                      | motion, so net friction = F_kin(ω) = Fc + (Fs-Fc)·S(ω)      |
| position-dependent level             | the same callback scales F_kin by (1 + a cos(kθ-φ)) and Fs |
|   (1 + a·cos(k·θ - φ))               | by (1 + a_s cos(kθ-φ)) each step, editing the friction row |
|                                      | of the constraint set so break-away varies with θ too       |

The running (a) and break-away (a_s) amplitudes may differ: at rest only gravity loads the
bearings, while running adds the cyclic inertia and cam/spring loads of the mechanism.

S(ω) is ``exp(-(|ω|/ωs)^δ)`` (Tustin, thesis eq. 12) or ``1/(1+(ω/ωs)²)`` (Hess and Soom,
thesis eq. 13); plain Coulomb + viscous is thesis eq. 14. Torques are at the joint they
act on (N m for hinges, N for slides). ``kinetic_friction`` is the same law in numpy for
the reduced 1-DOF model and for machines without a C compiler.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import mujoco
import numpy as np

from mechanism.errors import UserError
from mechanism.physics._numeric import numeric_block

STRIBECK_LAWS = {"none": 0, "tustin": 1, "hess-soom": 2}
# Friction-loss constraint stiffness. MuJoCo's friction constraint is soft: a joint held by
# friction creeps at a speed ~ R f / b (regularisation R, reference damping b = 2/timeconst).
# With the defaults (impedance 0.9, 20 ms) the shipped machine creeps at ~0.7 rad/s under
# 80 % of its break-away torque; impedance 0.9999 (MuJoCo's maximum) and a time constant of
# two time steps (the stiffest MuJoCo accepts) bring that to ~2e-4 rad/s: it really sticks.
STICTION_SOLIMP = (0.9999, 0.99999, 0.001, 0.5, 2.0)
SMOOTH_SIGN_VELOCITY = 0.05  # rad/s: the kinetic add-back fades out below this speed
NUMERIC_NAME = "mechanism_friction"
FIELDS = 12


@dataclass(frozen=True)
class FrictionLaw:
    """Friction on one joint. ``static=None`` means no stiction excess (Fs = Fc)."""

    coulomb: float = 0.0
    static: float | None = None
    viscous: float = 0.0
    stribeck: str = "none"
    stribeck_velocity: float = 0.0
    tustin_exponent: float = 1.0
    position_amplitude: float = 0.0
    static_position_amplitude: float | None = None  # break-away variation; None: same as running
    position_phase_rad: float = 0.0
    position_harmonic: float = 1.0
    position_joint: str | None = None  # whose angle sets the position dependence (default: own)

    def __post_init__(self):
        if self.stribeck not in STRIBECK_LAWS:
            raise UserError(
                f"unknown Stribeck law {self.stribeck!r}; choose one of {', '.join(STRIBECK_LAWS)}"
            )
        if min(self.coulomb, self.viscous, self.stribeck_velocity) < 0 or (self.static or 0) < 0:
            raise UserError(
                "friction levels, viscous coefficient and Stribeck velocity must be non-negative"
            )
        if self.static is not None and self.static < self.coulomb:
            raise UserError(
                f"static friction {self.static} is below the kinetic level {self.coulomb}"
            )
        if not 0 <= self.position_amplitude < 1 or not 0 <= self.static_amplitude < 1:
            raise UserError("position-dependent friction amplitudes must be in [0, 1)")

    @property
    def static_level(self) -> float:
        return self.coulomb if self.static is None else self.static

    @property
    def static_amplitude(self) -> float:
        return (
            self.position_amplitude
            if self.static_position_amplitude is None
            else self.static_position_amplitude
        )

    def position_scale(self, angle, amplitude: float | None = None) -> np.ndarray | float:
        """Scale of the sliding friction level (or, with ``amplitude``, of another level) at ``angle``."""
        amplitude = self.position_amplitude if amplitude is None else amplitude
        if not amplitude:
            return 1.0
        return 1.0 + amplitude * np.cos(
            self.position_harmonic * np.asarray(angle) - self.position_phase_rad
        )

    def stribeck_shape(self, velocity) -> np.ndarray:
        x = np.abs(np.asarray(velocity, dtype=float))
        if self.stribeck == "none" or self.stribeck_velocity <= 0:
            return np.zeros_like(x)
        x = x / self.stribeck_velocity
        if self.stribeck == "tustin":
            return np.exp(-(x**self.tustin_exponent))
        return 1.0 / (1.0 + x * x)

    def sliding_level(self, velocity) -> np.ndarray:
        """Magnitude of the sliding friction at the nominal position (no viscous part)."""
        return self.coulomb + (self.static_level - self.coulomb) * self.stribeck_shape(velocity)

    def static_at(self, angle=0.0):
        """Break-away level at ``angle`` of the position joint."""
        return self.static_level * self.position_scale(angle, self.static_amplitude)

    def scaled(self, factor: float) -> "FrictionLaw":
        """The same law with every level (Coulomb, static, viscous) multiplied by ``factor``."""
        return replace(
            self,
            coulomb=self.coulomb * factor,
            static=None if self.static is None else self.static * factor,
            viscous=self.viscous * factor,
        )

    def add(self, coulomb: float = 0.0, viscous: float = 0.0) -> "FrictionLaw":
        """The same law with extra Coulomb (also raising the static level) and viscous friction."""
        return replace(
            self,
            coulomb=self.coulomb + coulomb,
            static=None if self.static is None else self.static + coulomb,
            viscous=self.viscous + viscous,
        )


@dataclass
class FrictionSet:
    """Friction laws by joint name, as written into one model."""

    laws: Mapping[str, FrictionLaw] = field(default_factory=dict)

    def apply_to_spec(self, spec: mujoco.MjSpec) -> None:
        """Native parts (damping, frictionloss, stiction impedance) plus a placeholder for
        the callback's parameters; :meth:`bind` fills the addresses after compiling."""
        joints = {j.name: j for j in spec.joints}
        timeconst = 2 * spec.option.timestep
        for name, law in self.laws.items():
            if name not in joints:
                from mechanism.errors import close_matches

                raise UserError(
                    f"friction on unknown joint {name!r}; close matches: {close_matches(name, joints)}"
                )
            joint = joints[name]
            joint.damping = [law.viscous, 0.0, 0.0]
            joint.frictionloss = law.static_level
            joint.solimp_friction = list(STICTION_SOLIMP)
            joint.solref_friction = [timeconst, 1.0]
        if self._needs_callback():
            spec.add_numeric(name=NUMERIC_NAME, data=np.zeros(2 + FIELDS * len(self.laws)))

    def _needs_callback(self) -> bool:
        return any(
            law.static_level != law.coulomb or law.position_amplitude or law.static_amplitude
            for law in self.laws.values()
        )

    def bind(self, model: mujoco.MjModel) -> None:
        """Write the callback's parameter block (dof and angle addresses) into the model."""
        if not self._needs_callback():
            return
        block = [1.0, float(len(self.laws))]
        for name, law in self.laws.items():
            joint = model.joint(name)
            angle_joint = model.joint(law.position_joint or name)
            block += [
                float(joint.dofadr[0]),
                float(angle_joint.qposadr[0]),
                law.coulomb,
                law.static_level,
                law.stribeck_velocity,
                float(STRIBECK_LAWS[law.stribeck]),
                law.tustin_exponent,
                law.position_amplitude,
                law.position_phase_rad,
                law.position_harmonic,
                SMOOTH_SIGN_VELOCITY,
                law.static_amplitude,
            ]
        model.numeric(NUMERIC_NAME).data[:] = block


def python_friction(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """The friction part of native/machine.c in Python (the fallback without a compiler)."""
    block = numeric_block(model, NUMERIC_NAME)
    if block is None:
        return
    count = int(block[1])
    rows = data.efc_type[: data.nefc]
    ids = data.efc_id[: data.nefc]
    for k in range(count):
        f = block[2 + k * FIELDS : 2 + (k + 1) * FIELDS]
        dof, qadr, coulomb, static, vs, law, delta, amp, phase, harmonic, eps, static_amp = f
        dof = int(dof)
        wave = np.cos(harmonic * data.qpos[int(qadr)] - phase)
        scale = 1.0 + amp * wave
        level = static * (1.0 + static_amp * wave)
        match = np.flatnonzero((rows == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF) & (ids == dof))
        if match.size:
            data.efc_frictionloss[match[0]] = level
            if data.nisland > 0:  # the island solver works on its own sorted copy
                data.iefc_frictionloss[data.map_efc2iefc[match[0]]] = level
        v = data.qvel[dof]
        shape = 0.0
        if law and vs > 0:
            x = abs(v) / vs
            shape = np.exp(-(x**delta)) if law == 1 else 1.0 / (1.0 + x * x)
        kinetic = (coulomb + (static - coulomb) * shape) * scale
        data.qfrc_passive[dof] += (level - kinetic) * v / np.sqrt(v * v + eps * eps)
