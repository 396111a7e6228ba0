"""The one writer: an :class:`~converters.assembly.Assembly` and its kinematic :class:`~converters.tree.Plan`
become an MJCF model through ``mujoco.MjSpec`` (never by building XML text).

Conventions (docs/architecture.md): one body per rigid group, named after its root-most part;
per part a collision geom ``<part>`` (class ``collision``), a visual geom ``<part>_visual``
(class ``visual``) and a site ``<part>`` at the part frame; user-named CAD frames become sites;
joints keep the export's names; loop closures are ``loop:<joint>`` equalities and couplings
``coupling:<name>`` joint equalities. Body masses and inertias come from the export; geoms
carry no mass (``inertiafromgeom="false"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import mujoco
import numpy as np

from mechanism.converters import inertia as mass_properties
from mechanism.converters.assembly import BALL, GROUND, HINGE, SLIDE, Assembly, Coupling, Joint
from mechanism.converters.errors import ExportError
from mechanism.converters.geometry import Mesh
from mechanism.converters.names import Namer
from mechanism.converters.pose import Pose
from mechanism.converters.tree import Plan
from mechanism.tolerances import MIN_LENT_MASS_KG, MIN_MOMENT

TIMESTEP_S = 0.0005
INTEGRATOR = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
# Equality constraints (loops, couplings): time constant 2 x timestep (the stiffest MuJoCo accepts),
# critically damped, impedance near 1. A slider-crank at 120 rpm stays on its analytic stroke to
# 0.01% (tests/test_closed_chain.py); faster machines need a smaller timestep with solref = 2 x timestep.
EQUALITY_SOLREF = (2 * TIMESTEP_S, 1.0)
EQUALITY_SOLIMP = (0.99, 0.999, 0.0001, 0.5, 2.0)
CARRIER_MASS_FRACTION = 0.1  # of the follower body's mass properties, lent to a loop's carrier body
LIGHT_CARRIER_FRACTION = 1e-3  # of a donor's mass when the follower has none to share
MISSING_MASS_FRACTION = 1e-3  # a massless moving body gets this fraction of the lightest real part (lent by a neighbour)
# revolute closures: connect points this fraction of the model size apart
LOOP_SPACING_FRACTION = 0.1
LOOP_SPACING_LIMITS_M = (0.005, 0.1)
SIGNIFICANT_DIGITS = 10  # every number written is rounded: bytes do not depend on last-bit noise

KIND_NAMES = {HINGE: "hinge", SLIDE: "slide", BALL: "ball"}
JOINT_TYPES = {
    HINGE: mujoco.mjtJoint.mjJNT_HINGE,
    SLIDE: mujoco.mjtJoint.mjJNT_SLIDE,
    BALL: mujoco.mjtJoint.mjJNT_BALL,
}


def _r(values):
    """Round to a fixed number of significant digits (and turn -0.0 into 0.0)."""
    array = np.asarray(values, dtype=float)
    rounded = np.array([float(f"{v:.{SIGNIFICANT_DIGITS}g}") + 0.0 for v in array.ravel()])
    return rounded.reshape(array.shape).tolist() if array.shape else float(rounded[0])


def _quat(rotation: np.ndarray) -> list:
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).ravel())
    if quat[0] < 0:
        quat = -quat
    return _r(quat)


def _floored(inertia):
    """(inertia, moments or None, floor): ``inertia`` with its principal moments raised to the floor
    a moving MuJoCo body needs (and the triangle inequality restored); ``moments`` are the original
    principal moments when a repair was needed, else None."""
    moments, _ = mass_properties.principal(inertia)
    floor = max(MIN_MOMENT, 1e-9 * moments[2])
    if moments[0] < floor or moments[0] + moments[1] < moments[2]:
        return mass_properties.clamp_to_physical(inertia, floor), moments, floor
    return np.asarray(inertia, dtype=float), None, floor


def _set_inertial(element, props, pose: Pose) -> None:
    """Explicit mass, centre of mass and full inertia of a spec body whose frame is ``pose``."""
    rotation = pose.rotation.T
    local = rotation @ props.inertia @ rotation.T
    element.explicitinertial = True
    element.mass = _r(props.mass)
    element.ipos = _r(rotation @ (props.com - pose.position))
    element.fullinertia = _r(
        [local[0, 0], local[1, 1], local[2, 2], local[0, 1], local[0, 2], local[1, 2]]
    )


def _take_mass(element, mass: float) -> None:
    """Lend ``mass`` out of a spec body: its mass and inertia shrink in proportion, its centre of
    mass stays (the density scales down by a part in a thousand or less)."""
    total = float(element.mass)
    scale = (total - mass) / total
    element.mass = _r(total - mass)
    element.fullinertia = _r(np.asarray(element.fullinertia, dtype=float) * scale)
    inertia = np.asarray(element.inertia, dtype=float)
    if np.any(inertia):
        element.inertia = _r(inertia * scale)


@dataclass
class Built:
    """The spec and what the report needs to know about it."""

    spec: mujoco.MjSpec
    joint_names: dict[str, list[str]] = field(default_factory=dict)  # export joint -> MJCF joints
    joints_by_type: dict[str, int] = field(
        default_factory=lambda: {"hinge": 0, "slide": 0, "ball": 0, "free": 0}
    )
    n_bodies: int = 0
    n_closures: int = 0
    n_couplings: int = 0
    warnings: list[str] = field(default_factory=list)


def compound_names(name: str, primitives) -> list[str]:
    """MJCF joint names for one CAD joint: the name itself for one primitive, else
    ``<name>_<hinge|slide|ball>`` with a counter when a kind repeats (planar: ``_slide1``, ``_slide2``, ``_hinge``)."""
    if len(primitives) == 1:
        return [name]
    kinds = [KIND_NAMES[p.kind] for p in primitives]
    counts = {k: kinds.count(k) for k in kinds}
    seen: dict[str, int] = {}
    names = []
    for kind in kinds:
        seen[kind] = seen.get(kind, 0) + 1
        names.append(f"{name}_{kind}{seen[kind]}" if counts[kind] > 1 else f"{name}_{kind}")
    return names


class _Writer:
    def __init__(
        self,
        assembly: Assembly,
        plan: Plan,
        meshes: dict[str, Mesh | None],
        model_name: str,
        meshdir: str,
    ):
        self.assembly, self.plan, self.meshes = assembly, plan, meshes
        self.spec = mujoco.MjSpec()
        self.built = Built(spec=self.spec)
        self.spec.modelname = model_name
        self.spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
        # only float-level A + B < C is left after the repairs here
        self.spec.compiler.balanceinertia = True
        self.spec.compiler.meshdir = meshdir
        self.spec.option.timestep = TIMESTEP_S
        self.spec.option.integrator = INTEGRATOR
        self.spec.default.equality.solref = list(EQUALITY_SOLREF)
        self.spec.default.equality.solimp = list(EQUALITY_SOLIMP)
        self.visual = self.spec.add_default("visual", self.spec.default)
        self.visual.geom.contype = 0
        self.visual.geom.conaffinity = 0
        self.visual.geom.group = 1
        self.collision = self.spec.add_default("collision", self.spec.default)
        self.collision.geom.group = 3

        real = assembly.real_parts
        part_namer = Namer()
        self.part_names = {part.key: part_namer(part.name) for part in real}
        joint_namer = Namer()
        self.joint_names = {id(j): joint_namer(j.name) for j in assembly.joints if not j.synthetic}
        self.body_namer = Namer(reserved={"world"})
        self.geom_namer = Namer(reserved=self.part_names.values())
        self.site_namer = Namer(reserved=self.part_names.values())
        self.mjcf_joint_namer = Namer()
        self.equality_namer = Namer()
        self.spec_bodies: dict[int, mujoco.MjsBody] = {}
        self.body_names: dict[int, str] = {}
        self.body_poses: dict[int, Pose] = {}
        self.body_moves: dict[int, bool] = {}
        self.loop_spacing = self._loop_spacing()
        self.massless: list[
            tuple
        ] = []  # (plan body, spec body, pose) of moving bodies without mass

    # -- helpers -----------------------------------------------------------------------------
    def _loop_spacing(self) -> float:
        located = [p.com for p in self.assembly.real_parts] + [
            j.follower_frame.position for j in self.assembly.joints
        ]
        points = np.array(located) if located else np.zeros((1, 3))
        size = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
        low, high = LOOP_SPACING_LIMITS_M
        return float(np.clip(LOOP_SPACING_FRACTION * size, low, high))

    def _root_part(self, body) -> str | None:
        """The root-most real part, skipping massless, geometry-less helpers (gen-1 ``RootPart``)."""
        real = [k for k in body.parts if k != GROUND and not self.assembly.parts[k].virtual]
        solid = [
            k
            for k in real
            if self.assembly.parts[k].mass > 0 or self.assembly.parts[k].geometry is not None
        ]
        return (solid or real or [None])[0]

    def _body_pose(self, body) -> Pose:
        root = self._root_part(body)
        rotation = self.assembly.parts[root].frame.rotation if root else np.eye(3)
        if body.joint is not None:
            anchor = body.joint.base_frame if body.reversed else body.joint.follower_frame
            return Pose(rotation, anchor.position)
        if root:
            return self.assembly.parts[root].frame
        virtual = next((k for k in body.parts if k != GROUND), None)
        return self.assembly.parts[virtual].frame if virtual else Pose()

    def _body_label(self, body) -> str:
        root = self._root_part(body)
        if root:
            return self.part_names[root]
        virtual = next((k for k in body.parts if k != GROUND), None)
        return self.assembly.parts[virtual].name if virtual else "ground"

    def _set_pose(self, element, pose: Pose, parent: Pose) -> None:
        local = pose.relative_to(parent)
        element.pos = _r(local.position)
        element.quat = _quat(local.rotation)

    # -- bodies ------------------------------------------------------------------------------
    def write(self) -> Built:
        for body in self.plan.depth_first():
            self._body(body)
        self._lend_masses()
        for closure in self.plan.closures:
            self._closure(closure)
        self._couplings()
        return self.built

    def _is_free(self, body) -> bool:
        joint = body.joint
        if joint is None or body.parent is None or not self.plan.bodies[body.parent].is_ground:
            return False
        return [p.kind for p in joint.primitives] == [SLIDE, SLIDE, SLIDE, BALL]

    def _body(self, body) -> None:
        ground = body.index == 0
        has_parts = any(k != GROUND for k in body.parts)
        if ground and not has_parts:
            self.spec_bodies[0], self.body_names[0], self.body_poses[0] = (
                self.spec.worldbody,
                "world",
                Pose(),
            )
            self.body_moves[0] = False
            return
        free = self._is_free(body)
        if body.parent is None or free:
            parent_element, parent_pose = self.spec.worldbody, Pose()
        else:
            parent_element, parent_pose = (
                self.spec_bodies[body.parent],
                self.body_poses[body.parent],
            )
        pose = self._body_pose(body)
        name = self.body_namer(self._body_label(body))
        element = parent_element.add_body(name=name)
        self._set_pose(element, pose, parent_pose)
        self.spec_bodies[body.index], self.body_names[body.index], self.body_poses[body.index] = (
            element,
            name,
            pose,
        )
        moves = body.joint is not None or (
            body.parent is not None and self.body_moves.get(body.parent, False)
        )
        self.body_moves[body.index] = moves
        self.built.n_bodies += 1
        self._inertial(element, body, pose, moves)
        if body.joint is not None:
            if free:
                element.add_freejoint(name=self.mjcf_joint_namer(self.joint_names[id(body.joint)]))
                self.built.joints_by_type["free"] += 1
                self.built.joint_names[body.joint.name] = [element.first_joint().name]
            else:
                self._joints(element, body.joint, pose, body.reversed)
        for key in body.parts:
            if key != GROUND and not self.assembly.parts[key].virtual:
                self._part(element, key, pose)

    def _inertial(self, element, body, pose: Pose, moves: bool) -> None:
        parts = [self.assembly.parts[k] for k in body.parts if k != GROUND]
        props = mass_properties.combine((p.mass, p.com, p.inertia) for p in parts if p.mass > 0)
        label = self.body_names[body.index]
        if props.mass <= 0:
            if moves:  # MuJoCo needs mass here: lent by a neighbour once every body is written
                self.massless.append((body, element, pose))
            return
        if moves:
            props.inertia, moments, floor = _floored(props.inertia)
            if moments is not None:
                self.built.warnings.append(
                    f"body {label}: inertia is singular (principal moments "
                    f"{', '.join(f'{m:.3g}' for m in moments)} kg*m^2): raised to at least {floor:.3g} kg*m^2"
                )
        _set_inertial(element, props, pose)

    def _lend_masses(self) -> None:
        """Give every massless moving body the little mass MuJoCo needs, taken from a neighbouring
        body (the one it moves on, else a body moving on it, else the heaviest): the model's total
        mass stays the export's."""
        # an export without any mass (an Onshape model without materials) gets only the least MuJoCo needs
        lightest = min(
            (p.mass for p in self.assembly.real_parts if p.mass > 0),
            default=MIN_LENT_MASS_KG / MISSING_MASS_FRACTION,
        )
        for body, element, pose in self.massless:
            label = self.body_names[body.index]
            donor = self._donor([body.parent, *body.children])
            if donor is None:
                mass = MISSING_MASS_FRACTION * lightest
                source = "added (no body in the model has mass to lend it): the total mass grows by as much"
            else:
                donor_element, donor_label = donor
                mass = min(
                    max(
                        MISSING_MASS_FRACTION * min(lightest, donor_element.mass), MIN_LENT_MASS_KG
                    ),
                    0.5 * donor_element.mass,
                )
                _take_mass(donor_element, mass)
                source = f"taken from body {donor_label} (the total mass stays the export's)"
            inertia, _, floor = _floored(mass_properties.sphere(mass, mass / 1000.0))
            _set_inertial(
                element, mass_properties.MassProperties(mass, pose.position, inertia), pose
            )
            self.built.warnings.append(
                f"body {label} moves on joint {body.joint.name} but its parts have no mass: given {mass:.3g} kg "
                f"{source}, inertia at least {floor:.3g} kg*m^2"
            )

    def _donor(self, candidates):
        """(spec body, name) of the first candidate body index with mass, else the heaviest body."""

        def usable(index):
            element = self.spec_bodies.get(index) if index is not None else None
            return element is not None and element is not self.spec.worldbody and element.mass > 0

        for index in candidates:
            if usable(index):
                return self.spec_bodies[index], self.body_names[index]
        heavy = [i for i in self.spec_bodies if usable(i)]
        if not heavy:
            return None
        index = max(heavy, key=lambda i: self.spec_bodies[i].mass)
        return self.spec_bodies[index], self.body_names[index]

    def _joints(self, element, joint: Joint, body_pose: Pose, reversed_: bool) -> list[str]:
        primitives = list(joint.primitives)
        if reversed_:
            primitives = [type(p)(p.kind, -p.axis) for p in reversed(primitives)]
        names = [
            self.mjcf_joint_namer(n)
            for n in compound_names(self.joint_names[id(joint)], primitives)
        ]
        for primitive, name in zip(primitives, names):
            kwargs = dict(name=name, type=JOINT_TYPES[primitive.kind], pos=[0.0, 0.0, 0.0])
            if primitive.kind != BALL:
                kwargs["axis"] = _r(body_pose.rotation.T @ primitive.axis)
            element.add_joint(**kwargs)
            self.built.joints_by_type[KIND_NAMES[primitive.kind]] += 1
        self.built.joint_names[joint.name] = names
        return names

    # -- geometry and sites ------------------------------------------------------------------
    def _part(self, element, key: str, body_pose: Pose) -> None:
        part = self.assembly.parts[key]
        name = self.part_names[key]
        mesh = self.meshes.get(key)
        rgba = _r(part.color)
        if mesh is not None:
            if self.spec.mesh(mesh.name) is None:
                asset = self.spec.add_mesh(name=mesh.name, file=mesh.filename)
                asset.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            collision = element.add_geom(
                name=name,
                type=mujoco.mjtGeom.mjGEOM_MESH,
                meshname=mesh.name,
                default=self.collision,
            )
            if (
                not mesh.convex
            ):  # exact-distance mark: kept out of MuJoCo contacts, triangles kept as exported
                collision.contype = 0
                collision.conaffinity = 0
            self._set_pose(collision, part.frame, body_pose)
            visual = element.add_geom(
                name=self.geom_namer(f"{name}_visual"),
                type=mujoco.mjtGeom.mjGEOM_MESH,
                meshname=mesh.name,
                default=self.visual,
                rgba=rgba,
            )
            self._set_pose(visual, part.frame, body_pose)
        elif part.geometry is not None and part.mass > 0:
            half, axes = mass_properties.box_half_sizes(part.mass, part.inertia)
            visual = element.add_geom(
                name=self.geom_namer(f"{name}_visual"),
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=_r(half),
                default=self.visual,
                rgba=rgba,
            )
            self._set_pose(visual, Pose(axes, part.com), body_pose)
        site = element.add_site(name=name)
        self._set_pose(site, part.frame, body_pose)
        for frame in part.frames:
            named = element.add_site(name=self.site_namer(frame.name))
            self._set_pose(named, frame.pose, body_pose)

    # -- loops and couplings -----------------------------------------------------------------
    def _closure(self, closure) -> None:
        joint = closure.joint
        label = self.equality_namer(self.joint_names.get(id(joint), joint.name), prefix="loop:")
        base_name, follower_name = (
            self.body_names[closure.base_body],
            self.body_names[closure.follower_body],
        )
        follower_pose = self.body_poses[closure.follower_body]
        anchor = joint.follower_frame.position
        kinds = [p.kind for p in joint.primitives]
        self.built.n_closures += 1
        if "world" not in (
            base_name,
            follower_name,
        ):  # the CAD parts touch at the joint: no contact between them
            self.spec.add_exclude(bodyname1=base_name, bodyname2=follower_name)
        if kinds == [HINGE]:
            axis = joint.primitives[0].axis
            for suffix, sign in (("", -0.5), (":2", 0.5)):
                self._connect(
                    label + suffix,
                    follower_name,
                    base_name,
                    follower_pose.inverse().apply(anchor + sign * self.loop_spacing * axis),
                )
        elif kinds == [BALL]:
            self._connect(label, follower_name, base_name, follower_pose.inverse().apply(anchor))
        elif not kinds:
            self._weld(
                label,
                base_name,
                follower_name,
                self.body_poses[closure.follower_body].inverse().apply(anchor),
            )
        else:
            self._carrier(closure, label)

    def _connect(self, label: str, body1: str, body2: str, anchor) -> None:
        data = np.zeros(12)
        data[:3] = _r(anchor)
        self.spec.add_equality(
            name=label,
            type=mujoco.mjtEq.mjEQ_CONNECT,
            name1=body1,
            name2=body2,
            objtype=mujoco.mjtObj.mjOBJ_BODY,
            data=data.tolist(),
        )

    def _weld(self, label: str, body1: str, body2: str, anchor_in_body2) -> None:
        data = np.zeros(12)
        data[:3] = _r(anchor_in_body2)
        data[10] = 1.0  # torquescale
        self.spec.add_equality(
            name=label,
            type=mujoco.mjtEq.mjEQ_WELD,
            name1=body1,
            name2=body2,
            objtype=mujoco.mjtObj.mjOBJ_BODY,
            data=data.tolist(),
        )

    def _carrier(self, closure, label: str) -> None:
        """A light carrier body on the base carries the joint's real freedoms and is
        welded to the follower: the closure keeps exactly the joint's degrees of freedom."""
        joint = closure.joint
        base_element, base_pose = (
            self.spec_bodies[closure.base_body],
            self.body_poses[closure.base_body],
        )
        pose = Pose(joint.follower_frame.rotation, joint.follower_frame.position)
        name = self.body_namer(f"{self.joint_names[id(joint)]}_carrier")
        carrier = base_element.add_body(name=name)
        self._set_pose(carrier, pose, base_pose)
        share = self._follower_share(closure.follower_body)
        if share is not None:
            # a share of the follower's own mass distribution (same centre, same inertia ellipsoid): the
            # welded pair weighs and turns exactly as the follower did, and a carrier of real weight keeps
            # the weld well conditioned (a light one let loops open by 0.1 mm under gravity)
            _take_mass(self.spec_bodies[closure.follower_body], share.mass)
            _set_inertial(carrier, share, pose)
        else:
            donor = self._donor([closure.follower_body, closure.base_body])
            mass = LIGHT_CARRIER_FRACTION * (donor[0].mass if donor is not None else 1e-3)
            if (
                donor is not None
            ):  # the carrier is welded to the follower: its mass is lent, the total stays exact
                _take_mass(donor[0], mass)
            inertia, _, _ = _floored(mass_properties.sphere(mass, mass / 1000.0))
            _set_inertial(
                carrier, mass_properties.MassProperties(mass, pose.position, inertia), pose
            )
        self._joints(carrier, joint, pose, False)
        self._weld(
            label,
            name,
            self.body_names[closure.follower_body],
            self.body_poses[closure.follower_body].inverse().apply(joint.follower_frame.position),
        )

    def _follower_share(self, follower: int):
        """``CARRIER_MASS_FRACTION`` of the follower body's mass properties in world terms, or None
        when it has no mass or no full inertia to share."""
        element = self.spec_bodies.get(follower)
        if element is None or element is self.spec.worldbody or not element.mass > 0:
            return None
        local = np.asarray(element.fullinertia, dtype=float)
        if not np.all(np.isfinite(local)):
            return None
        tensor = np.array(
            [
                [local[0], local[3], local[4]],
                [local[3], local[1], local[5]],
                [local[4], local[5], local[2]],
            ]
        )
        body = self.body_poses[follower]
        rotation = body.rotation
        fraction = CARRIER_MASS_FRACTION
        return mass_properties.MassProperties(
            fraction * float(element.mass),
            body.apply(np.asarray(element.ipos, dtype=float)),
            fraction * (rotation @ tensor @ rotation.T),
        )

    def _couplings(self) -> None:
        for coupling in self.assembly.couplings:
            names = [self._coupled_joint(coupling, which) for which in ("input", "output")]
            self.spec.add_equality(
                name=self.equality_namer(coupling.name, prefix="coupling:"),
                type=mujoco.mjtEq.mjEQ_JOINT,
                name1=names[0],
                name2=names[1],
                objtype=mujoco.mjtObj.mjOBJ_JOINT,
                data=_r([coupling.offset, coupling.ratio] + [0.0] * 10),
            )
            self.built.n_couplings += 1

    def _coupled_joint(self, coupling: Coupling, which: Literal["input", "output"]) -> str:
        joint_name = coupling.input if which == "input" else coupling.output
        joint = self.assembly.joint(joint_name)
        if (
            joint is None
        ):  # the side-car's reader checks the names; an assembly built otherwise may not
            raise ExportError(
                f"coupling {coupling.name}: {which} joint {joint_name} is not a joint of the assembly"
            )
        names = self.built.joint_names.get(joint.name)
        if names is None:
            raise ExportError(
                f"coupling {coupling.name}: {which} joint {joint.name} ended up inside one rigid body"
            )
        return names[0]


GRAVITY_M_S2 = 9.81
UP_AXES = {"x": 0, "y": 1, "z": 2}


def gravity_along(up: str) -> list[float]:
    """The gravity vector for an export whose ``up`` axis (``x``, ``y``, ``z``, ``-y``, ``+z``...) points up."""
    text = str(up).strip().lower()
    sign = -1.0 if text.startswith("-") else 1.0
    axis = UP_AXES.get(text.lstrip("+-"))
    if axis is None:
        raise ExportError(f"up axis {up!r} is not one of x, y, z, -x, -y, -z")
    gravity = [0.0, 0.0, 0.0]
    gravity[axis] = -sign * GRAVITY_M_S2
    return gravity


def build(
    assembly: Assembly,
    plan: Plan,
    meshes: dict[str, Mesh | None],
    *,
    model_name: str,
    meshdir: str,
    gravity=(0.0, 0.0, -GRAVITY_M_S2),
) -> Built:
    """The MjSpec of ``assembly`` following ``plan`` (meshes are referenced as ``meshdir/<name>.stl``)."""
    writer = _Writer(assembly, plan, meshes, model_name, meshdir)
    writer.spec.option.gravity = list(gravity)
    return writer.write()
