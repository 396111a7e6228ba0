"""Headless meshcat viewer: the machine's motion as a self-contained HTML animation.

The scene is built with meshcat's own Python objects (geometry, materials, animation
clips) and the commands that a meshcat server would forward to a browser are recorded
instead (:class:`_Recorder`), then embedded in one HTML file next to meshcat's viewer
bundle: it opens in any browser with no server and no network. ``--serve`` sends the
same commands to a live meshcat server on localhost instead.

What is shown: every visual geom (the converter's class ``visual``, group 1; all geoms of
hand-written models) with its MJCF colour (``geom_rgba``, or its material's; parts fixed
to the world, such as the casting, translucent so the mechanism shows), grouped per
body so that one animated transform per body moves everything on it; probe markers (small
spheres on their parts, moving with them); for clearance pairs, markers at the two
closest points of each part and a line between them drawn where they are at the minimum.

Motion sources: a kinematic cycle (one shaft revolution), a dynamic simulation (the
simulated joint positions), or a recording (the identification CSV contract: ``time``,
``voltage``, ``arm_angle``), replayed kinematically through the pose solver.
"""

from __future__ import annotations

import base64
import contextlib
import itertools
import json
import os
from dataclasses import dataclass, field
from importlib import resources
from typing import Sequence

import mujoco
import numpy as np

from mechanism.machine import parts
from mechanism.errors import UserError

DEFAULT_FRAMES = 120
VIEW_SECTIONS = 32  # tessellation of primitive geoms in the viewer
# the model is scaled to about this size [viewer units] to suit meshcat's default camera
TARGET_SIZE = 1.5
FRAME_OPACITY = 0.3  # parts fixed to the world are drawn translucent
MARKER_COLORS = (0xE6194B, 0x3CB44B, 0x4363D8, 0xF58231, 0x911EB4, 0x42D4F4)


@dataclass
class Motion:
    """Joint positions to animate, one row per frame, and the frame times [s]."""

    time_s: np.ndarray
    qpos: np.ndarray
    description: str
    realtime: bool = True  # play at the recorded speed (else slowed to a readable 4 s)


def _check_frames(frames: int) -> None:
    if not 2 <= frames <= 20_000:
        raise UserError(f"frames must be between 2 and 20000, got {frames}")


def cycle_motion(
    model: mujoco.MjModel, frames: int = DEFAULT_FRAMES, driver: str | None = None, description=None
) -> Motion:
    """One revolution of ``driver`` in ``frames`` frames (the last one back at the start); a
    driver that rocks goes from the lower end of its travel to the upper and back."""
    from mechanism.kinematics.pose import approach, named_joint, sweep
    from mechanism.machine.machine import inspection_travel

    _check_frames(frames)
    driver = named_joint(driver)
    travel = inspection_travel(model, driver, description)
    if travel.rotates:
        angles = np.linspace(0.0, 2 * np.pi, frames)
        return Motion(
            angles / (2 * np.pi),
            sweep(model, angles, driver),
            f"one {driver} revolution",
            realtime=False,
        )
    phase = np.linspace(0.0, 1.0, frames)
    angles = travel.lower + (travel.upper - travel.lower) * (1.0 - np.cos(2 * np.pi * phase)) / 2
    data = mujoco.MjData(model)
    approach(model, data, driver, float(angles[0]))
    return Motion(
        phase, sweep(model, angles, driver, data), f"{travel.text()} and back", realtime=False
    )


