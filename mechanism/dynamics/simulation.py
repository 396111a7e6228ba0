"""Simulate a machine under a motor voltage.

The voltage is known in advance (constant, profile or duty cycle), so a whole run is one
``mujoco.rollout`` call: MuJoCo steps the model in C with the compiled friction/load
callback and no Python per step. Outputs are sampled at ``sample_rate_hz`` (1 kHz like the
thesis's dSpace recordings); acceleration is the mean over each sample interval.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import mujoco.rollout
import numpy as np

from mechanism.errors import UserError
from mechanism.lazy import renamed
from mechanism.physics.inputs import VoltageProfile
from mechanism.machine.machine import TORQUE_SENSOR, Machine, MachineConfig, actuator_name
from mechanism.physics.motor import DCMotor, ServoDrive

MAX_DURATION_S = 3600.0


CHUNK_STEPS = 4000  # rollout calls of ~2 s simulated: a progress bar without per-step Python


def _rollout_in_chunks(model, data, control: np.ndarray, progress: bool, guard=None):
    """``mujoco.rollout`` over the whole control sequence, continued chunk by chunk from
    the last state so that a progress bar can follow long runs."""
    from tqdm import tqdm

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.zeros(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    nstep = len(control)
    states = np.empty((nstep, len(state)))
    sensors = np.empty((nstep, model.nsensordata))
    warmstart = data.qacc_warmstart.copy()
    with tqdm(
        total=nstep * model.opt.timestep,
        unit="s",
        disable=not progress or None,
        desc="simulating",
        bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s simulated",
    ) as bar:
        for start in range(0, nstep, CHUNK_STEPS):
            stop = min(nstep, start + CHUNK_STEPS)
            chunk_state, chunk_sensors = mujoco.rollout.rollout(
                model,
                data,
                state[None, :],
                control[None, start:stop],
                nstep=stop - start,
                initial_warmstart=warmstart[None, :],
            )
            states[start:stop], sensors[start:stop] = chunk_state[0], chunk_sensors[0]
            check_stable(
                model,
                data,
                states[start:stop],
                sensors[start:stop],
                start * model.opt.timestep,
                control[start:stop],
            )
            if guard is not None:
                guard(states[start:stop], start * model.opt.timestep)
            state = states[stop - 1]
            warmstart = data.qacc_warmstart.copy()
            bar.update((stop - start) * model.opt.timestep)
    return states, sensors


MUJOCO_MAX_VALUE = 1e10  # mjMAXVAL: larger controls and states count as diverged
_INSTABILITY_WARNINGS = ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS", "mjWARN_BADCTRL")
LIKELY_CAUSE = (
    "likely cause: a time step too large for the model's stiffness (try a smaller --timestep) or a "
    "parameter out of its physical range (inductance, friction, loads, voltage)"
)


def unstable(time_s: float, what: str) -> UserError:
    return UserError(
        f"the simulation became unstable at t = {time_s:.4f} s ({what}); {LIKELY_CAUSE}"
    )


def check_stable(
    model,
    data,
    states: np.ndarray,
    sensors: np.ndarray,
    start_s: float,
    control: np.ndarray | None = None,
) -> None:
    """UserError at the first sign of instability in a rollout chunk: MuJoCo's warning
    counters (it zeroes a bad control, or resets the state after a bad acceleration, and goes
    on), a time that stops increasing (that reset), any non-finite state or sensor value."""
    bad = ~np.isfinite(states).all(axis=1) | ~np.isfinite(sensors).all(axis=1)
    bad[1:] |= np.diff(states[:, 0]) <= 0
    if control is not None:
        bad |= ~(np.abs(control) < MUJOCO_MAX_VALUE).all(axis=1)
    first = int(np.argmax(bad)) if bad.any() else None
    when = start_s + (first or 0) * model.opt.timestep
    for name in (
        _INSTABILITY_WARNINGS if data is not None else ()
    ):  # a batch's threads share their data
        warning = getattr(mujoco.mjtWarning, name)
        if data.warning[warning].number:
            raise unstable(
                when, f"MuJoCo: {mujoco.mju_warningText(warning, data.warning[warning].lastinfo)}"
            )
    if first is not None:
        raise unstable(when, "non-finite or reset state")


# a body this many times the model's size from its centre has left the machine
RUNAWAY_EXTENT = 10.0
# a motor this many times faster than its no-load speed is driven by numbers, not physics
RUNAWAY_SPEED = 1.5
RUNAWAY_BODY_STRIDE = 20  # body positions are checked every 20 steps (and at each chunk's end)


def _ancestor_joint(model: mujoco.MjModel, body: int) -> str:
    """The nearest joint at or above ``body`` (what lets it move)."""
    while body > 0:
        if model.body_jntnum[body]:
            return (
                model.joint(int(model.body_jntadr[body])).name
                or f"joint {int(model.body_jntadr[body])}"
            )
        body = int(model.body_parentid[body])
    return "none"


def runaway_guard(machine: Machine, voltages_V: np.ndarray):
    """A check of each rollout chunk that ends the run with one UserError naming the joint and
    the simulated time where a body has left ten times the model's extent or the motor turns
    faster than 1.5 times its no-load speed (at the run's largest voltage, at least the supply's)."""
    from mechanism.machine.machine import STALL_VOLTAGE_V

    model = machine.model
    nq = model.nq
    extent = float(model.stat.extent)
    centre = np.array(model.stat.center)
    from mechanism.machine.machine import actuator_name
    from mechanism.physics.motor import DCMotor

    supply = machine.description.section("supply").get("voltage_V", 0.0)
    limits = []  # (joint, dof, no-load speed [rad/s], at what voltage)
    for joint, drive in machine.drives.items():
        if isinstance(drive, DCMotor):
            column = (
                np.atleast_2d(voltages_V)[
                    :, machine.model.actuator(actuator_name(machine.description, joint)).id
                ]
                if np.ndim(voltages_V) == 2
                else np.asarray(voltages_V)
            )
            volts = (
                max(float(np.max(np.abs(column))) if np.size(column) else 0.0, supply)
                or STALL_VOLTAGE_V
            )
        else:
            volts = STALL_VOLTAGE_V
        speed = drive.no_load_speed_rad_s(volts)
        if speed is not None:
            limits.append(
                (joint, int(machine.model.jnt_dofadr[machine.model.joint(joint).id]), speed, volts)
            )
    data = mujoco.MjData(model)
    dt = model.opt.timestep

    def check(states: np.ndarray, start_s: float) -> None:
        first_fast, fast_motor = None, None
        for joint, dof, no_load, volts in limits:
            over = np.flatnonzero(~(np.abs(states[:, 1 + nq + dof]) <= RUNAWAY_SPEED * no_load))
            if over.size and (first_fast is None or over[0] < first_fast):
                first_fast, fast_motor = int(over[0]), (joint, dof, no_load, volts)
        picks = list(range(0, len(states), RUNAWAY_BODY_STRIDE)) + [len(states) - 1]
        for i in picks:
            if first_fast is not None and i > first_fast:
                break
            data.qpos[:] = states[i, 1 : 1 + nq]
            mujoco.mj_kinematics(model, data)
            distance = np.linalg.norm(data.xpos[1:] - centre, axis=1)
            far = np.flatnonzero(~(distance <= RUNAWAY_EXTENT * extent))
            if far.size:
                body = int(far[np.argmax(distance[far])]) + 1
                joint = _ancestor_joint(model, body)
                raise UserError(
                    f"the run left the machine at t = {start_s + (i + 1) * dt:.4f} s: body "
                    f"{model.body(body).name or body} (joint {joint}) is {distance[body - 1] * 1e3:.4g} mm "
                    f"from the model's centre, more than {RUNAWAY_EXTENT:g} times its size "
                    f"({extent * 1e3:.4g} mm): a joint without a limit or damping ran away (give "
                    f'[limits."{joint}"] or [friction."{joint}"] viscous_Nm_s_per_rad)'
                )
        if first_fast is not None:
            assert fast_motor is not None  # set together with first_fast
            joint, dof, no_load, volts = fast_motor
            rpm = abs(float(states[first_fast, 1 + nq + dof])) * 60 / (2 * np.pi)
            raise UserError(
                f"the motor joint {joint} turned at {rpm:.4g} rpm at t = "
                f"{start_s + (first_fast + 1) * dt:.4f} s, more than {RUNAWAY_SPEED:g} times its no-load "
                f"speed ({no_load * 60 / (2 * np.pi):.4g} rpm at {volts:g} V): the numbers are not "
                f"physical; {LIKELY_CAUSE}"
            )

    return check


@dataclass
class SimulationResult:
    time_s: np.ndarray
    voltage_V: np.ndarray
    current_A: np.ndarray
    shaft_angle_rad: np.ndarray  # from the described zero
    shaft_velocity_rad_s: np.ndarray
    shaft_acceleration_rad_s2: np.ndarray
    tool_z_mm: np.ndarray  # the tool above the plate top (NaN without a described tool)
    motor_velocity_rad_s: np.ndarray
    metadata: dict = field(default_factory=dict)
    # full physics state (mjSTATE_FULLPHYSICS) after each sample, for replays
    state: np.ndarray | None = None
    sensordata: np.ndarray | None = None  # the model's sensors after each sample (full model only)
    # every joint's position/velocity, each motor's input/current
    joints: dict[str, np.ndarray] = field(default_factory=dict)

    # the sewing machine's names of the shaft and tool fields, kept as aliases
    arm_angle_rad = renamed("shaft_angle_rad")
    arm_velocity_rad_s = renamed("shaft_velocity_rad_s")
    arm_acceleration_rad_s2 = renamed("shaft_acceleration_rad_s2")
    needle_z_mm = renamed("tool_z_mm")

    def columns(self) -> dict[str, np.ndarray]:
        """The CSV columns (``mechanism simulate --csv``): the shaft's and the tool's keep their
        historical names (``arm_*``, ``needle_z_mm``: the file contract)."""
        return {
            "time_s": self.time_s,
            "voltage_V": self.voltage_V,
            "current_A": self.current_A,
            "arm_angle_rad": self.shaft_angle_rad,
            "arm_velocity_rad_s": self.shaft_velocity_rad_s,
            "arm_acceleration_rad_s2": self.shaft_acceleration_rad_s2,
            "needle_z_mm": self.tool_z_mm,
            "motor_velocity_rad_s": self.motor_velocity_rad_s,
            "arm_speed_rpm": self.shaft_velocity_rad_s * 60 / (2 * np.pi),
            **self.joints,
        }

    def window(self, last_s: float) -> slice:
        start = np.searchsorted(self.time_s, self.time_s[-1] - last_s)
        return slice(int(start), None)

    @property
    def mean_speed_rpm(self) -> float:
        """Mean shaft speed [rpm] over the last second (the last half of shorter runs)."""
        return self.speed_summary(min(1.0, 0.5 * float(self.time_s[-1])))["mean_rpm"]

    def speed_summary(self, last_s: float = 1.0) -> dict[str, float]:
        """Mean / min / max shaft speed [rpm] over the last ``last_s`` seconds."""
        rpm = self.shaft_velocity_rad_s[self.window(last_s)] * 60 / (2 * np.pi)
        return {
            "mean_rpm": float(rpm.mean()),
            "min_rpm": float(rpm.min()),
            "max_rpm": float(rpm.max()),
        }


def simulate(
    voltage: VoltageProfile | float,
    duration_s: float,
    machine: Machine | None = None,
    config: MachineConfig | None = None,
    start_angle_rad: float = 0.0,
    sample_rate_hz: float = 1000.0,
    progress: bool = False,
) -> SimulationResult:
    """Run the machine (default: the shipped one, under ``config``) from rest at shaft angle
    ``start_angle_rad`` for ``duration_s`` seconds."""
    machine = machine or Machine(None, config)
    run = _Run(machine, voltage, duration_s, start_angle_rad, sample_rate_hz)
    guard = runaway_guard(machine, run.control)
    state, sensordata = _rollout_in_chunks(
        machine.model, machine.data, run.control, progress, guard
    )
    return run.result(state, sensordata)


def simulate_batch(
    machines: list[Machine],
    voltages: list[VoltageProfile | float],
    duration_s: float,
    start_angle_rad: float = 0.0,
    sample_rate_hz: float = 1000.0,
    threads: int = 1,
) -> list[SimulationResult | UserError]:
    """Run many machines of one size signature (variants of one model) in a single
    ``mujoco.rollout`` call on its thread pool; each result equals :func:`simulate`'s (the
    state carries everything, so one long rollout is the chunked one). A run that became
    unstable is returned as its UserError, in its place."""
    runs = [
        _Run(m, v, duration_s, start_angle_rad, sample_rate_hz) for m, v in zip(machines, voltages)
    ]
    if not runs:
        return []
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    models = [m.model for m in machines]
    initial = np.array([_state(m.model, m.data, spec) for m in machines])
    warmstart = np.array([m.data.qacc_warmstart for m in machines])
    control = np.array([r.control for r in runs])
    datas = [mujoco.MjData(models[0]) for _ in range(max(1, min(threads, len(runs))))]
    states, sensors = mujoco.rollout.rollout(
        models, datas, initial, control, initial_warmstart=warmstart
    )
    results: list[SimulationResult | UserError] = []
    for run, state, sensor in zip(runs, states, sensors):
        try:
            check_stable(run.machine.model, None, state, sensor, 0.0, run.control)
            runaway_guard(run.machine, run.control)(state, 0.0)
            results.append(run.result(state, sensor))
        except UserError as exc:
            results.append(exc)
    return results


def _state(model, data, spec) -> np.ndarray:
    state = np.zeros(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    return state


class _Run:
    """One run's controls (the machine reset to its start) and the unpacking of its states."""

    def __init__(
        self,
        machine: Machine,
        voltage: VoltageProfile | float,
        duration_s: float,
        start_angle_rad: float,
        sample_rate_hz: float,
    ):
        if not 0 < duration_s <= MAX_DURATION_S:
            raise UserError(
                f"duration must be positive and at most {MAX_DURATION_S:g} s, got {duration_s:g}"
            )
        if not 10 <= sample_rate_hz <= 100_000:
            raise UserError("sample rate must be between 10 Hz and 100 kHz")
        from mechanism.files.limits import check_elements

        self.machine, self.start_angle_rad = machine, start_angle_rad
        model = machine.model
        self.dt = dt = model.opt.timestep
        self.substeps = max(1, int(round(1.0 / (sample_rate_hz * dt))))
        self.nsample = int(round(duration_s * sample_rate_hz))
        nstep = self.nsample * self.substeps
        width = (
            mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
            + model.nsensordata
            + model.nu
            + 1
        )
        check_elements(
            float(nstep) * width, f"a {duration_s:g} s run at a {dt * 1e3:g} ms time step"
        )
        machine.reset(start_angle_rad)
        self.control = np.zeros((nstep, model.nu))
        times = np.arange(nstep) * dt
        for joint, profile in motor_inputs(machine, voltage).items():
            self.control[:, model.actuator(actuator_name(machine.description, joint)).id] = profile(
                times
            )

    def result(self, state: np.ndarray, sensordata: np.ndarray) -> SimulationResult:
        machine, model, dt, substeps = self.machine, self.machine.model, self.dt, self.substeps
        # the full physics state: [time, qpos, qvel, act, ...]
        qpos = state[:, 1 : 1 + model.nq]
        qvel = state[:, 1 + model.nq : 1 + model.nq + model.nv]
        shaft_angle = machine.shaft_angle(qpos)
        shaft_velocity = machine.shaft_velocity(qvel)
        motor_velocity = qvel[:, machine.motor_dof]
        samples = np.arange(1, self.nsample + 1) * substeps - 1  # state after each sample interval
        previous = np.concatenate([[0.0], shaft_velocity])[samples + 1 - substeps]
        acceleration = (shaft_velocity[samples] - previous) / (substeps * dt)

        torque = sensordata[:, model.sensor(TORQUE_SENSOR).adr[0]]
        applied = self.control[:, machine.actuator]
        current = torque / machine.motor.torque_constant_Nm_A
        if machine.motor.cogging_Nm:  # the electromagnetic part only
            motor_angle = qpos[:, machine.motor_qpos]
            cog = machine.motor.cogging_Nm * np.sin(
                machine.motor.cogging_poles * motor_angle + machine.motor.cogging_phase_rad
            )
            current = (torque - cog) / machine.motor.torque_constant_Nm_A
        if (
            machine.supply
        ):  # the limit acts in the passive callback: the sensor sees the commanded current
            motor = machine.motor
            commanded = (applied - motor.back_emf_V_s_rad * motor_velocity) / motor.resistance_ohm
            current = current + machine.supply.current(motor, applied, motor_velocity) - commanded
        tool_z = machine.tool_height_mm_at(shaft_angle)
        joints = joint_columns(
            machine, qpos[samples], qvel[samples], self.control[samples], sensordata[samples]
        )
        voltage, current = applied[samples], current[samples]
        main = machine.drives[machine.motor_joint]
        if not isinstance(
            main, DCMotor
        ):  # the main motor's terminal voltage and current, not its command
            current = joints[f"{machine.motor_joint}_current_A"]
            if isinstance(main, ServoDrive):
                voltage = main.voltage(
                    applied[samples], qpos[samples, machine.motor_qpos], motor_velocity[samples]
                )
            else:
                # a current drive's voltage is its amplifier's business
                voltage = np.full(len(samples), np.nan)
        return SimulationResult(
            time_s=(samples + 1) * dt,
            voltage_V=voltage,
            current_A=current,
            shaft_angle_rad=shaft_angle[samples],
            shaft_velocity_rad_s=shaft_velocity[samples],
            shaft_acceleration_rad_s2=acceleration,
            tool_z_mm=tool_z[samples],
            motor_velocity_rad_s=motor_velocity[samples],
            metadata={
                "timestep_s": dt,
                "native_callbacks": machine.native,
                "start_angle_rad": self.start_angle_rad,
                "sensor_columns": {
                    model.sensor(i).name: int(model.sensor_adr[i]) for i in range(model.nsensor)
                },
            },
            state=state[samples],
            sensordata=sensordata[samples],
            joints=joints,
        )


