"""Stepper motors of the Sapphire 870 (PM25S-048) as MuJoCo actuators.

Two models of the same motor, both plain MuJoCo actuators on a hinge (or any single-output
transmission: the actuator length is the rotor angle), driven by compiled callbacks
(``mechanism/native/stepper.c``; a slower Python version of the same callbacks is used
where no C compiler exists). The mechanics (inertia, viscous damping as joint damping,
integration, anything else in the model) stay in MuJoCo.

``circuit``
    Thesis eq. 16-17 (the SimPowerSystems model): two phases with resistance R and
    inductance L, back-EMF ``e_a = -p psi_m sin(p th) w``, ``e_b = -p psi_m sin(p th - pi/2) w``,
    torque ``T = -p psi_m (i_a sin(p th) + i_b sin(p th - pi/2)) - Tdm sin(4 p th)``, fed by a
    fixed-frequency peak-current chopper on a supply voltage. The phase currents and the
    chopper switch states are the actuator's activation (``actdim=4``). The chopper's
    voltage limit (against L di/dt and the back-EMF) is what makes this model lose steps at
    high step rates.
``physical``
    Thesis eq. 19-26 (Righettini et al.): an equivalent spring
    ``T = Kt i sin(pi / (2 alpha_p) (alpha_0 - alpha_m))`` with the current
    ``i = (Vs - Kw |w|) / R`` (L di/dt neglected, as in the thesis) and the damping ``c w``.

Conventions: ``p`` is the number of pole pairs (12 for 48 steps/rev, so
``pi / (2 alpha_p) = p``); one electrical period is 4 full steps. The actuator's control is
the commanded shaft angle [rad]; the driver inside the actuator rounds it to the drive
mode's resolution and sets the phase current references (full step: both phases on;
half step; microstepping with sine/cosine currents). Step counts and rates are in full
steps (7.5 degrees) whatever the mode.

Deviation from the thesis text: eq. 17's detent term is written ``Tdm sin(2 p th)``, a
period of two full steps, which would make every other full-step position detent-unstable.
A two-phase motor's detent torque repeats every full step; we use ``Tdm sin(4 p th)``
(stable at the one-phase-on positions), as Simscape Electrical's stepper block does.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import functools
import math
import time as _time
import warnings
from dataclasses import dataclass, field

import numpy as np

from mechanism.errors import UserError
from mechanism.data.reference import thesis
from mechanism.steppers.step_profiles import StepProfile

# Layout of actuator_user, mirrored in mechanism/native/stepper.c.
MARKER = 870048.0
KIND_CODES = {"circuit": 1, "physical": 2}
(
    USER_MARKER, USER_KIND, USER_POLE_PAIRS, USER_DIVISIONS, USER_SINE, USER_CURRENT,
    USER_RESISTANCE, USER_INDUCTANCE, USER_FLUX, USER_DETENT, USER_SUPPLY, USER_CHOP_HZ,
    USER_DECAY_MARGIN, USER_KT, USER_KW, USER_SIZE,
) = range(16)
CIRCUIT_ACTDIM = 4  # i_a, i_b, chopper_a, chopper_b
MAX_STEPS = 2_500_000  # one run's states stay under ~200 MB
KINDS = tuple(KIND_CODES)


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
        for name in ("holding_torque_Nm", "rated_current_A", "resistance_ohm", "inductance_H", "supply_V",
                     "chopper_hz", "rotor_inertia_kg_m2"):
            if not getattr(self, name) > 0:
                raise UserError(f"stepper parameter {name} must be positive, got {getattr(self, name)}")
        for name in ("detent_torque_Nm", "damping_Nm_s_rad", "load_inertia_kg_m2", "load_torque_Nm", "decay_margin"):
            if not getattr(self, name) >= 0:
                raise UserError(f"stepper parameter {name} must not be negative, got {getattr(self, name)}")

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
    """The PM25S-048 of the Sapphire 870 on a 24 V chopper drive.

    ================  ============  =========================================================
    parameter         value         source
    ================  ============  =========================================================
    step angle        7.5 deg       thesis (data sheet), reference file
    pole pairs p      12            thesis eq. 17, reference file (48 steps/rev = 4 p)
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
    stepper = thesis()["stepper_motors"]
    values = dict(
        step_angle_deg=float(stepper["step_angle_deg"]),
        pole_pairs=int(stepper["poles_in_torque_equation"]),
        holding_torque_Nm=0.025,
        detent_torque_Nm=0.00125,
        rated_current_A=0.5,
        resistance_ohm=10.0,
        inductance_H=0.012,
        supply_V=24.0,
        chopper_hz=20e3,
        rotor_inertia_kg_m2=0.5e-7,
        damping_Nm_s_rad=3e-5,
    )
    values.update(overrides)
    return StepperParams(**values)