def recording_motion(
    model: mujoco.MjModel,
    path: str | os.PathLike,
    frames: int = DEFAULT_FRAMES,
    driver: str | None = None,
    zero_rad: float = 0.0,
    direction: float = 1.0,
) -> Motion:
    """A bench recording (``time``, ``voltage``, ``shaft_angle`` or ``arm_angle`` [rad, from the
    shaft's zero]) replayed kinematically at ``frames`` evenly spaced times; the driver joint's
    position is ``zero_rad + direction * angle``."""
    from mechanism.kinematics.pose import named_joint, solve_pose
    from mechanism.files.tables import check_increasing, read_table

    _check_frames(frames)
    table = read_table(
        path,
        required=["time", "arm_angle"],
        optional=["voltage"],
        aliases={
            "time": ["time_s"],
            "arm_angle": ["arm_angle_rad", "shaft_angle", "shaft_angle_rad"],
            "voltage": ["voltage_V"],
        },
        min_rows=2,
        what="recording",
    )
    time, angle = table["time"], table["arm_angle"]
    check_increasing(time, table.source)
    times = np.linspace(time[0], time[-1], frames)
    angles = zero_rad + direction * np.interp(times, time, angle)
    driver = named_joint(driver)
    data = mujoco.MjData(model)
    qpos = []
    # walk from angle 0 in small steps so that the assembly stays on its branch
    previous = zero_rad
    for target in angles:
        for step in np.linspace(previous, target, max(2, int(abs(target - previous) / 0.1) + 2))[
            1:
        ]:
            solve_pose(model, data, {driver: float(step)})
        previous = float(target)
        qpos.append(data.qpos.copy())
    return Motion(times - times[0], np.asarray(qpos), f"recording {os.path.basename(str(path))}")


def simulation_motion(
    voltage: float, duration_s: float, frames: int = DEFAULT_FRAMES, description=None
) -> tuple[mujoco.MjModel, Motion]:
    """A dynamic simulation from rest under ``voltage`` (the main motor's, or joint -> input): its
    joint positions at ``frames`` times."""
    from mechanism.machine.machine import input_unit

    from mechanism.machine.machine import Machine
    from mechanism.dynamics.simulation import simulate

    _check_frames(frames)
    machine = Machine(description)
    result = simulate(voltage, duration_s, machine=machine, progress=True)
    picks = np.linspace(0, len(result.time_s) - 1, frames).round().astype(int)
    assert result.state is not None  # the full model's simulate() keeps every sample's state
    qpos = result.state[picks, 1 : 1 + machine.model.nq]
    how = (
        f"{voltage:g} V"
        if not isinstance(voltage, dict)
        else ", ".join(
            f"{joint} {value:g} {unit}"
            for joint, value, unit in (
                (j, v, input_unit(machine.description, j)) for j, v in voltage.items()
            )
        )
    )
    return machine.model, Motion(result.time_s[picks], qpos, f"simulation at {how}")


# -- the scene -------------------------------------------------------------------------------


def _meshcat():
    """meshcat, imported without the deprecation warning its server module raises on pyzmq >= 17."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import meshcat
        import meshcat.servers.zmqserver  # noqa: F401
    return meshcat


class _Recorder:
    """Stands in for meshcat's ZMQ window: keeps every command, packed as the server would."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command) -> None:
        import umsgpack

        self.commands.append(umsgpack.packb(command.lower()))


def _color(model: mujoco.MjModel, geom: int) -> tuple[int, float]:
    rgba = model.geom_rgba[geom]
    material = model.geom_matid[geom]
    if material >= 0 and np.allclose(
        rgba, [0.5, 0.5, 0.5, 1.0]
    ):  # MuJoCo's default: the material decides
        rgba = model.mat_rgba[material]
    r, g, b = (int(round(255 * float(np.clip(c, 0, 1)))) for c in rgba[:3])
    return (r << 16) | (g << 8) | b, float(rgba[3])


def _transform(position, rotation) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3] = np.asarray(rotation).reshape(3, 3)
    matrix[:3, 3] = position
    return matrix


