"""Small mechanisms with analytic answers, built through MjSpec (shared by the inspection tests).

- :func:`crank_and_post`: a cylinder on a crank (``arm_shaft``) sweeping past a fixed
  cylinder with parallel axes: centre distance sqrt(P² + ρ² - 2Pρ cos(θ - α)).
- :func:`needle_and_plate`: a slider-crank whose slider carries a pin (``needle``) that
  passes through a round hole in a fixed plate (``needle_plate``), with a lateral offset;
  a second pin (``hook``) on a 2:1 coupled shaft. Both are triangle meshes named and
  classed like the converter's output (visual + collision geoms, a site per part).
"""

from __future__ import annotations

import manifold3d
import mujoco
import numpy as np
import trimesh

SECTIONS = 512  # chordal error r (1 - cos(pi/512)) < 2e-5 r


def _mesh_from(vertices, faces, spec, name):
    spec.add_mesh(
        name=name,
        uservert=np.asarray(vertices, float).ravel().tolist(),
        userface=np.asarray(faces, int).ravel().tolist(),
    )


def _cylinder_y(radius, length, sections=SECTIONS):
    """A closed cylinder mesh with its axis along y, centred at the origin."""
    mesh = trimesh.creation.cylinder(radius=radius, height=length, sections=sections)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    return mesh.vertices, mesh.faces


def _add_part(body, spec, name, mesh, pos=(0, 0, 0), rgba=(0.7, 0.7, 0.75, 1), mass=0.01):
    """Geoms and a site named after the part, as the converter writes them: the collision
    geom ``<part>`` (group 3, marked for exact distance), the visual ``<part>_visual``."""
    body.add_geom(
        name=name,
        type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname=mesh,
        pos=list(pos),
        group=3,
        contype=0,
        conaffinity=0,
        mass=mass,
    )
    body.add_geom(
        name=f"{name}_visual",
        type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname=mesh,
        pos=list(pos),
        group=1,
        contype=0,
        conaffinity=0,
        rgba=list(rgba),
        mass=0,
    )
    body.add_site(name=name, pos=list(pos))


def crank_and_post(P=0.03, rho=0.012, r1=0.005, r2=0.004, alpha_deg=37.3, mesh=True):
    """Fixed cylinder ``post`` (radius r1) at x = P; cylinder ``pin`` (radius r2) on a crank
    of radius ρ turning about y with the driver ``arm_shaft``; closest at θ = α."""
    spec = mujoco.MjSpec()
    spec.option.gravity = [0, 0, -9.81]
    alpha = np.radians(alpha_deg)
    center = [rho * np.cos(alpha), 0.0, rho * np.sin(alpha)]
    post = spec.worldbody.add_body(name="post", pos=[P, 0, 0])
    crank = spec.worldbody.add_body(name="crank")
    crank.add_joint(name="arm_shaft", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
    crank.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.002, 0, 0], mass=0.1, contype=0, conaffinity=0
    )
    if mesh:
        _mesh_from(*_cylinder_y(r1, 0.02), spec, "post_mesh")
        _mesh_from(*_cylinder_y(r2, 0.02), spec, "pin_mesh")
        _add_part(post, spec, "post", "post_mesh")
        _add_part(crank, spec, "pin", "pin_mesh", pos=center)
    else:
        quat = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0]  # cylinder z axis -> y
        post.add_geom(
            name="post",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[r1, 0.01, 0],
            quat=quat,
            contype=0,
            conaffinity=0,
        )
        crank.add_geom(
            name="pin",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[r2, 0.01, 0],
            pos=center,
            quat=quat,
            contype=0,
            conaffinity=0,
        )
        post.add_site(name="post")
        crank.add_site(name="pin", pos=center)
    return spec


def crank_post_distance(theta, P=0.03, rho=0.012, r1=0.005, r2=0.004, alpha_deg=37.3):
    return np.sqrt(P**2 + rho**2 - 2 * P * rho * np.cos(theta - np.radians(alpha_deg))) - r1 - r2