# --------------------------------------------------------------------------- drive modes


@dataclass(frozen=True)
class DriveMode:
    """How the driver turns a commanded angle into phase currents."""

    name: str
    divisions: int  # positions per full step
    sine: bool  # sine/cosine currents (microstepping) or +-I/0 per phase

    @property
    def offset_rad_electrical(self) -> float:
        """Full stepping energises both phases: its positions sit half a step off the
        one-phase positions."""
        return 0.25 * math.pi if (not self.sine and self.divisions == 1) else 0.0


def drive_mode(name: str) -> DriveMode:
    """``full`` (both phases on), ``half`` or ``microN`` (N = 2..256 sine/cosine
    positions per full step, e.g. ``micro16``)."""
    text = str(name).strip().lower()
    if text == "full":
        return DriveMode("full", 1, False)
    if text == "half":
        return DriveMode("half", 2, False)
    if text.startswith("micro"):
        digits = text[len("micro"):]
        if digits.isdigit() and 2 <= int(digits) <= 256:
            return DriveMode(text, int(digits), True)
    raise UserError(f"unknown drive mode '{name}': use full, half or microN with N = 2..256 (e.g. micro16)")


def _drive(u, command_rad):
    """The driver, from an actuator's user array (see :func:`user_data`); arrays or
    scalars. Mirrors ``drive`` in stepper.c."""
    p, n, current = u[USER_POLE_PAIRS], u[USER_DIVISIONS], u[USER_CURRENT]
    sine = u[USER_SINE] != 0
    pitch = 0.5 * math.pi / n
    offset = 0.25 * math.pi if (not sine and n == 1) else 0.0
    phi = offset + np.floor((p * np.asarray(command_rad) - offset) / pitch + 0.5) * pitch
    c, s = np.cos(phi), np.sin(phi)
    if sine:
        return phi, current * c, current * s
    ref_a = np.where(np.abs(c) < 1e-6, 0.0, current * np.sign(c))
    ref_b = np.where(np.abs(s) < 1e-6, 0.0, current * np.sign(s))
    return phi, ref_a, ref_b


def _physical_current(u, omega):
    """Thesis eq. 25: i = (Vs - Kw |w|) / R, not below zero."""
    return np.maximum(0.0, (u[USER_SUPPLY] - u[USER_KW] * np.abs(omega)) / u[USER_RESISTANCE])


def _circuit_torque(u, theta, current_a, current_b):
    """Thesis eq. 17 with the detent term of period one full step."""
    p = u[USER_POLE_PAIRS]
    return (-p * u[USER_FLUX] * (current_a * np.sin(p * theta) + current_b * np.sin(p * theta - 0.5 * np.pi))
            - u[USER_DETENT] * np.sin(4 * p * theta))


def _physical_torque(u, theta, omega, command_rad):
    """Thesis eq. 21 with eq. 25's current; the spring scales with the driver's current
    vector (two phases on = 1, one phase or microstepping = 1/sqrt 2)."""
    phi, ref_a, ref_b = _drive(u, command_rad)
    magnitude = np.hypot(ref_a, ref_b) / (math.sqrt(2) * u[USER_CURRENT])
    return u[USER_KT] * _physical_current(u, omega) * magnitude * np.sin(phi - u[USER_POLE_PAIRS] * np.asarray(theta))


def drive(params: StepperParams, mode: DriveMode, command_rad):
    """The driver: rounded electrical angle and the phase current references [A] for a
    commanded shaft angle [rad] (arrays or scalars)."""
    return _drive(user_data(params, "circuit", mode), command_rad)


def physical_torque(params: StepperParams, mode: DriveMode, theta, omega, command_rad):
    """The physical model's torque [N m] at rotor angle and speed for a command."""
    return _physical_torque(user_data(params, "physical", mode), theta, omega, command_rad)


def rest_angle_rad(params: StepperParams, mode: DriveMode, steps=0.0):
    """The equilibrium shaft angle of a commanded position in full steps (unloaded)."""
    return mode.offset_rad_electrical / params.pole_pairs + np.asarray(steps) * params.step_rad


