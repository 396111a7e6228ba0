"""The tool's motion over one shaft revolution, and where a hook point meets the tool.

What a designer checks first on a new drive: the tool's stroke, the dead centres, the tool's
velocity and acceleration per unit shaft speed (the acceleration is what loads the crank, link
and bushings). On a sewing machine (a description that names a [hook]) also the hook timing: the
shaft angle at which the rotary hook's point passes the needle (the tool), how far the needle has
risen from bottom dead centre by then (the loop lift), and how close the point runs to the needle.

Everything is computed on the converted MJCF by MuJoCo, with the position solver of
:mod:`mechanism.kinematics.pose` (all loop closures and couplings hold):

* tool height: the described tool site above the described plate's top surface, against gravity;
* velocity dz/dθ: exact, from the constraint Jacobians (no finite differences);
* acceleration d²z/dθ²: spectral derivative of the exact velocity over the revolution;
* hook passage: the shaft angle where the described hook site, seen along the hook joint's
  axis, crosses the tool axis (the line from the tool site to its eye site), refined
  by root finding on fresh poses; the clearance is the exact distance from the hook point
  to the tool part's mesh triangles.

Angles are shaft angles from the described zero, positive = the motor's forward direction.

The sewing machine's own words stay available: ``NeedleMotion`` and ``needle_motion`` are this
module's ``ToolMotion`` and ``tool_motion`` (``mechanism.inspection.needle`` re-exports them),
the ``needle_*``/``arm_*`` fields are aliases of the ``tool_*``/``shaft_*`` ones, and
``columns(names="needle")`` (the default, what ``mechanism needle`` writes) keeps the table's
historical column names; ``names="tool"`` gives the generic ones (``mechanism tool``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from mechanism.errors import UserError
from mechanism.lazy import renamed

MIN_SAMPLES = 36
MAX_SAMPLES = 36000

ColumnNames = Literal["needle", "tool"]
"""Which words the table uses: ``"needle"`` (the sewing machine's historical columns, written by
``mechanism needle``) or ``"tool"`` (the generic ones, written by ``mechanism tool``)."""

# (generic name, the sewing machine's historical name), in the table's order
COLUMN_NAMES: tuple[tuple[str, str], ...] = (
    ("shaft_angle_deg", "arm_angle_deg"),
    ("tool_z_mm", "needle_z_mm"),
    ("tool_velocity_mm_per_rad", "needle_velocity_mm_per_rad"),
    ("tool_acceleration_mm_per_rad2", "needle_acceleration_mm_per_rad2"),
    ("tool_velocity_mm_s", "needle_velocity_mm_s"),
    ("tool_acceleration_mm_s2", "needle_acceleration_mm_s2"),
    ("hook_angle_deg", "hook_angle_deg"),
    ("hook_point_to_tool_mm", "hook_point_to_needle_mm"),
)

# the dataclass's historical attribute names (the sewing machine's) -> the generic fields
FIELD_ALIASES: dict[str, str] = {
    "arm_angle_deg": "shaft_angle_deg",
    "needle_z_mm": "tool_z_mm",
    "needle_velocity_mm_per_rad": "tool_velocity_mm_per_rad",
    "needle_acceleration_mm_per_rad2": "tool_acceleration_mm_per_rad2",
    "hook_point_to_needle_mm": "hook_point_to_tool_mm",
    "needle_rise_at_passage_mm": "tool_rise_at_passage_mm",
    "hook_point_to_needle_axis_mm": "hook_point_to_tool_axis_mm",
    "arm_speed_rad_s": "shaft_speed_rad_s",
}


@dataclass
class ToolMotion:
    """The tool (and a described hook) over one shaft revolution (arrays sampled at ``shaft_angle_deg``)."""

    shaft_angle_deg: np.ndarray
    tool_z_mm: np.ndarray  # tool point above the plate top
    tool_velocity_mm_per_rad: np.ndarray  # dz/dθ: mm/s per rad/s of shaft speed
    tool_acceleration_mm_per_rad2: np.ndarray  # d²z/dθ²: mm/s² per (rad/s)² at constant shaft speed
    hook_angle_deg: np.ndarray  # hook joint position (0 at the assembly pose)
    hook_point_to_tool_mm: np.ndarray  # hook point to the tool axis, across the hook axis
    stroke_mm: float
    tdc_angle_deg: float
    bdc_angle_deg: float
    tdc_z_mm: float
    bdc_z_mm: float
    plate_reference: str  # what tool_z_mm is measured from
    hook_passage_angle_deg: float | None = None
    tool_rise_at_passage_mm: float | None = None  # tool height above BDC at the passage
    hook_point_to_tool_axis_mm: float | None = None  # at the passage
    # hook point to the tool surface (mesh) at the passage
    hook_point_clearance_mm: float | None = None
    # hook point above the tool-eye centre at the passage
    hook_point_above_eye_mm: float | None = None
    speed_rpm: float | None = None
    notes: list[str] = field(default_factory=list)
    zero_meaning: str = "the described zero"  # what shaft angle 0 is, in the description's words

    # the sewing machine's names, kept as aliases
    arm_angle_deg = renamed("shaft_angle_deg")
    needle_z_mm = renamed("tool_z_mm")
    needle_velocity_mm_per_rad = renamed("tool_velocity_mm_per_rad")
    needle_acceleration_mm_per_rad2 = renamed("tool_acceleration_mm_per_rad2")
    hook_point_to_needle_mm = renamed("hook_point_to_tool_mm")
    needle_rise_at_passage_mm = renamed("tool_rise_at_passage_mm")
    hook_point_to_needle_axis_mm = renamed("hook_point_to_tool_axis_mm")
    arm_speed_rad_s = renamed("shaft_speed_rad_s")

    @property
    def shaft_speed_rad_s(self) -> float | None:
        return None if self.speed_rpm is None else self.speed_rpm * 2 * math.pi / 60

    def columns(self, names: ColumnNames = "needle") -> dict[str, np.ndarray]:
        """CSV columns, units in the names: the sewing machine's historical names (``"needle"``,
        the default) or the generic ones (``"tool"``); the same numbers either way."""
        if names not in ("needle", "tool"):
            raise UserError(f"column names {names!r}: expected 'needle' or 'tool'")
        values: dict[str, np.ndarray] = {
            "shaft_angle_deg": self.shaft_angle_deg,
            "tool_z_mm": self.tool_z_mm,
            "tool_velocity_mm_per_rad": self.tool_velocity_mm_per_rad,
            "tool_acceleration_mm_per_rad2": self.tool_acceleration_mm_per_rad2,
        }
        w = self.shaft_speed_rad_s
        if w is not None:
            values["tool_velocity_mm_s"] = self.tool_velocity_mm_per_rad * w
            values["tool_acceleration_mm_s2"] = self.tool_acceleration_mm_per_rad2 * w**2
        values["hook_angle_deg"] = self.hook_angle_deg
        values["hook_point_to_tool_mm"] = self.hook_point_to_tool_mm
        if names == "tool":
            return values
        historical = dict(COLUMN_NAMES)
        return {historical[name]: column for name, column in values.items()}

    def summary_lines(self) -> list[str]:
        vel = np.abs(self.tool_velocity_mm_per_rad).max()
        acc = np.abs(self.tool_acceleration_mm_per_rad2).max()
        lines = [
            f"stroke: {self.stroke_mm:.3f} mm",
            f"top dead centre: shaft angle {self.tdc_angle_deg:.2f} deg, tool point {self.tdc_z_mm:.3f} mm",
            f"bottom dead centre: shaft angle {self.bdc_angle_deg:.2f} deg, tool point {self.bdc_z_mm:.3f} mm",
            f"peak velocity: {vel:.3f} mm/rad; peak acceleration: {acc:.3f} mm/rad^2",
        ]
        w = self.shaft_speed_rad_s
        if w is not None:
            lines.append(
                f"at {self.speed_rpm:g} rpm: peak velocity {vel * w / 1000:.3f} m/s, "
                f"peak acceleration {acc * w**2 / 1000:.1f} m/s^2"
            )
        if self.hook_passage_angle_deg is not None:
            # a hook is the sewing machine's: its rotary hook meets the needle, in its own words
            clear = (
                f", {self.hook_point_clearance_mm:.3f} mm clear of the needle"
                if self.hook_point_clearance_mm is not None
                else ""
            )
            lines.append(
                f"hook point passes the needle at shaft angle {self.hook_passage_angle_deg:.2f} deg: needle "
                f"{self.tool_rise_at_passage_mm:.3f} mm above bottom dead centre, hook point "
                f"{self.hook_point_above_eye_mm:.3f} mm above the eye centre, "
                f"{self.hook_point_to_tool_axis_mm:.3f} mm from the needle axis" + clear
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


def tool_motion(machine=None, samples: int = 360, speed_rpm: float | None = None) -> ToolMotion:
    """The tool's motion of a machine (default: the shipped one) over one shaft revolution
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

    def tool_z_at(angle: float) -> float:
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
    tdc_z, bdc_z = tool_z_at(tdc), tool_z_at(bdc)

    # the hook timing needs the hook joint, the hook point's site and the tool eye's site
    hook_joint = (
        roles.hook_joint if roles.hook_point is not None and roles.eye is not None else None
    )
    has_hook = hook_joint is not None
    hook_angle = (
        np.degrees(tables.positions[hook_joint])
        if hook_joint is not None
        else np.full(samples, np.nan)
    )
    motion = ToolMotion(
        shaft_angle_deg=np.degrees(theta),
        tool_z_mm=z,
        tool_velocity_mm_per_rad=velocity,
        tool_acceleration_mm_per_rad2=acceleration,
        hook_angle_deg=hook_angle,
        hook_point_to_tool_mm=np.full(samples, np.nan),
        stroke_mm=tdc_z - bdc_z,
        tdc_angle_deg=math.degrees(tdc) if rocks else _signed_deg(tdc),
        bdc_angle_deg=math.degrees(bdc) if rocks else math.degrees(bdc) % 360.0,
        tdc_z_mm=tdc_z,
        bdc_z_mm=bdc_z,
        plate_reference=reference,
        speed_rpm=speed_rpm,
        notes=notes,
        zero_meaning=machine.zero_meaning,
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
    motion.hook_point_to_tool_mm = distances * 1000.0
    passage = hook.passage(theta, offsets, solve=pose_at)
    if passage is None:
        notes.append(
            "the hook point never passes the needle while the needle is at the hook's height"
        )
        return motion
    pose_at(passage)
    _, across = hook.offset_and_distance()
    motion.hook_passage_angle_deg = math.degrees(passage) % 360.0
    motion.tool_rise_at_passage_mm = (up @ data.site(roles.tip).xpos - plate_z) * 1000.0 - bdc_z
    motion.hook_point_to_tool_axis_mm = across * 1000.0
    motion.hook_point_above_eye_mm = (
        float(up @ (data.site(roles.hook_point).xpos - data.site(roles.eye).xpos)) * 1000.0
    )
    clearance = hook.clearance_to_tool_mesh()
    if clearance is None:
        notes.append(
            "no tool part mesh described ([tool] part): clearance to the needle surface not computed"
        )
    else:
        motion.hook_point_clearance_mm = clearance * 1000.0
    return motion


class _HookGeometry:
    """Hook point relative to the tool (needle) axis, in the plane normal to the hook axis."""

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
        """(signed angular offset of the hook point from the tool about the hook axis [rad],
        distance of the hook point from the tool axis, measured across the hook axis [m])."""
        axis, anchor, point, tip, eye = self._frames()
        tool_dir = (eye - tip) / np.linalg.norm(eye - tip)
        # the tool axis where it crosses the hook point's plane (normal to the hook axis)
        denom = tool_dir @ axis
        s = ((point - tip) @ axis) / denom if abs(denom) > 1e-9 else 0.0
        crossing = tip + s * tool_dir

        def planar(v):
            return v - (v @ axis) * axis

        a, b = planar(point - anchor), planar(crossing - anchor)
        offset = math.atan2(np.cross(b, a) @ axis, a @ b)
        return offset, float(np.linalg.norm(planar(point - crossing)))

    def tool_span(self) -> bool:
        """Is the hook point level with the tool (between its point and its butt)?"""
        axis, _, point, tip, eye = self._frames()
        return (point - tip) @ ((eye - tip) / np.linalg.norm(eye - tip)) > 0

    def passage(self, theta, offsets, solve) -> float | None:
        """The shaft angle where the hook point crosses the tool axis with the tool level
        with it; the crossing nearest to the tool when there are several."""
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
            if not self.tool_span():
                continue
            distance = self.offset_and_distance()[1]
            if best is None or distance < best[1]:
                best = (angle, distance)
        return None if best is None else best[0]

    def clearance_to_tool_mesh(self) -> float | None:
        """Exact distance [m] from the hook point to the tool part's surface (its mesh triangles)."""
        import mujoco

        from mechanism.inspection.shapes import PartShape

        if (
            self.roles.part is None
            or self.geom < 0
            or self.model.geom_type[self.geom] != mujoco.mjtGeom.mjGEOM_MESH
        ):
            return None
        tool = PartShape(self.model, self.roles.part)
        tool.update(self.data)
        return float(tool.point_distance(self.data.site(self.roles.hook_point).xpos)[0])


def _velocity_zero(theta: np.ndarray, velocity: np.ndarray, falling: bool) -> float:
    """Shaft angle where the (exact) tool velocity crosses zero: from + to - at the top
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
        raise UserError("the tool does not reciprocate over a shaft revolution")
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


def write_csv(motion: ToolMotion, path: str | os.PathLike, names: ColumnNames = "needle") -> Path:
    """The table over the revolution with the summary as ``#`` comment lines at its top:
    ``names="needle"`` (the default) writes the sewing machine's historical columns and header,
    exactly as ``mechanism needle`` always has; ``names="tool"`` the generic ones (``mechanism tool``)."""
    from mechanism.files.tables import write_table

    columns = motion.columns(names)
    if names == "needle":
        title = "needle motion over one arm revolution (arm angle 0 = needle top dead centre)"
    else:
        title = f"tool motion over one shaft revolution (shaft angle 0 = {motion.zero_meaning})"
    return write_table(path, columns, comments=[title, *motion.summary_lines()])


def plot(motion: ToolMotion, path: str | os.PathLike) -> None:
    """The tool's position, velocity and acceleration against the shaft angle, dead centres, the
    plate level and the hook passage marked."""
    from mechanism.files.plotting import plt, save_figure

    angle = motion.shaft_angle_deg
    per_speed = motion.speed_rpm is not None
    w = motion.shaft_speed_rad_s or 1.0
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 8.5))
    series = [
        (motion.tool_z_mm, "tool point [mm]"),
        (
            motion.tool_velocity_mm_per_rad
            * (w if per_speed else 1.0)
            / (1000.0 if per_speed else 1.0),
            "velocity [m/s]" if per_speed else "velocity [mm/rad]\n(mm/s per rad/s)",
        ),
        (
            motion.tool_acceleration_mm_per_rad2
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
    top.axhline(0.0, color="tab:brown", lw=2.0, alpha=0.6, label=motion.plate_reference)
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
        motion.hook_passage_angle_deg is not None and motion.tool_rise_at_passage_mm is not None
    ):  # set together
        z_pass = motion.bdc_z_mm + motion.tool_rise_at_passage_mm
        top.plot(
            [motion.hook_passage_angle_deg],
            [z_pass],
            "o",
            color="tab:red",
            label=(
                f"hook point passes: {motion.hook_passage_angle_deg:.1f}°, needle +"
                f"{motion.tool_rise_at_passage_mm:.2f} mm from BDC, {motion.hook_point_clearance_mm:.2f} mm clear"
                if motion.hook_point_clearance_mm is not None
                else f"hook point passes: {motion.hook_passage_angle_deg:.1f}°"
            ),
        )
    top.legend(loc="upper center", fontsize=8)
    top.set_title(
        f"Tool motion over one shaft revolution (stroke {motion.stroke_mm:.2f} mm"
        + (f", {motion.speed_rpm:g} rpm)" if per_speed else ")")
    )
    axes[-1].set_xlabel(f"shaft angle [deg] (0 = {motion.zero_meaning})")
    axes[-1].set_xlim(0, 360)
    axes[-1].set_xticks(range(0, 361, 45))
    fig.tight_layout()
    save_figure(fig, path)


# the sewing machine's names of this module's API (mechanism.inspection.needle re-exports them)
NeedleMotion = ToolMotion
needle_motion = tool_motion
DEPRECATED_ALIASES = {"NeedleMotion": "ToolMotion", "needle_motion": "tool_motion"}