def motor_inputs(machine: Machine, inputs) -> dict[str, VoltageProfile]:
    """Each motor's input over time (a zero-order hold in its unit: V, goal rad or A). ``inputs``:
    the main motor's (a number or profile), or a mapping joint -> number or profile. A motor given
    none gets 0 V (dc), 0 A (current), or holds its joint where the run starts (servo)."""
    from mechanism.machine.machine import input_unit
    from mechanism.physics.motor import ServoDrive

    description = machine.description
    if not isinstance(inputs, dict) and input_unit(description, machine.motor_joint) != "V":
        raise UserError(
            f"a voltage drives a dc motor; the main motor on {machine.motor_joint} is a "
            f"{description.motor['type']} drive: give its input by joint "
            f"({'--goal' if input_unit(description, machine.motor_joint) == 'rad' else '--current'} "
            f"{machine.motor_joint}=...)"
        )
    given = dict(inputs) if isinstance(inputs, dict) else {machine.motor_joint: inputs}
    for joint in given:
        if joint not in machine.drives:
            raise UserError(
                f"no motor on joint {joint!r}; the described motors: {', '.join(machine.drives)}"
            )
    out = {}
    for joint, drive in machine.drives.items():
        value = given.get(joint)
        unit = input_unit(description, joint)
        if value is None:
            if isinstance(drive, ServoDrive):
                value = float(
                    machine.data.qpos[machine.model.jnt_qposadr[machine.model.joint(joint).id]]
                )
            else:
                value = 0.0
        if not isinstance(value, VoltageProfile):
            value = float(value)
            if not np.isfinite(value):
                raise UserError(f"input of the motor on {joint}: must be a finite number of {unit}")
            if joint == machine.motor_joint and unit == "V" and not isinstance(inputs, dict):
                # the one-motor voltage keeps its range check
                value = VoltageProfile.constant(value)
            else:
                value = VoltageProfile(np.array([0.0]), np.array([value]))
        if joint == machine.motor_joint and unit == "V":
            machine.check_voltage(value)  # within the described motor's rated voltage
        out[joint] = value
    return out