def linear_stiffness(params: StepperParams, kind: str, mode: DriveMode, steps: float = 0.0) -> float:
    """dT/dtheta [N m/rad] at rest at the commanded position (unloaded, standstill):
    the linearised model whose ringing frequency is sqrt(K / J)."""
    phi, ref_a, ref_b = drive(params, mode, rest_angle_rad(params, mode, steps))
    p = params.pole_pairs
    if kind == "circuit":
        current_vector = float(np.hypot(ref_a, ref_b))
        return p * p * params.flux_linkage_Vs * current_vector + 4 * p * params.detent_torque_Nm * math.cos(4 * float(phi))
    magnitude = float(np.hypot(ref_a, ref_b)) / (math.sqrt(2) * params.rated_current_A)
    return p * params.physical_kt_Nm_A * params.supply_V / params.resistance_ohm * magnitude


# --------------------------------------------------------------------------- MuJoCo model


def user_data(params: StepperParams, kind: str, mode: DriveMode) -> list[float]:
    if kind not in KIND_CODES:
        raise UserError(f"unknown stepper model '{kind}': use {' or '.join(KINDS)}")
    u = [0.0] * USER_SIZE
    u[USER_MARKER] = MARKER
    u[USER_KIND] = KIND_CODES[kind]
    u[USER_POLE_PAIRS] = params.pole_pairs
    u[USER_DIVISIONS] = mode.divisions
    u[USER_SINE] = 1.0 if mode.sine else 0.0
    u[USER_CURRENT] = params.rated_current_A
    u[USER_RESISTANCE] = params.resistance_ohm
    u[USER_INDUCTANCE] = params.inductance_H
    u[USER_FLUX] = params.flux_linkage_Vs
    u[USER_DETENT] = params.detent_torque_Nm
    u[USER_SUPPLY] = params.supply_V
    u[USER_CHOP_HZ] = params.chopper_hz
    u[USER_DECAY_MARGIN] = params.decay_margin
    u[USER_KT] = params.physical_kt_Nm_A
    u[USER_KW] = params.physical_kw_V_s_rad
    return u


def add_stepper(spec, joint: str, params: StepperParams, kind: str = "circuit", mode: str | DriveMode = "full",
                name: str = "stepper", gear: float = 1.0):
    """Add a stepper actuator on ``joint`` of an ``mujoco.MjSpec`` (``gear`` = motor turns
    per joint turn). The chopper's switch state needs the activation to advance by one
    Euler step (Euler and implicit integrators do that); an RK4 model is switched to Euler.
    The model's timestep must resolve the chopper (see :func:`default_timestep`)."""
    import mujoco

    mode = drive_mode(mode) if isinstance(mode, str) else mode
    spec.nuser_actuator = max(int(spec.nuser_actuator), USER_SIZE)
    if kind == "circuit" and spec.option.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        warnings.warn("the circuit stepper model needs an Euler or implicit integrator: switching the model from RK4 to Euler")
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    actuator = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.gear[0] = gear
    actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
    actuator.gainprm[0] = 0.0  # all of the torque is the user bias
    actuator.biastype = mujoco.mjtBias.mjBIAS_USER
    if kind == "circuit":
        actuator.dyntype = mujoco.mjtDyn.mjDYN_USER
        actuator.actdim = CIRCUIT_ACTDIM
    actuator.userdata = user_data(params, kind, mode)
    return actuator


def default_timestep(params: StepperParams, kind: str) -> float:
    """Ten steps per chopper period for the circuit model; the physical model has no
    electrical dynamics and needs only to resolve the rotor's ringing."""
    if kind == "circuit":
        return 0.1 / params.chopper_hz
    natural_hz = math.sqrt(linear_stiffness(params, "physical", drive_mode("full")) / params.inertia_kg_m2) / (2 * math.pi)
    return min(2e-5, 0.02 / natural_hz)


def build_model(params: StepperParams, kind: str = "circuit", mode: str | DriveMode = "full",
                timestep: float | None = None):
    """A bare motor: one rotor (inertia rotor + load) on a hinge ``rotor`` with the viscous
    damping c and the load torque as Coulomb friction, the actuator ``stepper`` and a
    torque sensor."""
    import mujoco

    if kind not in KIND_CODES:
        raise UserError(f"unknown stepper model '{kind}': use {' or '.join(KINDS)}")
    spec = mujoco.MjSpec()
    spec.modelname = f"stepper_{kind}"
    spec.option.timestep = timestep or default_timestep(params, kind)
    spec.option.gravity = [0, 0, 0]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    body = spec.worldbody.add_body(name="rotor")
    body.mass = 0.01
    body.inertia = [params.inertia_kg_m2] * 3
    body.explicitinertial = True
    joint = body.add_joint(name="rotor", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1],
                           damping=params.damping_Nm_s_rad, frictionloss=params.load_torque_Nm)
    # MuJoCo's default friction time constant (20 ms) is far slower than this rotor's dynamics
    joint.solref_friction = [4 * spec.option.timestep, 1.0]
    add_stepper(spec, "rotor", params, kind, mode)
    spec.add_sensor(name="torque", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC, objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
                    objname="stepper")
    return spec.compile()


