"""The dynamic sewing machine: the converted MJCF plus motor, friction and loads.

The MJCF from the CAD export carries geometry, masses, joints, loop closures and belt/gear
couplings only. :class:`Machine` adds, through ``MjSpec``:

- the main motor as a native ``<dcmotor>`` on the ``motor`` joint (mechanism.physics.motor);
- friction per joint (mechanism.physics.friction), thesis values by default: viscous on the motor
  (cold 2.2e-5 / warm 1.0e-5 N m s/rad), Coulomb 0.18 N m on the arm shaft, static friction
  with a Tustin decay, and position-dependent levels over the arm revolution calibrated on the
  thesis's break-away torques and speed ripple (mechanism.sysid.calibration);
- loads (mechanism.physics.loads): fabric layers on the needle, belt tension, feeding;
- a sensor for the motor torque (the current); the needle height comes from the exact kinematics.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace

import mujoco
import numpy as np

from mechanism import native
from mechanism.errors import UserError
from mechanism.physics.friction import FrictionLaw, FrictionSet, python_friction
from mechanism.kinematics.pose import joint_dof, solve_pose
from mechanism.physics.loads import BELT_TENSION_COULOMB_NM, FEEDING_COULOMB_NM, FabricLoad, python_needle_load
from mechanism.machine.models import load_spec
from mechanism.physics.motor import DCMotor
from mechanism.data.reference import thesis

ARM, MOTOR, LOWER = "arm_shaft", "motor", "lower_shaft"
NEEDLE_SITE = "needle_tip"
NEEDLE_PLATE = "needle_plate"

# Position-dependent friction on the arm shaft, calibrated on the shipped model against the
# thesis by ``python -m mechanism.sysid.calibration`` (see its docstring; rerun it after changing the
# machine's moving parts). Running level: Fc (1 + a cos(θ - φ)), fitted to the speed ripple of
# figs. 11-14; break-away level: Fs (1 + a_s cos(θ - φ)), so that with the CAD gravity it
# spans the measured 0.2384 (needle going down) to 0.2771 N m (just after bottom dead centre).
RUNNING_POSITION_AMPLITUDE = 0.174
POSITION_PHASE_RAD = float(np.deg2rad(177.7))
STATIC_FRICTION_ARM_NM = 0.2564
STATIC_POSITION_AMPLITUDE = 0.0719
STRIBECK_VELOCITY_ARM_RAD_S = 0.5  # Tustin decay speed; the thesis gives none, typical of lubricated bearings


def thesis_friction(warm: bool = False) -> dict[str, FrictionLaw]:
    """Friction laws per joint from the thesis's identified values."""
    ident = thesis()["identified_parameters"]
    return {
        MOTOR: FrictionLaw(viscous=ident["viscous_warm_Nm_s_per_rad" if warm else "viscous_cold_Nm_s_per_rad"]),
        ARM: FrictionLaw(
            coulomb=ident["kinetic_friction_arm_Nm"],
            static=STATIC_FRICTION_ARM_NM,
            stribeck="tustin",
            stribeck_velocity=STRIBECK_VELOCITY_ARM_RAD_S,
            position_amplitude=RUNNING_POSITION_AMPLITUDE,
            static_position_amplitude=STATIC_POSITION_AMPLITUDE,
            position_phase_rad=POSITION_PHASE_RAD,
        ),
    }


@dataclass
class MachineConfig:
    warm: bool = False
    layers: int = 0
    needle: bool = True
    feeding: bool = False
    belt_tension: str = "normal"
    motor: DCMotor = field(default_factory=DCMotor.from_thesis)
    friction: dict[str, FrictionLaw] | None = None  # replaces the thesis laws joint by joint
    fabric: FabricLoad | None = None  # overrides the default fabric model for ``layers``
    timestep_s: float = 0.0005

    def __post_init__(self):
        if self.belt_tension not in BELT_TENSION_COULOMB_NM:
            raise UserError(f"belt tension must be one of {', '.join(BELT_TENSION_COULOMB_NM)}, got {self.belt_tension!r}")
        if not 1e-5 <= self.timestep_s <= 2e-3:
            raise UserError("time step must be between 0.01 ms and 2 ms")

    def friction_laws(self) -> dict[str, FrictionLaw]:
        laws = thesis_friction(self.warm)
        laws.update(self.friction or {})
        extra_arm = BELT_TENSION_COULOMB_NM[self.belt_tension]
        if extra_arm:
            laws[ARM] = laws.get(ARM, FrictionLaw()).add(coulomb=extra_arm)
        if self.feeding:
            laws[LOWER] = laws.get(LOWER, FrictionLaw()).add(coulomb=FEEDING_COULOMB_NM)
        return laws

    def fabric_load(self) -> FabricLoad:
        if not self.needle:
            return FabricLoad(layers=0)
        return self.fabric or FabricLoad(layers=self.layers)


_CALLBACK_INSTALLED = False