def _shown_geoms(model: mujoco.MjModel) -> list[int]:
    visual = [g for g in range(model.ngeom) if model.geom_group[g] == parts.VISUAL_GROUP]
    if not visual:
        visual = [g for g in range(model.ngeom) if model.geom_group[g] < 3]
    return [
        g
        for g in visual
        if model.geom_type[g]
        not in (
            mujoco.mjtGeom.mjGEOM_PLANE,
            mujoco.mjtGeom.mjGEOM_HFIELD,
            mujoco.mjtGeom.mjGEOM_SDF,
        )
    ]


@dataclass
class Marker:
    """A small sphere fixed to a body at a point of the body frame [m]."""

    name: str
    body: int
    point: np.ndarray
    color: int


@dataclass
class Overlays:
    markers: list[Marker] = field(default_factory=list)
    # name, world points [m]
    lines: list[tuple[str, np.ndarray, np.ndarray]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@contextlib.contextmanager
def _reproducible_ids():
    """meshcat names every scene element with ``uuid.uuid1()`` (the clock and the host): the
    same scene wrote a different file at every run. Counted ids instead, while one scene is
    built, so that the same inputs give the same bytes."""
    import types
    import uuid

    import meshcat.geometry

    counter = itertools.count(1)
    original = meshcat.geometry.uuid
    meshcat.geometry.uuid = types.SimpleNamespace(uuid1=lambda: uuid.UUID(int=next(counter)))
    try:
        yield
    finally:
        meshcat.geometry.uuid = original


def build_scene(
    model: mujoco.MjModel, motion: Motion, overlays: Overlays | None = None, visualizer=None
):
    """Send the scene and its animation to a meshcat ``visualizer`` (a recorder by default);
    returns the visualizer."""
    with _reproducible_ids():
        return _build_scene(model, motion, overlays, visualizer)


def _build_scene(model, motion, overlays, visualizer):
    meshcat = _meshcat()
    import meshcat.geometry as g
    from meshcat.animation import Animation

    from mechanism.inspection.shapes import geom_mesh

    overlays = overlays or Overlays()
    vis = visualizer or meshcat.Visualizer(window=_Recorder())
    data = mujoco.MjData(model)
    data.qpos[:] = motion.qpos[0]
    mujoco.mj_kinematics(model, data)

    # everything under one root that centres and scales the model for meshcat's camera
    shown = _shown_geoms(model)
    if not shown:
        raise UserError("the model has no visual geometry to show")
    placed_vertices = []
    for geom in shown:
        vertices, _ = geom_mesh(model, geom, VIEW_SECTIONS)
        placed_vertices.append(
            vertices @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]
        )
    points = np.vstack(placed_vertices)
    low, high = points.min(axis=0), points.max(axis=0)
    scale = TARGET_SIZE / max(float(np.max(high - low)), 1e-9)
    root = np.diag([scale, scale, scale, 1.0])
    root[:3, 3] = -scale * 0.5 * (low + high)
    vis["/Grid"].set_property("visible", False)
    vis["/Axes"].set_property("visible", False)
    # from the operator's side (-y), a little above
    vis["/Cameras/default/rotated/<object>"].set_property("position", [0.0, 0.6, 1.9])
    scene = vis["mechanism"]
    scene.set_transform(root)

    bodies = sorted(
        {int(model.geom_bodyid[geom]) for geom in shown} | {m.body for m in overlays.markers}
    )
    for geom in shown:
        body = int(model.geom_bodyid[geom])
        vertices, faces = geom_mesh(model, geom, VIEW_SECTIONS)
        color, opacity = _color(model, geom)
        if (
            model.body_weldid[body] == 0
        ):  # the fixed frame (casting, plates): see the mechanism through it
            opacity = min(opacity, FRAME_OPACITY)
        material = g.MeshLambertMaterial(color=color, opacity=opacity, transparent=opacity < 1)
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or f"geom{geom}"
        node = scene[_body_path(model, body)][name]
        node.set_object(g.TriangularMeshGeometry(vertices, faces), material)
        quat_matrix = np.zeros(9)
        mujoco.mju_quat2Mat(quat_matrix, model.geom_quat[geom])
        node.set_transform(_transform(model.geom_pos[geom], quat_matrix))
    radius = 0.006 / scale * TARGET_SIZE / 1.5  # about 0.6 % of the view
    for marker in overlays.markers:
        node = scene[_body_path(model, marker.body)][f"marker:{marker.name}"]
        node.set_object(g.Sphere(radius), g.MeshLambertMaterial(color=marker.color))
        node.set_transform(_transform(marker.point, np.eye(3)))
    for name, start, end in overlays.lines:
        vertices = np.column_stack([start, end]).astype(np.float32)
        scene[f"line:{name}"].set_object(
            g.Line(g.PointsGeometry(vertices), g.LineBasicMaterial(color=0xFF0000, linewidth=3))
        )

    animation = Animation(default_framerate=_framerate(motion))
    for frame, qpos in enumerate(motion.qpos):
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        with animation.at_frame(scene, frame) as at:
            for body in bodies:
                at[_body_path(model, body)].set_transform(
                    _transform(data.xpos[body], data.xmat[body])
                )
    vis.set_animation(animation, play=True, repetitions=1_000_000)
    return vis