# --------------------------------------------------------------------------- callbacks


@functools.lru_cache(maxsize=None)
def _native():
    from mechanism import native

    lib = native.load("stepper")
    if lib is not None:
        lib.stepper_set_next.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    return lib


def _address(callback) -> int | None:
    try:
        return ctypes.cast(callback, ctypes.c_void_p).value
    except (ctypes.ArgumentError, TypeError):
        return None


def install(backend: str = "auto") -> str:
    """Install the stepper callbacks; returns the backend installed: ``native`` (the C
    callbacks, kept installed; idempotent) or, with ``backend="python"`` or where no C
    compiler exists, ``python``. A callback of another part installed before ours as a C
    function pointer keeps serving its own actuators (ours forward to it).

    Python callbacks must not stay installed while models are compiled (MuJoCo's compiler
    calls them with a model the bindings cannot wrap): use :func:`python_callbacks` around
    a stepping loop instead of installing them for good."""
    import mujoco

    lib = _native() if backend in ("auto", "native") else None
    if backend == "native" and lib is None:
        raise UserError("the compiled stepper callbacks are not available (no C compiler)")
    if lib is None:
        return "python"
    ours_dyn, ours_bias = _address(lib.stepper_act_dyn), _address(lib.stepper_act_bias)
    current_dyn, current_bias = mujoco.get_mjcb_act_dyn(), mujoco.get_mjcb_act_bias()
    if _address(current_dyn) == ours_dyn and _address(current_bias) == ours_bias:
        return "native"
    if callable(current_dyn) and _address(current_dyn) is None or callable(current_bias) and _address(current_bias) is None:
        warnings.warn("replacing a Python MuJoCo actuator callback with the compiled stepper callbacks")
    next_dyn, next_bias = _address(current_dyn), _address(current_bias)
    lib.stepper_set_next(None if next_dyn == ours_dyn else next_dyn, None if next_bias == ours_bias else next_bias)
    mujoco.set_mjcb_act_dyn(lib.stepper_act_dyn)
    mujoco.set_mjcb_act_bias(lib.stepper_act_bias)
    return "native"


@contextlib.contextmanager
def python_callbacks():
    """The Python stepper callbacks installed for the duration of a stepping loop; the
    callbacks installed before are restored afterwards."""
    import mujoco

    previous = mujoco.get_mjcb_act_dyn(), mujoco.get_mjcb_act_bias()
    mujoco.set_mjcb_act_dyn(_py_act_dyn)
    mujoco.set_mjcb_act_bias(_py_act_bias)
    try:
        yield
    finally:
        mujoco.set_mjcb_act_dyn(previous[0])
        mujoco.set_mjcb_act_bias(previous[1])


def uninstall() -> None:
    import mujoco

    mujoco.set_mjcb_act_dyn(None)
    mujoco.set_mjcb_act_bias(None)


def _py_params(m, actuator_id: int):
    if m.nuser_actuator < USER_SIZE:
        return None
    u = m.actuator_user[actuator_id]
    return u if u[USER_MARKER] == MARKER else None


def _sgn(x: float) -> float:
    return math.copysign(1.0, x) if x else 0.0


def _py_chopper_phase(u, i, ref, emf, tick, h, on):
    supply, r, l = u[USER_SUPPLY], u[USER_RESISTANCE], u[USER_INDUCTANCE]
    margin = u[USER_DECAY_MARGIN] * u[USER_CURRENT]
    reached = ref != 0 and i * _sgn(ref) >= abs(ref)
    if ref == 0:
        on = 0.0
    elif tick:
        on = 0.0 if reached else 1.0
    elif on and reached:
        on = 0.0
    if on:
        return (supply * _sgn(ref) - r * i - emf) / l, on
    must_fall = i != 0 and (ref == 0 or i * ref < 0 or abs(i) > abs(ref) + margin)
    if not must_fall:
        return (0.0 if ref == 0 else (-r * i - emf) / l), on
    di = (-supply * _sgn(i) - r * i - emf) / l
    if (i + h * di) * i < 0:
        di = -i / h
    return di, on