def install_callbacks() -> bool:
    """Install the machine's passive-force callback once per process (C if possible).
    Returns True for the compiled version. Models without our numerics are untouched."""
    global _CALLBACK_INSTALLED
    library = native.load("machine")
    if not _CALLBACK_INSTALLED:
        if library is not None:
            mujoco.set_mjcb_passive(library.mechanism_passive)
        else:
            def passive(model, data):
                python_friction(model, data)
                python_needle_load(model, data)

            mujoco.set_mjcb_passive(passive)
        _CALLBACK_INSTALLED = True
    return library is not None


def needle_plate_top_z(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """World height [m] of the needle plate's top surface (max z of its geometry)."""
    tops = []
    for gid in range(model.ngeom):
        if model.geom(gid).name.split("_")[:2] != ["needle", "plate"]:
            continue
        mesh = model.geom_dataid[gid]
        if model.geom_type[gid] != mujoco.mjtGeom.mjGEOM_MESH or mesh < 0:
            continue
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        vertices = model.mesh_vert[start : start + count]
        world = vertices @ data.geom_xmat[gid].reshape(3, 3).T + data.geom_xpos[gid]
        tops.append(world[:, 2].max())
    if not tops:
        raise UserError(f"the model has no '{NEEDLE_PLATE}' part: cannot place fabric on the needle plate")
    return float(max(tops))


class Machine:
    """A compiled, ready-to-simulate machine. ``machine.model`` / ``machine.data`` are plain
    MuJoCo objects; everything added is visible in ``mujoco.mj_saveLastXML``."""

    def __init__(self, model_path: str | os.PathLike | None = None, config: MachineConfig | None = None, extend=None):
        """``extend(spec)``, if given, adds to the spec before it is compiled (probe sites
        and sensors, mechanism.inspection.probes); it must not add joints or actuators."""
        self.config = config or MachineConfig()
        spec = load_spec(model_path)
        self.model_path = model_path
        spec.option.timestep = self.config.timestep_s  # before friction: its stiffness follows it
        for equality in spec.equalities:  # loops and belts as stiff as the step allows (2 steps)
            equality.solref = [2 * self.config.timestep_s, 1.0]
        joints = {j.name for j in spec.joints}
        for required in (MOTOR, ARM):
            if required not in joints:
                raise UserError(f"the model has no '{required}' joint; a sewing machine model needs '{MOTOR}' and '{ARM}'")
        self.motor = self.config.motor
        self.motor.add_to_spec(spec, joint=MOTOR)
        self.friction = FrictionSet(self.config.friction_laws())
        self.friction.apply_to_spec(spec)
        self.fabric = self.config.fabric_load()
        self.fabric.apply_to_spec(spec)
        self.has_needle_site = any(s.name == NEEDLE_SITE for s in spec.sites)
        spec.add_sensor(name="motor_torque", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname="motor")
        if extend is not None:
            extend(spec)
        try:
            self.model = spec.compile()
        except Exception as exc:
            raise UserError(f"cannot build the machine model: {' '.join(str(exc).split())}") from None
        self.spec = spec
        self.data = mujoco.MjData(self.model)
        self.friction.bind(self.model)
        self.native = install_callbacks()
        self.arm_qpos, self.arm_dof = joint_dof(self.model, ARM)
        self.motor_qpos, self.motor_dof = joint_dof(self.model, MOTOR)
        self.plate_top_z = None
        self._needle_table = None
        if self.has_needle_site:
            self.reset(0.0)
            try:
                self.plate_top_z = needle_plate_top_z(self.model, self.data)
            except UserError:
                if self.fabric.layers:
                    raise
        if self.fabric.layers:
            if not self.has_needle_site:
                raise UserError(f"fabric layers need a '{NEEDLE_SITE}' site on the needle")
            self.fabric.bind(self.model, NEEDLE_SITE, self.plate_top_z)

    def reset(self, arm_angle_rad: float = 0.0) -> mujoco.MjData:
        """Machine at rest with the arm shaft at ``arm_angle_rad`` (0 = needle TDC)."""
        mujoco.mj_resetData(self.model, self.data)
        solve_pose(self.model, self.data, {ARM: float(arm_angle_rad)})
        self.data.qvel[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        return self.data

    def needle_z_mm(self, needle_world_z) -> np.ndarray:
        """Needle point height above the needle-plate top [mm] from world z [m]."""
        reference = self.plate_top_z if self.plate_top_z is not None else 0.0
        return (np.asarray(needle_world_z) - reference) * 1e3

    def needle_z_mm_at(self, arm_angle_rad) -> np.ndarray:
        """Needle point height above the needle plate [mm] of the rigid mechanism at arm
        angles, from the exact pose solution (tabulated once per machine). Dynamic site
        positions differ from it by the loop closures' compliance (about 0.1 mm at 1000 rpm
        with a 0.5 ms step), which this reading leaves out."""
        from mechanism.kinematics.linkage import compute_tables, periodic_interp

        if self._needle_table is None:
            self._needle_table = compute_tables(self.model, ARM, NEEDLE_SITE, n=720).tool_z_m  # 0.5 deg: < 2e-4 mm
        return self.needle_z_mm(periodic_interp(self._needle_table, arm_angle_rad))

    def with_config(self, **changes) -> "Machine":
        return Machine(self.model_path, replace(self.config, **changes))