# slider-crank dimensions [m]
R, L = 0.0165, 0.05
PLATE_TOP = 0.02  # needle-plate top surface height
TIP_BELOW_BAR = 0.0365  # needle tip below the needle-bar origin: tip 10 mm above the plate at TDC, 23 mm below at BDC
# needle 0.2 mm off the hole centre: 0.3 mm clearance
NEEDLE_RADIUS, HOLE_RADIUS, OFFSET = (
    0.0006,
    0.0011,
    0.0002,
)
# scarf from 2 mm to 4.5 mm above the tip, 0.3 mm deep on the hook side (-y)
SCARF = (
    0.002,
    0.0045,
    0.0003,
)
HOOK_PASS_DEG = 195.0  # the hook point passes the needle 15 deg after BDC
HOOK_RADIUS, HOOK_POINT_RADIUS, HOOK_GAP = 0.003, 0.0003, 0.0001  # 0.1 mm from the scarf bottom


def needle_tip_z(theta):
    """Analytic height of the needle tip [m] (world z) over the arm angle."""
    return R * np.cos(theta) + np.sqrt(L**2 - (R * np.sin(theta)) ** 2) - TIP_BELOW_BAR


def needle_tip_dz(theta):
    """d(tip z)/dθ [m/rad]."""
    s, c = np.sin(theta), np.cos(theta)
    return -R * s - R**2 * s * c / np.sqrt(L**2 - (R * s) ** 2)


def needle_tip_d2z(theta):
    """d²(tip z)/dθ² [m/rad²]."""
    s, c = np.sin(theta), np.cos(theta)
    root = np.sqrt(L**2 - (R * s) ** 2)
    return -R * c - R**2 * (c * c - s * s) / root - R**4 * s * s * c * c / root**3


def _plate_with_hole():
    plate = manifold3d.Manifold.cube([0.04, 0.04, 0.002], center=True)
    hole = manifold3d.Manifold.cylinder(0.004, HOLE_RADIUS, HOLE_RADIUS, SECTIONS, center=True)
    mesh = (plate - hole).to_mesh()
    return np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts)


def _needle():
    """Needle along z from the tip (z = 0) up 30 mm, with a scarf on its -y side."""
    body = manifold3d.Manifold.cylinder(0.03, NEEDLE_RADIUS, NEEDLE_RADIUS, SECTIONS)
    low, high, depth = SCARF
    cut = manifold3d.Manifold.cube([0.004, 0.002, high - low]).translate(
        [-0.002, -0.002 - NEEDLE_RADIUS + depth, low]
    )
    mesh = (body - cut).to_mesh()
    return np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts)


def _hook_point():
    point = manifold3d.Manifold.cylinder(
        0.0006, HOOK_POINT_RADIUS, HOOK_POINT_RADIUS, SECTIONS, center=True
    )
    mesh = point.to_mesh()
    return np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts)