def _py_act_dyn(m, d, actuator_id):
    u = _py_params(m, actuator_id)
    if u is None or u[USER_KIND] != KIND_CODES["circuit"] or m.actuator_actnum[actuator_id] != CIRCUIT_ACTDIM:
        return 0.0
    out, adr = m.actuator_outadr[actuator_id], m.actuator_actadr[actuator_id]
    theta, omega = d.actuator_length[out], d.actuator_velocity[out]
    p, psi, h, t, f = u[USER_POLE_PAIRS], u[USER_FLUX], m.opt.timestep, d.time, u[USER_CHOP_HZ]
    tick = math.floor(t * f + 1e-6) != math.floor((t - h) * f + 1e-6)
    _, ref_a, ref_b = (float(x) for x in _drive(u, d.ctrl[m.actuator_ctrladr[actuator_id]]))
    emf_a = -p * psi * math.sin(p * theta) * omega
    emf_b = -p * psi * math.sin(p * theta - 0.5 * math.pi) * omega
    act = d.act[adr:adr + CIRCUIT_ACTDIM].copy()
    on_a, on_b = float(act[2] > 0.5), float(act[3] > 0.5)
    di_a, on_a = _py_chopper_phase(u, act[0], ref_a, emf_a, tick, h, on_a)
    di_b, on_b = _py_chopper_phase(u, act[1], ref_b, emf_b, tick, h, on_b)
    d.act_dot[adr:adr + CIRCUIT_ACTDIM] = [di_a, di_b, (on_a - act[2]) / h, (on_b - act[3]) / h]
    return 0.0


def _py_act_bias(m, d, actuator_id):
    u = _py_params(m, actuator_id)
    if u is None:
        return 0.0
    out = m.actuator_outadr[actuator_id]
    theta, omega = d.actuator_length[out], d.actuator_velocity[out]
    if u[USER_KIND] == KIND_CODES["circuit"] and m.actuator_actnum[actuator_id] == CIRCUIT_ACTDIM:
        adr = m.actuator_actadr[actuator_id]
        return float(_circuit_torque(u, theta, d.act[adr], d.act[adr + 1]))
    if u[USER_KIND] == KIND_CODES["physical"]:
        return float(_physical_torque(u, theta, omega, d.ctrl[m.actuator_ctrladr[actuator_id]]))
    return 0.0


# --------------------------------------------------------------------------- simulation


@dataclass
class StepperRun:
    """One simulated sequence at the simulation's full time resolution. Angles are
    relative to the start (the rest position of step 0), unwrapped."""

    kind: str
    mode: DriveMode
    params: StepperParams
    profile: StepProfile
    time_s: np.ndarray
    command_deg: np.ndarray  # the driver's rounded command
    rotor_deg: np.ndarray
    speed_rad_s: np.ndarray
    current_a_A: np.ndarray
    current_b_A: np.ndarray
    torque_Nm: np.ndarray
    backend: str = "native"
    wall_s: float = 0.0
    summary: dict = field(default_factory=dict)

    @property
    def step_deg(self) -> float:
        return self.params.step_angle_deg

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return float(self.time_s[-1] + (self.time_s[1] - self.time_s[0])) / self.wall_s if self.wall_s else math.inf

    def columns(self, sample_period_s: float | None = None) -> dict[str, np.ndarray]:
        """The CSV columns, every ``sample_period_s`` (all steps when None)."""
        dt = self.time_s[1] - self.time_s[0]
        every = max(1, int(round(sample_period_s / dt))) if sample_period_s else 1
        pick = slice(None, None, every)
        return {
            "time_s": self.time_s[pick],
            "commanded_position_deg": self.command_deg[pick],
            "rotor_position_deg": self.rotor_deg[pick],
            "rotor_speed_rad_s": self.speed_rad_s[pick],
            "phase_a_current_A": self.current_a_A[pick],
            "phase_b_current_A": self.current_b_A[pick],
            "torque_Nm": self.torque_Nm[pick],
            "commanded_rate_steps_s": self.profile.rate_steps_s(self.time_s[pick]),
        }


def _state_slices(model):
    """Where time, qpos, qvel and act sit in a full-physics state vector."""
    import mujoco

    sizes, offset = {}, 0
    full = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    bit = 1
    while bit <= full:
        if full & bit:
            n = mujoco.mj_stateSize(model, bit)
            sizes[bit] = slice(offset, offset + n)
            offset += n
        bit <<= 1
    s = mujoco.mjtState
    return (sizes[int(s.mjSTATE_TIME)], sizes[int(s.mjSTATE_QPOS)], sizes[int(s.mjSTATE_QVEL)],
            sizes[int(s.mjSTATE_ACT)])