def _body_path(model, body: int) -> str:
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body) or f"body{body}"
    return f"body:{name}"


def _framerate(motion: Motion) -> float:
    frames = len(motion.time_s)
    span = float(motion.time_s[-1] - motion.time_s[0])
    if motion.realtime and span > 0:
        return max(1.0, (frames - 1) / span)
    return max(1.0, (frames - 1) / 4.0)  # a cycle plays in 4 s


def static_html(vis, title: str, frames: int, notes: Sequence[str] = ()) -> str:
    """One HTML page with meshcat's viewer and the recorded scene; no server, no network.

    ``document.body.dataset`` carries ``frames`` (keyframes of the longest animation
    track, as loaded by the viewer) and ``ready`` once every command has been handled."""
    bundle = (
        resources.files("meshcat").joinpath("viewer/dist/main.min.js").read_text(encoding="utf-8")
    )
    commands = json.dumps([base64.b64encode(c).decode("ascii") for c in vis.window.commands])
    caption = "<br>".join(_escape(n) for n in [title, *notes])
    return f"""<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>{_escape(title)}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
#caption {{ position: absolute; left: 10px; bottom: 10px; font: 13px sans-serif; color: #222;
           background: rgba(255,255,255,0.75); padding: 4px 8px; border-radius: 4px; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="caption">{caption}</div>
<script>
{bundle}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var commands = {commands};
for (const text of commands) {{
  const raw = atob(text);
  const bytes = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
  viewer.handle_command_bytearray(bytes);
}}
var frames = 0;
for (const action of viewer.animator.actions) {{
  for (const track of action.getClip().tracks) frames = Math.max(frames, track.times.length);
}}
document.body.dataset.frames = String(frames);
document.body.dataset.expectedFrames = "{frames}";
document.body.dataset.ready = "true";
</script>
</body>
</html>
"""


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


# -- overlays ------------------------------------------------------------------------------


def probe_markers(
    model: mujoco.MjModel, names: Sequence[str], points_mm: Sequence | None = None
) -> list[Marker]:
    """Markers at probe points (part/frame names, optional points [mm] in their frames)."""
    markers = []
    for i, name in enumerate(names):
        frame = parts.find_frame(model, name)
        point = np.asarray(points_mm[i] if points_mm else (0, 0, 0), dtype=float) / 1000.0
        markers.append(
            Marker(
                f"probe:{name}",
                frame.body,
                frame.point_in_body(point),
                MARKER_COLORS[i % len(MARKER_COLORS)],
            )
        )
    return markers