def joint_columns(
    machine: Machine,
    qpos: np.ndarray,
    qvel: np.ndarray,
    control: np.ndarray,
    sensordata: np.ndarray,
) -> dict[str, np.ndarray]:
    """Every hinge's and slide's position and velocity (``JOINT_pos_rad``/``JOINT_vel_rad_s``, or
    ``_mm``/``_mm_s``), each motor's input (``JOINT_input_V|rad|A``) and current (``JOINT_current_A``)."""
    from mechanism.machine.machine import actuator_name, input_unit, torque_sensor_name
    from mechanism.physics.motor import CurrentDrive, ServoDrive

    model = machine.model
    out: dict[str, np.ndarray] = {}
    for j in range(model.njnt):
        name, kind = model.joint(j).name, int(model.jnt_type[j])
        if not name or kind not in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            continue
        q, v = qpos[:, model.jnt_qposadr[j]], qvel[:, model.jnt_dofadr[j]]
        if kind == int(mujoco.mjtJoint.mjJNT_SLIDE):
            out[f"{name}_pos_mm"], out[f"{name}_vel_mm_s"] = q * 1e3, v * 1e3
        else:
            out[f"{name}_pos_rad"], out[f"{name}_vel_rad_s"] = q, v
    for joint, drive in machine.drives.items():
        command = control[:, model.actuator(actuator_name(machine.description, joint)).id]
        out[f"{joint}_input_{input_unit(machine.description, joint)}"] = command
        jid = model.joint(joint).id
        q, v = qpos[:, model.jnt_qposadr[jid]], qvel[:, model.jnt_dofadr[jid]]
        if isinstance(drive, ServoDrive):
            current = drive.current(command, q, v)
        elif isinstance(drive, CurrentDrive):
            current = drive.current(command)
        else:
            torque = sensordata[
                :, model.sensor(torque_sensor_name(machine.description, joint)).adr[0]
            ]
            if drive.cogging_Nm:
                torque = torque - drive.cogging_Nm * np.sin(
                    drive.cogging_poles * q + drive.cogging_phase_rad
                )
            current = torque / drive.torque_constant_Nm_A
        out[f"{joint}_current_A"] = np.asarray(current, dtype=float)
    return out


def plot_simulation(result: SimulationResult, path) -> None:
    """Shaft speed, current with voltage, and tool height over time."""
    from mechanism.files.plotting import plt, save_figure

    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    axes[0].plot(result.time_s, result.shaft_velocity_rad_s * 60 / (2 * np.pi), lw=0.8)
    axes[0].set_ylabel("shaft speed [rpm]")
    axes[1].plot(result.time_s, result.current_A, lw=0.8, color="tab:red")
    axes[1].set_ylabel("current [A]")
    ax_v = axes[1].twinx()
    ax_v.plot(result.time_s, result.voltage_V, lw=0.8, color="tab:gray")
    ax_v.set_ylabel("voltage [V]")
    axes[2].plot(result.time_s, result.tool_z_mm, lw=0.8, color="tab:green")
    axes[2].axhline(0.0, color="k", lw=0.5)
    axes[2].set_ylabel("tool above plate [mm]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    save_figure(fig, path)