def needle_and_plate(hook_offset_deg=0.0, rod_mass=0.02, slider_mass=0.05):
    """A sewing-machine-like slider-crank built like the converter's output.

    ``crank`` turns about y on ``arm_shaft``; ``rod`` hangs on it at the ``crank_pin``
    hinge; the needle bar (body and part ``needle_bar``) slides along z on its
    ``needle_bar`` joint, 0.2 mm off the plate's hole axis in x, and is closed to the rod
    by two connects ``loop:rod_end:a``/``:b``. The ``needle`` part (with a scarf) hangs
    below the bar, site ``needle_tip`` at its point, and passes through the hole of the
    fixed ``needle_plate``. The ``hook`` turns about z at twice the arm speed
    (``coupling:hook_drive``) and its point passes the scarf 0.1 mm away at 195°;
    ``hook_offset_deg`` advances the hook (mistiming).
    """
    spec = mujoco.MjSpec()
    spec.option.gravity = [0, 0, -9.81]
    _mesh_from(*_plate_with_hole(), spec, "plate_mesh")
    _mesh_from(*_needle(), spec, "needle_mesh")
    _mesh_from(*_hook_point(), spec, "hook_mesh")
    y_axis = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0]

    crank = spec.worldbody.add_body(name="crank")
    crank.add_joint(name="arm_shaft", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
    crank.add_geom(
        name="crank",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[0.02, 0.003, 0],
        quat=y_axis,
        mass=0.2,
        contype=0,
        conaffinity=0,
        group=1,
    )
    crank.add_site(name="crank")
    crank.add_site(name="crank_pin_center", pos=[0, 0, R])
    rod = crank.add_body(name="rod", pos=[0, 0, R])
    rod.add_joint(name="crank_pin", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
    rod.add_geom(
        name="rod",
        type=mujoco.mjtGeom.mjGEOM_CAPSULE,
        fromto=[0, 0, 0, 0, 0, L],
        size=[0.003, 0, 0],
        mass=rod_mass,
        contype=0,
        conaffinity=0,
        group=1,
    )
    rod.add_site(name="rod")

    bar = spec.worldbody.add_body(name="needle_bar", pos=[OFFSET, 0, R + L])
    bar.add_joint(name="needle_bar", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1])
    bar.add_geom(
        name="needle_bar",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[0.004, 0.01, 0],
        mass=slider_mass,
        contype=0,
        conaffinity=0,
        group=1,
    )
    bar.add_site(name="needle_bar")
    _add_part(bar, spec, "needle", "needle_mesh", pos=(0, 0, -TIP_BELOW_BAR), mass=1e-4)
    bar.add_site(name="needle_tip", pos=[0, 0, -TIP_BELOW_BAR])

    plate = spec.worldbody.add_body(name="needle_plate", pos=[0, 0, PLATE_TOP - 0.001])
    _add_part(plate, spec, "needle_plate", "plate_mesh")

    # hook point level: the middle of the scarf when the hook passes
    level = needle_tip_z(np.radians(HOOK_PASS_DEG)) + 0.5 * (SCARF[0] + SCARF[1])
    axis_y = -(NEEDLE_RADIUS - SCARF[2]) - HOOK_GAP - HOOK_POINT_RADIUS - HOOK_RADIUS
    hook = spec.worldbody.add_body(name="hook_body", pos=[OFFSET, axis_y, level])
    hook.add_joint(name="hook", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    hook.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[0.001, 0, 0],
        mass=0.01,
        contype=0,
        conaffinity=0,
        group=1,
    )
    _add_part(hook, spec, "hook", "hook_mesh", pos=(HOOK_RADIUS, 0, 0))
    hook.add_site(name="hook_point", pos=[HOOK_RADIUS + HOOK_POINT_RADIUS, 0, 0])

    spec.add_equality(
        name="loop:rod_end:a",
        type=mujoco.mjtEq.mjEQ_CONNECT,
        objtype=mujoco.mjtObj.mjOBJ_BODY,
        name1="rod",
        name2="needle_bar",
        data=[0, 0.01, L] + [0] * 9,
    )
    spec.add_equality(
        name="loop:rod_end:b",
        type=mujoco.mjtEq.mjEQ_CONNECT,
        objtype=mujoco.mjtObj.mjOBJ_BODY,
        name1="rod",
        name2="needle_bar",
        data=[0, -0.01, L] + [0] * 9,
    )
    # hook angle = 2 arm angle + offset; the point faces the needle (+y) at 2*195 + offset = 90 (mod 360)
    offset = np.radians(90.0 - 2 * HOOK_PASS_DEG + hook_offset_deg)
    spec.add_equality(
        name="coupling:hook_drive",
        type=mujoco.mjtEq.mjEQ_JOINT,
        objtype=mujoco.mjtObj.mjOBJ_JOINT,
        name1="hook",
        name2="arm_shaft",
        data=[offset, 2.0, 0, 0, 0] + [0] * 7,
    )
    return spec
