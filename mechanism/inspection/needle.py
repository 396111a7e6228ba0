"""Tool (needle) motion over one shaft revolution, and where a hook point meets the needle.

What a sewing-machine designer checks first on a new needle drive: the needle-bar stroke,
the dead centres, the needle's velocity and acceleration per unit arm speed (the
acceleration is what loads the crank, link and bushings), and the hook timing: the arm
angle at which the rotary hook's point passes the needle, how far the needle has risen from
bottom dead centre by then (the loop lift), and how close the point runs to the needle.

Everything is computed on the converted MJCF by MuJoCo, with the position solver of
:mod:`mechanism.kinematics.pose` (all loop closures and couplings hold):

* tool height: the described tool site above the described plate's top surface, against gravity;
* velocity dz/dθ: exact, from the constraint Jacobians (no finite differences);
* acceleration d²z/dθ²: spectral derivative of the exact velocity over the revolution;
* hook passage: the shaft angle where the described hook site, seen along the hook joint's
  axis, crosses the needle axis (the line from the tool site to its eye site), refined
  by root finding on fresh poses; the clearance is the exact distance from the hook point
  to the needle's mesh triangles.

Angles are shaft angles from the described zero, positive = the motor's forward direction.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mechanism.errors import UserError

MIN_SAMPLES = 36
MAX_SAMPLES = 36000


@dataclass
class NeedleMotion:
    """Needle and hook over one arm revolution (arrays sampled at ``arm_angle_deg``)."""

    arm_angle_deg: np.ndarray
    needle_z_mm: np.ndarray  # needle point above the needle-plate top
    needle_velocity_mm_per_rad: np.ndarray  # dz/dθ: mm/s per rad/s of arm speed
    needle_acceleration_mm_per_rad2: np.ndarray  # d²z/dθ²: mm/s² per (rad/s)² at constant arm speed
    hook_angle_deg: np.ndarray  # hook joint position (0 at the assembly pose)
    hook_point_to_needle_mm: np.ndarray  # hook point to the needle axis, across the hook axis
    stroke_mm: float
    tdc_angle_deg: float
    bdc_angle_deg: float
    tdc_z_mm: float
    bdc_z_mm: float
    plate_reference: str  # what needle_z_mm is measured from
    hook_passage_angle_deg: float | None = None
    needle_rise_at_passage_mm: float | None = None  # needle height above BDC at the passage
    hook_point_to_needle_axis_mm: float | None = None  # at the passage
    # hook point to the needle surface (mesh) at the passage
    hook_point_clearance_mm: float | None = None
    # hook point above the needle-eye centre at the passage
    hook_point_above_eye_mm: float | None = None
    speed_rpm: float | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def arm_speed_rad_s(self) -> float | None:
        return None if self.speed_rpm is None else self.speed_rpm * 2 * math.pi / 60

    def columns(self) -> dict[str, np.ndarray]:
        """CSV columns, units in the names."""
        cols = {
            "arm_angle_deg": self.arm_angle_deg,
            "needle_z_mm": self.needle_z_mm,
            "needle_velocity_mm_per_rad": self.needle_velocity_mm_per_rad,
            "needle_acceleration_mm_per_rad2": self.needle_acceleration_mm_per_rad2,
        }
        w = self.arm_speed_rad_s
        if w is not None:
            cols["needle_velocity_mm_s"] = self.needle_velocity_mm_per_rad * w
            cols["needle_acceleration_mm_s2"] = self.needle_acceleration_mm_per_rad2 * w**2
        cols["hook_angle_deg"] = self.hook_angle_deg
        cols["hook_point_to_needle_mm"] = self.hook_point_to_needle_mm
        return cols

    def summary_lines(self) -> list[str]:
        vel = np.abs(self.needle_velocity_mm_per_rad).max()
        acc = np.abs(self.needle_acceleration_mm_per_rad2).max()
        lines = [
            f"stroke: {self.stroke_mm:.3f} mm",
            f"top dead centre: shaft angle {self.tdc_angle_deg:.2f} deg, tool point {self.tdc_z_mm:.3f} mm",
            f"bottom dead centre: shaft angle {self.bdc_angle_deg:.2f} deg, tool point {self.bdc_z_mm:.3f} mm",
            f"peak velocity: {vel:.3f} mm/rad; peak acceleration: {acc:.3f} mm/rad^2",
        ]
        w = self.arm_speed_rad_s
        if w is not None:
            lines.append(
                f"at {self.speed_rpm:g} rpm: peak velocity {vel * w / 1000:.3f} m/s, "
                f"peak acceleration {acc * w**2 / 1000:.1f} m/s^2"
            )
        if self.hook_passage_angle_deg is not None:
            lines.append(
                f"hook point passes the needle at shaft angle {self.hook_passage_angle_deg:.2f} deg: needle "
                f"{self.needle_rise_at_passage_mm:.3f} mm above bottom dead centre, hook point "
                f"{self.hook_point_above_eye_mm:.3f} mm above the eye centre, "
                f"{self.hook_point_to_needle_axis_mm:.3f} mm from the needle axis, "
                f"{self.hook_point_clearance_mm:.3f} mm clear of the needle"
            )
        lines.append(f"tool height measured from {self.plate_reference}")
        lines += [f"note: {note}" for note in self.notes]
        return lines


@dataclass(frozen=True)
class _Roles:
    """The names the tool motion needs, from the machine description."""

    tip: str
    eye: str | None
    part: str | None
    hook_joint: str | None
    hook_point: str | None


def needle_motion(machine=None, samples: int = 360, speed_rpm: float | None = None) -> NeedleMotion:
    """Tool (needle) motion of a machine (default: the shipped one) over one shaft revolution
    at ``samples`` equally spaced shaft angles from the described zero, and the hook timing
    when the description names a hook ([hook] joint and site, [tool] eye_site and part)."""
    import mujoco

    from mechanism.kinematics.linkage import compute_tables, periodic_derivative, up_axis
    from mechanism.kinematics.pose import approach, solve_pose, sweep
    from mechanism.machine.machine import load_machine

    samples = _check_samples(samples)
    if speed_rpm is not None and not (math.isfinite(speed_rpm) and speed_rpm > 0):
        raise UserError(f"speed must be a positive number of rpm (got {speed_rpm})")
    machine = machine or load_machine()
    if not machine.tool_site:
        raise UserError(
            f"machine {machine.name}: its description names no tool ([tool] site): no tool motion to compute"
        )
    tool, hook = machine.description.section("tool"), machine.description.section("hook")
    roles = _Roles(
        machine.tool_site,
        tool.get("eye_site"),
        tool.get("part"),
        hook.get("joint"),
        hook.get("site"),
    )
    model, shaft = machine.model, machine.shaft_joint
    up = up_axis(model)
    tables = compute_tables(
        model,
        shaft,
        roles.tip,
        n=samples,
        zero_rad=machine.frame.zero_rad,
        direction=machine.frame.direction,
        span=machine.shaft_span_rad,
    )
    rocks = not tables.periodic
    data = mujoco.MjData(model)
    notes: list[str] = []
    if machine.plate_top_z is not None:
        plate_z, reference = machine.plate_top_z, f"the top surface of {machine.plate_part}"
    else:
        plate_z, reference = 0.0, "the world origin (the description names no [tool] plate)"
        notes.append("no plate part described: heights are measured from the world origin")

    theta = tables.angle_rad
    # the machine's loader checked that [tool] site names a site, so the tool's tables are there
    assert tables.tool_z_m is not None and tables.tool_dz_drad is not None
    z = (tables.tool_z_m - plate_z) * 1000.0
    velocity = tables.tool_dz_drad * 1000.0
    acceleration = np.gradient(velocity, theta) if rocks else periodic_derivative(velocity)

    if rocks:
        approach(model, data, shaft, machine.joint_position(float(theta[0])))
    poses = sweep(model, [machine.joint_position(a) for a in theta], driver=shaft, data=data)

    def pose_at(angle: float) -> None:
        """Solve the pose at shaft ``angle`` starting from the nearest sampled pose (same branch)."""
        if rocks:
            nearest = int(np.argmin(np.abs(theta - angle)))
        else:
            nearest = int(round((angle % (2 * math.pi)) / (2 * math.pi) * samples)) % samples
        data.qpos[:] = poses[nearest]
        solve_pose(model, data, {shaft: machine.joint_position(angle)})

    def needle_z_at(angle: float) -> float:
        pose_at(angle)
        return (up @ data.site(roles.tip).xpos - plate_z) * 1000.0

    if rocks:  # a rocking drive: the tool's highest and lowest points over the travel
        tdc, bdc = float(theta[int(np.argmax(z))]), float(theta[int(np.argmin(z))])
        notes.append(
            f"the shaft rocks between {math.degrees(theta[0]):.4g} and {math.degrees(theta[-1]):.4g} deg: "
            "the tool's top and bottom are its highest and lowest points over that travel"
        )
    else:
        tdc = _velocity_zero(theta, velocity, falling=True)
        bdc = _velocity_zero(theta, velocity, falling=False)
    tdc_z, bdc_z = needle_z_at(tdc), needle_z_at(bdc)

    # the hook timing needs the hook joint, the hook point's site and the needle eye's site
    hook_joint = (
        roles.hook_joint if roles.hook_point is not None and roles.eye is not None else None
    )
    has_hook = hook_joint is not None
    hook_angle = (
        np.degrees(tables.positions[hook_joint])
        if hook_joint is not None
        else np.full(samples, np.nan)
    )
    motion = NeedleMotion(
        arm_angle_deg=np.degrees(theta),
        needle_z_mm=z,
        needle_velocity_mm_per_rad=velocity,
        needle_acceleration_mm_per_rad2=acceleration,
        hook_angle_deg=hook_angle,
        hook_point_to_needle_mm=np.full(samples, np.nan),
        stroke_mm=tdc_z - bdc_z,
        tdc_angle_deg=math.degrees(tdc) if rocks else _signed_deg(tdc),
        bdc_angle_deg=math.degrees(bdc) if rocks else math.degrees(bdc) % 360.0,
        tdc_z_mm=tdc_z,
        bdc_z_mm=bdc_z,
        plate_reference=reference,
        speed_rpm=speed_rpm,
        notes=notes,
    )
    if has_hook and rocks:
        notes.append(
            "hook timing is computed for a shaft turning whole revolutions, not for one that rocks"
        )
        return motion
    if not has_hook:
        notes.append(
            "no hook described ([hook] joint and site, [tool] eye_site): hook timing not computed"
        )
        return motion
    hook = _HookGeometry(model, data, roles)
    offsets, distances = np.zeros(samples), np.zeros(samples)
    for i, angle in enumerate(theta):
        pose_at(float(angle))
        offsets[i], distances[i] = hook.offset_and_distance()
    motion.hook_point_to_needle_mm = distances * 1000.0
    passage = hook.passage(theta, offsets, solve=pose_at)
    if passage is None:
        notes.append(
            "the hook point never passes the needle while the needle is at the hook's height"
        )
        return motion
    pose_at(passage)
    _, across = hook.offset_and_distance()
    motion.hook_passage_angle_deg = math.degrees(passage) % 360.0
    motion.needle_rise_at_passage_mm = (up @ data.site(roles.tip).xpos - plate_z) * 1000.0 - bdc_z
    motion.hook_point_to_needle_axis_mm = across * 1000.0
    motion.hook_point_above_eye_mm = (
        float(up @ (data.site(roles.hook_point).xpos - data.site(roles.eye).xpos)) * 1000.0
    )
    clearance = hook.clearance_to_needle_mesh()
    if clearance is None:
        notes.append(
            "no tool part mesh described ([tool] part): clearance to the needle surface not computed"
        )
    else:
        motion.hook_point_clearance_mm = clearance * 1000.0
    return motion


class _HookGeometry:
    """Hook point relative to the needle axis, in the plane normal to the hook axis."""

    def __init__(self, model, data, roles: _Roles):
        import mujoco

        self.model, self.data, self.roles = model, data, roles
        self.joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, roles.hook_joint)
        self.geom = (
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, roles.part) if roles.part else -1
        )

    def _frames(self):
        d = self.data
        axis = d.xaxis[self.joint] / np.linalg.norm(d.xaxis[self.joint])
        anchor = d.xanchor[self.joint]
        point = d.site(self.roles.hook_point).xpos.copy()
        tip, eye = d.site(self.roles.tip).xpos.copy(), d.site(self.roles.eye).xpos.copy()
        return axis, anchor, point, tip, eye

    def offset_and_distance(self) -> tuple[float, float]:
        """(signed angular offset of the hook point from the needle about the hook axis [rad],
        distance of the hook point from the needle axis, measured across the hook axis [m])."""
        axis, anchor, point, tip, eye = self._frames()
        needle_dir = (eye - tip) / np.linalg.norm(eye - tip)
        # the needle axis where it crosses the hook point's plane (normal to the hook axis)
        denom = needle_dir @ axis
        s = ((point - tip) @ axis) / denom if abs(denom) > 1e-9 else 0.0
        crossing = tip + s * needle_dir

        def planar(v):
            return v - (v @ axis) * axis

        a, b = planar(point - anchor), planar(crossing - anchor)
        offset = math.atan2(np.cross(b, a) @ axis, a @ b)
        return offset, float(np.linalg.norm(planar(point - crossing)))

    def needle_span(self) -> bool:
        """Is the hook point level with the needle (between its point and its butt)?"""
        axis, _, point, tip, eye = self._frames()
        return (point - tip) @ ((eye - tip) / np.linalg.norm(eye - tip)) > 0

    def passage(self, theta, offsets, solve) -> float | None:
        """The arm angle where the hook point crosses the needle axis with the needle level
        with it; the crossing nearest to the needle when there are several."""
        from scipy.optimize import brentq

        n = len(theta)
        best = None
        for i in range(n):
            a, b = offsets[i], offsets[(i + 1) % n]
            if not (a <= 0 < b or a >= 0 > b) or abs(a - b) > math.pi:
                continue  # no crossing, or the ±π wrap on the far side of the hook axis
            lo = theta[i]
            hi = theta[i + 1] if i + 1 < n else theta[0] + 2 * math.pi

            def f(angle):
                solve(angle)
                return self.offset_and_distance()[0]

            angle = brentq(f, lo, hi, xtol=1e-12)
            solve(angle)
            if not self.needle_span():
                continue
            distance = self.offset_and_distance()[1]
            if best is None or distance < best[1]:
                best = (angle, distance)
        return None if best is None else best[0]

    def clearance_to_needle_mesh(self) -> float | None:
        """Exact distance [m] from the hook point to the needle's surface (its mesh triangles)."""
        import mujoco

        from mechanism.inspection.shapes import PartShape

        if (
            self.roles.part is None
            or self.geom < 0
            or self.model.geom_type[self.geom] != mujoco.mjtGeom.mjGEOM_MESH
        ):
            return None
        needle = PartShape(self.model, self.roles.part)
        needle.update(self.data)
        return float(needle.point_distance(self.data.site(self.roles.hook_point).xpos)[0])