def clearance_overlays(model: mujoco.MjModel, results, driver: str) -> Overlays:
    """Markers at the closest points of each checked pair, fixed to their parts, and a
    line between them at the minimum."""
    from mechanism.kinematics.pose import sweep

    overlays = Overlays()
    data = mujoco.MjData(model)
    for k, result in enumerate(results):
        angle = np.radians(
            result.angle_deg if result.driver_angle_deg is None else result.driver_angle_deg
        )
        data.qpos[:] = sweep(
            model, np.linspace(0, angle, max(2, int(abs(angle) / 0.1) + 2)), driver
        )[-1]
        mujoco.mj_kinematics(model, data)
        color = MARKER_COLORS[(k + 3) % len(MARKER_COLORS)]
        for part, point in ((result.pair.a, result.point_a_mm), (result.pair.b, result.point_b_mm)):
            body = int(model.geom_bodyid[parts.shape_geoms(model, part)[0]])
            local = data.xmat[body].reshape(3, 3).T @ (np.asarray(point) / 1000.0 - data.xpos[body])
            overlays.markers.append(
                Marker(f"closest:{result.pair.label}:{part}", body, local, color)
            )
        overlays.lines.append(
            (
                result.pair.label,
                np.asarray(result.point_a_mm) / 1000.0,
                np.asarray(result.point_b_mm) / 1000.0,
            )
        )
        overlays.notes.append(
            f"{result.pair.label}: min {result.min_distance_mm:.3f} mm at {result.angle_deg:.1f} deg"
        )
    return overlays


# -- the one call the CLI makes ------------------------------------------------------------


def view(
    html: str | os.PathLike | None = None,
    model_path: str | os.PathLike | None = None,
    voltage: float | None = None,
    duration_s: float | None = None,
    recording: str | os.PathLike | None = None,
    frames: int = DEFAULT_FRAMES,
    probe_names: Sequence[str] = (),
    pairs: str | Sequence[str] | None = None,
    serve: bool = False,
    driver: str | None = None,
    description=None,
) -> dict:
    """Animate the model (cycle by default, else a simulation or a recording) and write a
    self-contained HTML file and/or serve it live. Returns a summary."""
    from mechanism.machine.models import load_model
    from mechanism.files.outputs import atomic_file

    if html is None and not serve:
        raise UserError("nothing to do: give an HTML output file and/or serve")
    if (voltage is None) != (duration_s is None):
        raise UserError("a simulated motion needs both a voltage and a duration")
    if voltage is not None and recording is not None:
        raise UserError("choose one motion: a simulation (voltage, duration) or a recording")
    if voltage is not None and duration_s is not None:  # both or neither, checked above
        model, motion = simulation_motion(voltage, duration_s, frames, description)
    elif recording:
        from mechanism.machine.machine import Machine

        machine = Machine(description)
        model = machine.model
        motion = recording_motion(
            model,
            recording,
            frames,
            machine.shaft_joint,
            machine.frame.zero_rad,
            machine.frame.direction,
        )
    else:
        model = load_model(model_path)
        motion = cycle_motion(model, frames, driver, description)
    overlays = Overlays(markers=probe_markers(model, list(probe_names)))
    if pairs:
        from mechanism.inspection.clearance import check_clearance, parse_pairs

        report = check_clearance(
            model, parse_pairs(pairs, model), driver=driver, description=description
        )
        extra = clearance_overlays(model, report.results, report.driver)
        overlays.markers += extra.markers
        overlays.lines += extra.lines
        overlays.notes += extra.notes
    title = f"mechanism: {os.path.basename(str(model_path or getattr(description, 'name', 'machine')))}, {motion.description}"
    summary = {"frames": len(motion.qpos), "title": title, "notes": overlays.notes}
    if html is not None:
        vis = build_scene(model, motion, overlays)
        with atomic_file(html) as handle:
            handle.write(static_html(vis, title, len(motion.qpos), overlays.notes))
        summary["html"] = str(html)
    if serve:
        live = _meshcat().Visualizer()
        build_scene(model, motion, overlays, live)
        summary["url"] = live.url()
    return summary
