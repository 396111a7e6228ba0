"""Stepper motors (the Sapphire 870's PM25S-048) as MuJoCo actuators, and the needle zigzag check.

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

The code sits in private modules by concern (``_motor``: the motor's data; ``_drive``: drive
modes, torque laws and the callbacks' parameter array; ``_actuator``: the MuJoCo actuator and a
bare motor model; ``_callbacks``: the compiled callbacks and their Python twin;
``_simulation``: runs, sweeps, pull-out, static torque; ``_report``: a run, its analysis and
plots). Use the names below; :mod:`mechanism.steppers.step_profiles` (step sequences) and
:mod:`mechanism.steppers.zigzag` (the needle zigzag) are public modules of their own.
"""

from mechanism.steppers._actuator import add_stepper, build_model, default_timestep
from mechanism.steppers._callbacks import install, python_callbacks
from mechanism.steppers._drive import (
    KINDS,
    DriveMode,
    drive,
    drive_mode,
    linear_stiffness,
    physical_torque,
    rest_angle_rad,
    user_data,
)
from mechanism.steppers._motor import (
    StepperParams,
    described_step_rate,
    described_stepper,
    pm25s048,
)
from mechanism.steppers._report import StepperRun, analyse, plot_run, plot_sweep, slip_events
from mechanism.steppers._simulation import (
    MAX_STEPS,
    command_array,
    holding_torque,
    initial_state,
    pull_out_rate,
    run_rollout,
    simulate,
    sweep_rates,
)

__all__ = [
    # the motor
    "StepperParams",
    "pm25s048",
    "described_stepper",
    "described_step_rate",
    # the driver and the torque laws
    "KINDS",
    "DriveMode",
    "drive_mode",
    "drive",
    "physical_torque",
    "rest_angle_rad",
    "linear_stiffness",
    "user_data",
    # the MuJoCo actuator and its callbacks
    "add_stepper",
    "build_model",
    "default_timestep",
    "install",
    "python_callbacks",
    # runs
    "MAX_STEPS",
    "simulate",
    "initial_state",
    "command_array",
    "run_rollout",
    "sweep_rates",
    "pull_out_rate",
    "holding_torque",
    # what a run says
    "StepperRun",
    "analyse",
    "slip_events",
    "plot_run",
    "plot_sweep",
]