def initial_state(model, params: StepperParams, mode: DriveMode, kind: str):
    """The motor at rest at step 0, energised (currents at their references)."""
    import mujoco

    data = mujoco.MjData(model)
    start = float(rest_angle_rad(params, mode))
    data.qpos[0] = start
    if kind == "circuit":
        _, ref_a, ref_b = drive(params, mode, start)
        data.act[:2] = [float(ref_a), float(ref_b)]
    state = np.empty(mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    return data, state


def command_array(params: StepperParams, mode: DriveMode, profile: StepProfile, time_s: np.ndarray) -> np.ndarray:
    """The actuator's control (commanded shaft angle, rad) at each step."""
    return rest_angle_rad(params, mode, profile.position_steps(time_s))


def run_rollout(model, states0: np.ndarray, controls: np.ndarray, backend: str = "auto"):
    """Roll out ``controls`` (nbatch x nstep) from ``states0`` (nbatch x nstate); returns the
    states *before* each step and the sensor data of each step, aligned in time."""
    import mujoco

    installed = install(backend)
    nbatch, nstep = controls.shape
    data = mujoco.MjData(model)
    if installed == "native":
        from mujoco import rollout

        state, sensor = rollout.rollout(model, data, states0, controls[:, :, None])
    else:
        state = np.empty((nbatch, nstep, states0.shape[1]))
        sensor = np.empty((nbatch, nstep, model.nsensordata))
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        with python_callbacks():
            for b in range(nbatch):
                mujoco.mj_setState(model, data, states0[b], full)
                for k in range(nstep):
                    data.ctrl[0] = controls[b, k]
                    mujoco.mj_step(model, data)
                    mujoco.mj_getState(model, data, state[b, k], full)
                    sensor[b, k] = data.sensordata
    before = np.concatenate([states0[:, None, :], state[:, :-1, :]], axis=1)
    return before, sensor, installed


def simulate(profile: StepProfile, kind: str = "circuit", mode: str | DriveMode = "full",
             params: StepperParams | None = None, timestep: float | None = None, settle_s: float = 0.1,
             backend: str = "auto") -> StepperRun:
    """Run ``profile`` on the bare motor and analyse it (``run.summary``)."""
    params = params or pm25s048()
    mode = drive_mode(mode) if isinstance(mode, str) else mode
    model = build_model(params, kind, mode, timestep)
    h = model.opt.timestep
    nstep = int(math.ceil((profile.duration_s + settle_s) / h))
    if nstep > MAX_STEPS:
        raise UserError(f"{profile.name}: {profile.duration_s + settle_s:g} s is too long for one run of the {kind} model "
                        f"(at most {MAX_STEPS * h:g} s, {MAX_STEPS} steps of {h:g} s)")
    time_s = np.arange(nstep) * h
    controls = command_array(params, mode, profile, time_s)
    _, state0 = initial_state(model, params, mode, kind)
    started = _time.perf_counter()
    before, sensor, installed = run_rollout(model, state0[None], controls[None], backend)
    wall = _time.perf_counter() - started
    run = _make_run(model, params, kind, mode, profile, time_s, controls, before[0], sensor[0])
    run.backend, run.wall_s = installed, wall
    run.summary = analyse(run)
    return run


def _make_run(model, params, kind, mode, profile, time_s, controls, before, sensor) -> StepperRun:
    _, qpos, qvel, act = _state_slices(model)
    start = float(rest_angle_rad(params, mode))
    phi, _, _ = drive(params, mode, controls)
    rotor = before[:, qpos][:, 0]
    if kind == "circuit":
        currents = before[:, act][:, :2]
        current_a, current_b = currents[:, 0].copy(), currents[:, 1].copy()
    else:  # the physical model's one current (eq. 25), reported on the driver's phase pattern
        _, ref_a, ref_b = drive(params, mode, controls)
        scale = _physical_current(user_data(params, kind, mode), before[:, qvel][:, 0]) / params.rated_current_A
        current_a, current_b = ref_a * scale, ref_b * scale
    return StepperRun(
        kind=kind, mode=mode, params=params, profile=profile, time_s=time_s,
        command_deg=np.degrees(phi / params.pole_pairs - start),
        rotor_deg=np.degrees(rotor - start),
        speed_rad_s=before[:, qvel][:, 0].copy(),
        current_a_A=current_a, current_b_A=current_b,
        torque_Nm=sensor[:, 0].copy(),
    )


# --------------------------------------------------------------------------- analysis


def slip_events(run: StepperRun) -> list[tuple[float, int]]:
    """(time, full steps) each time the rotor slips a whole electrical period (4 full
    steps) against the field: negative = it fell behind the command. A slip is counted
    when the load angle passes 1.25 half-periods, so an oscillation at the edge does not
    chatter."""
    p = run.params.pole_pairs
    load = np.radians(run.command_deg - run.rotor_deg) * p  # electrical radians, + = rotor behind
    steps_per_period = 4
    events, centre, start = [], 0, 0
    while True:
        beyond = np.flatnonzero(np.abs(load[start:] - 2 * np.pi * centre) > 1.25 * np.pi)
        if beyond.size == 0:
            return events
        k = start + int(beyond[0])
        new_centre = int(np.round(load[k] / (2 * np.pi)))
        events.append((float(run.time_s[k]), -(new_centre - centre) * steps_per_period))
        centre, start = new_centre, k


def analyse(run: StepperRun, settle_window_s: float = 0.005, reversal_window_s: float = 0.05) -> dict:
    """Peak position, final error, lost steps (rotor more than half a step from the
    command after settling) with slip times, and at each reversal, within
    ``reversal_window_s`` either side: the overshoot (how far the rotor passes the
    commanded turning point), the peak speed error against the commanded speed and the
    peak speed (the spike of the thesis's figure 20)."""
    step = run.step_deg
    tail = run.time_s >= run.time_s[-1] - settle_window_s
    final_error = float(np.mean(run.rotor_deg[tail] - run.command_deg[tail]))
    lost = int(round(abs(final_error) / step)) if abs(final_error) > step / 2 else 0
    summary = {
        "model": run.kind,
        "mode": run.mode.name,
        "sequence": run.profile.name,
        "duration_s": float(run.time_s[-1]),
        "peak_command_deg": float(np.max(run.command_deg)),
        "peak_position_deg": float(np.max(run.rotor_deg)),
        "final_command_deg": float(np.mean(run.command_deg[tail])),
        "final_position_deg": float(np.mean(run.rotor_deg[tail])),
        "final_error_deg": final_error,
        "lost_steps": lost,
        "slips": slip_events(run),
    }
    reversals = []
    for t_rev in run.profile.reversal_times_s():
        before = run.profile.rate_steps_s(np.array([max(t_rev - 1e-6, 0.0)]))[0]
        direction = 1.0 if before > 0 else -1.0
        window = (run.time_s >= t_rev - reversal_window_s) & (run.time_s <= t_rev + reversal_window_s)
        turn = float(np.max(direction * run.command_deg[window]))
        overshoot = float(np.max(direction * run.rotor_deg[window]) - turn)
        commanded_speed = run.profile.rate_steps_s(run.time_s[window]) * run.params.step_rad
        speed_error = float(np.max(np.abs(run.speed_rad_s[window] - commanded_speed)))
        reversals.append({"time_s": t_rev, "overshoot_deg": overshoot, "peak_speed_error_rad_s": speed_error,
                          "peak_speed_rad_s": float(np.max(np.abs(run.speed_rad_s[window])))})
    summary["reversals"] = reversals
    return summary


def sweep_rates(rates, kind: str = "circuit", mode: str | DriveMode = "full", params: StepperParams | None = None,
                ramp_s: float = 0.1, hold_s: float = 0.05, settle_s: float = 0.05, backend: str = "auto",
                progress: bool = False) -> list[dict]:
    """Ramp up to each rate, hold, ramp down and settle; report the slips. The rate at
    which slips start is the pull-out rate (the ramps keep pull-in effects out)."""
    from mechanism.steppers.step_profiles import from_rates

    params = params or pm25s048()
    mode = drive_mode(mode) if isinstance(mode, str) else mode
    model = build_model(params, kind, mode)
    h = model.opt.timestep
    total = 2 * ramp_s + hold_s + settle_s
    time_s = np.arange(int(math.ceil(total / h))) * h
    _, state0 = initial_state(model, params, mode, kind)
    results = []
    iterator = rates
    if progress:
        from tqdm import tqdm

        iterator = tqdm(rates, desc=f"{kind} sweep", unit="rate", leave=False)
    for rate in iterator:
        rate = float(rate)
        profile = from_rates(f"ramp to {rate:g} steps/s", [0, ramp_s, ramp_s + hold_s, 2 * ramp_s + hold_s],
                             [0, rate, rate, 0])
        controls = command_array(params, mode, profile, time_s)
        before, sensor, installed = run_rollout(model, state0[None], controls[None], backend)
        run = _make_run(model, params, kind, mode, profile, time_s, controls, before[0], sensor[0])
        summary = analyse(run)
        results.append({"rate_steps_s": rate, "lost_steps": summary["lost_steps"], "slips": len(summary["slips"]),
                        "final_error_deg": summary["final_error_deg"]})
    return results


def pull_out_rate(kind: str = "circuit", mode: str | DriveMode = "full", params: StepperParams | None = None,
                  low: float = 250.0, high: float = 6000.0, resolution: float = 25.0, **kwargs) -> float | None:
    """The lowest step rate [steps/s] at which the motor loses steps on a ramped move,
    found by bisection between ``low`` (must hold) and ``high``; None if ``high`` holds."""
    def loses(rate):
        result = sweep_rates([rate], kind, mode, params, **kwargs)[0]
        return result["lost_steps"] > 0 or result["slips"] > 0

    if not loses(high):
        return None
    if loses(low):
        return low
    while high - low > resolution:
        middle = 0.5 * (low + high)
        if loses(middle):
            high = middle
        else:
            low = middle
    return high


def holding_torque(displacement_rad, kind: str = "circuit", mode: str | DriveMode = "full",
                   params: StepperParams | None = None, hold_s: float = 0.004, backend: str = "auto") -> np.ndarray:
    """Static torque [N m] with the rotor held at ``displacement_rad`` from the rest position
    of step 0, motor energised (the data sheet's torque-displacement curve). The rotor is
    held by giving it a huge inertia; the torque is averaged over the second half of
    ``hold_s`` (whole chopper periods), after the currents have settled."""
    params = params or pm25s048()
    mode = drive_mode(mode) if isinstance(mode, str) else mode
    displacement = np.atleast_1d(np.asarray(displacement_rad, dtype=float))
    held = params.replace(rotor_inertia_kg_m2=1e6, load_inertia_kg_m2=0.0)
    model = build_model(held, kind, mode, timestep=default_timestep(params, kind))
    h = model.opt.timestep
    nstep = int(round(hold_s / h))
    _, qpos, _, _ = _state_slices(model)
    _, state0 = initial_state(model, params, mode, kind)
    states = np.repeat(state0[None], displacement.size, axis=0)
    states[:, qpos.start] += displacement
    controls = np.full((displacement.size, nstep), float(rest_angle_rad(params, mode)))
    _, sensor, _ = run_rollout(model, states, controls, backend)
    return sensor[:, nstep // 2:, 0].mean(axis=1)


# --------------------------------------------------------------------------- plots


def plot_run(run: StepperRun, path) -> None:
    """Position, speed (the thesis's figures 19 and 20), phase currents and torque."""
    from mechanism.files.plotting import plt, save_figure

    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    t = run.time_s
    axes[0].plot(t, run.command_deg, "--", color="0.4", lw=1, label="commanded")
    axes[0].plot(t, run.rotor_deg, lw=1.2, label="rotor")
    axes[0].set_ylabel("position [deg]")
    axes[1].plot(t, run.profile.rate_steps_s(t) * run.params.step_rad, "--", color="0.4", lw=1, label="commanded")
    axes[1].plot(t, run.speed_rad_s, lw=0.8, label="rotor")
    axes[1].set_ylabel("speed [rad/s]")
    axes[2].plot(t, run.current_a_A, lw=0.6, label="phase A")
    axes[2].plot(t, run.current_b_A, lw=0.6, label="phase B")
    axes[2].set_ylabel("current [A]")
    axes[3].plot(t, run.torque_Nm * 1e3, lw=0.6)
    axes[3].set_ylabel("torque [mN m]")
    axes[3].set_xlabel("time [s]")
    for reversal in run.summary.get("reversals", []):
        for ax in axes[:2]:
            ax.axvline(reversal["time_s"], color="r", lw=0.6, alpha=0.5)
    for ax in axes[:3]:
        ax.legend(loc="best", fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    s = run.summary
    fig.suptitle(f"{run.profile.name}: {run.kind} model, {run.mode.name} step; lost steps {s['lost_steps']}, "
                 f"final error {s['final_error_deg']:.2f} deg", fontsize=10)
    save_figure(fig, path)


def plot_sweep(results: dict[str, list[dict]], path) -> None:
    """Lost steps against the step rate, one line per model."""
    from mechanism.files.plotting import plt, save_figure

    fig, ax = plt.subplots(figsize=(7, 4))
    for kind, rows in results.items():
        ax.plot([r["rate_steps_s"] for r in rows], [r["lost_steps"] for r in rows], "o-", label=kind)
    ax.set_xlabel("step rate [full steps/s]")
    ax.set_ylabel("lost steps after a ramped move")
    ax.grid(alpha=0.3)
    ax.legend()
    save_figure(fig, path)