def _velocity_zero(theta: np.ndarray, velocity: np.ndarray, falling: bool) -> float:
    """Arm angle where the (exact) needle velocity crosses zero: from + to - at the top
    dead centre (``falling``), from - to + at the bottom one; linear between samples."""
    n = len(theta)
    best = None
    for i in range(n):
        a, b = velocity[i], velocity[(i + 1) % n]
        if (falling and a > 0 >= b) or (not falling and a < 0 <= b):
            hi = theta[i + 1] if i + 1 < n else theta[0] + 2 * math.pi
            angle = theta[i] if a == b else theta[i] + (hi - theta[i]) * a / (a - b)
            # several crossings only for a wobbly drive: keep the one with the steepest slope
            if best is None or abs(b - a) > best[1]:
                best = (angle, abs(b - a))
    if best is None:
        raise UserError("the needle does not reciprocate over an arm revolution")
    return best[0]


def _signed_deg(angle: float) -> float:
    """Degrees in (-180, 180] (top dead centre reads 0, not 360)."""
    deg = math.degrees(angle) % 360.0
    deg = deg - 360.0 if deg > 180.0 else deg
    return 0.0 if abs(deg) < 1e-9 else deg


def _check_samples(samples) -> int:
    if (
        isinstance(samples, bool)
        or int(samples) != samples
        or not MIN_SAMPLES <= samples <= MAX_SAMPLES
    ):
        raise UserError(
            f"samples must be a whole number from {MIN_SAMPLES} to {MAX_SAMPLES} (got {samples})"
        )
    return int(samples)


# ----------------------------------------------------------------------------- outputs


def write_csv(motion: NeedleMotion, path: str | os.PathLike) -> Path:
    from mechanism.files.tables import write_table

    comments = ["needle motion over one arm revolution (arm angle 0 = needle top dead centre)"]
    comments += [line for line in motion.summary_lines()]
    return write_table(path, motion.columns(), comments=comments)


def plot(motion: NeedleMotion, path: str | os.PathLike) -> None:
    """Needle position, velocity and acceleration against arm angle, dead centres, the
    needle-plate level and the hook passage marked."""
    from mechanism.files.plotting import plt, save_figure

    angle = motion.arm_angle_deg
    per_speed = motion.speed_rpm is not None
    w = motion.arm_speed_rad_s or 1.0
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 8.5))
    series = [
        (motion.needle_z_mm, "needle point [mm]"),
        (
            motion.needle_velocity_mm_per_rad
            * (w if per_speed else 1.0)
            / (1000.0 if per_speed else 1.0),
            "velocity [m/s]" if per_speed else "velocity [mm/rad]\n(mm/s per rad/s)",
        ),
        (
            motion.needle_acceleration_mm_per_rad2
            * (w**2 if per_speed else 1.0)
            / (1000.0 if per_speed else 1.0),
            "acceleration [m/s²]" if per_speed else "acceleration [mm/rad²]",
        ),
    ]
    for ax, (values, label) in zip(axes, series):
        ax.plot(angle, values, color="tab:blue", lw=1.6)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.axhline(0.0, color="0.3", lw=0.8)
        for x in (motion.tdc_angle_deg, motion.bdc_angle_deg):
            ax.axvline(x, color="0.5", ls=":", lw=1)
        if motion.hook_passage_angle_deg is not None:
            ax.axvline(motion.hook_passage_angle_deg, color="tab:red", ls="--", lw=1.2)
    top = axes[0]
    top.axhline(0.0, color="tab:brown", lw=2.0, alpha=0.6, label="needle-plate top")
    top.plot([motion.tdc_angle_deg], [motion.tdc_z_mm], "v", color="0.3")
    top.plot([motion.bdc_angle_deg], [motion.bdc_z_mm], "^", color="0.3")
    top.annotate(
        f"TDC {motion.tdc_angle_deg:.1f}°",
        (motion.tdc_angle_deg, motion.tdc_z_mm),
        xytext=(6, -12),
        textcoords="offset points",
        fontsize=8,
    )
    top.annotate(
        f"BDC {motion.bdc_angle_deg:.1f}°",
        (motion.bdc_angle_deg, motion.bdc_z_mm),
        xytext=(6, 4),
        textcoords="offset points",
        fontsize=8,
    )
    if (
        motion.hook_passage_angle_deg is not None and motion.needle_rise_at_passage_mm is not None
    ):  # set together
        z_pass = motion.bdc_z_mm + motion.needle_rise_at_passage_mm
        top.plot(
            [motion.hook_passage_angle_deg],
            [z_pass],
            "o",
            color="tab:red",
            label=(
                f"hook point passes: {motion.hook_passage_angle_deg:.1f}°, needle +"
                f"{motion.needle_rise_at_passage_mm:.2f} mm from BDC, {motion.hook_point_clearance_mm:.2f} mm clear"
                if motion.hook_point_clearance_mm is not None
                else f"hook point passes: {motion.hook_passage_angle_deg:.1f}°"
            ),
        )
    top.legend(loc="upper center", fontsize=8)
    top.set_title(
        f"Needle motion over one arm revolution (stroke {motion.stroke_mm:.2f} mm"
        + (f", {motion.speed_rpm:g} rpm)" if per_speed else ")")
    )
    axes[-1].set_xlabel("arm angle [deg] (0 = needle top dead centre)")
    axes[-1].set_xlim(0, 360)
    axes[-1].set_xticks(range(0, 361, 45))
    fig.tight_layout()
    save_figure(fig, path)
