"""Clearance and interference between real part shapes over the machine's cycle.

For each pair of parts, the driver (the sewing machine's ``arm_shaft``) is stepped over
one or more revolutions at a fixed resolution (default 0.5°); at each angle the pose
solver assembles the mechanism (:func:`mechanism.kinematics.pose.solve_pose`) and the exact
distance between the two parts' shapes is measured (:mod:`mechanism.inspection.shapes`: the
model's own triangles, never convex hulls, so a needle passing through the needle-plate
hole is a clearance, not a collision). Then:

- every local minimum of the sampled distance among the lowest few is refined on the
  angle by bounded Brent minimisation (to 1e-5 rad), because the true minimum falls
  between samples: a hook point passing a needle scarf at 2x arm speed moves ~0.2 mm
  per 0.5° sample;
- every interference (overlap) is reported with its angle range (ends found by
  bisection to 1e-4°) and its largest penetration depth (refined on the angle), where
  depth is measured as in :func:`mechanism.inspection.shapes.penetration`.

A pair's ``min_distance_mm`` is the smallest clearance, or minus the largest penetration
depth when the parts interfere. The cycle is assumed periodic over the revolutions
checked (true when every coupled part returns to its start, e.g. the hook at 2:1).

Accuracy: distances are exact for the stored triangles (fcl, double precision; MuJoCo
stores mesh vertices in single precision, ~10 nm at 0.1 m), so the error against the
CAD surface is the export's tessellation error; the pose solver is exact to 1e-10 m; the
refined angle is exact to 1e-5 rad wherever the distance is unimodal within ±1 sample.
"""

from __future__ import annotations

import itertools
import json
import os
from dataclasses import dataclass, field
from typing import Sequence

import mujoco
import numpy as np
from scipy.optimize import minimize_scalar

from mechanism.machine import parts
from mechanism.kinematics.cycle import DEFAULT_RESOLUTION_DEG, cycle_angles
from mechanism.errors import UserError, close_matches
from mechanism.files.tables import true_runs
from mechanism.kinematics.pose import approach, joint_dof, named_joint, solve_pose
from mechanism.inspection.shapes import PartShape, overlap_volume, penetration
from mechanism.tolerances import (
    ANGLE_TOLERANCE_RAD,
    DEPTH_ANGLE_TOLERANCE_RAD,
    BOUNDARY_TOLERANCE_RAD,
    HULL_TOLERANCE_M,
)

# at most this many local minima refined per pair (those that may hold the smallest)
MINIMA_REFINED = 3
SPEED_MARGIN = 1.25  # travel is measured between samples (chords): allow 25% more along the way
HULL_DISTMAX_M = 1.0


@dataclass(frozen=True)
class Pair:
    a: str
    b: str

    @property
    def label(self) -> str:
        return f"{self.a}:{self.b}"

    @property
    def column(self) -> str:
        return f"{self.a}_vs_{self.b}"


def parse_pairs(text: str | Sequence[str], model: mujoco.MjModel) -> list[Pair]:
    """``"needle:hook,needle:needle_plate"`` (or a list of such strings) -> pairs, checked
    against the model's parts."""
    items = [text] if isinstance(text, str) else list(text)
    names = parts.part_names(model)
    pairs: list[Pair] = []
    for item in (p.strip() for chunk in items for p in chunk.split(",")):
        if not item:
            continue
        a, sep, b = item.partition(":")
        a, b = a.strip(), b.strip()
        if not sep or not a or not b or ":" in b:
            raise UserError(f"pair {item!r}: expected two part names as A:B")
        if a == b:
            raise UserError(
                f"pair {item!r} names the same part twice; a clearance needs two different parts"
            )
        for name in (a, b):
            if name not in names:
                raise UserError(
                    f"pair {item!r}: no part named {name!r} with a shape; close matches: {close_matches(name, names)}"
                )
        pair = Pair(a, b)
        if pair not in pairs and Pair(b, a) not in pairs:
            pairs.append(pair)
    if not pairs:
        raise UserError("no part pairs given (use A:B[,C:D...] or all pairs)")
    return pairs


def all_pairs(model: mujoco.MjModel) -> list[Pair]:
    """Every pair of parts that can move relative to each other, except parts joined to
    each other by a joint or loop constraint between two moving bodies (their bearing
    surfaces touch by design). A joint to the fixed frame does not exclude pairs: the
    frame holds many parts and the model does not say which one carries the bearing."""
    names = [name for name in parts.part_names(model) if _has_shape(model, name)]
    weld = model.body_weldid
    joined = set()
    for body in range(1, model.nbody):
        joined.add(frozenset((int(weld[body]), int(weld[model.body_parentid[body]]))))
    for eq in range(model.neq):
        if (
            int(model.eq_type[eq]) in (int(mujoco.mjtEq.mjEQ_CONNECT), int(mujoco.mjtEq.mjEQ_WELD))
            and model.eq_objtype[eq] == mujoco.mjtObj.mjOBJ_BODY
        ):
            joined.add(frozenset((int(weld[model.eq_obj1id[eq]]), int(weld[model.eq_obj2id[eq]]))))
    pairs = []
    for a, b in itertools.combinations(names, 2):
        wa = int(weld[model.geom_bodyid[parts.shape_geoms(model, a)[0]]])
        wb = int(weld[model.geom_bodyid[parts.shape_geoms(model, b)[0]]])
        if wa == wb or (wa != 0 and wb != 0 and frozenset((wa, wb)) in joined):
            continue
        pairs.append(Pair(a, b))
    if not pairs:
        raise UserError("the model has no pair of parts that move relative to each other")
    return pairs


def _has_shape(model, name) -> bool:
    return any(
        model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE for g in parts.shape_geoms(model, name)
    )


@dataclass
class Interference:
    start_deg: float  # driver angle where the overlap begins (end may exceed 360 N when it wraps)
    end_deg: float
    depth_mm: float  # largest penetration depth in the range
    angle_deg: float  # where it is deepest
    volume_mm3: float  # overlap volume at that angle
    point_a_mm: np.ndarray
    point_b_mm: np.ndarray


@dataclass
class PairClearance:
    pair: Pair
    min_distance_mm: float  # smallest clearance; minus the largest depth when interfering
    angle_deg: float
    point_a_mm: np.ndarray  # closest points (world), or the deepest point pair
    point_b_mm: np.ndarray
    interferences: list[Interference] = field(default_factory=list)
    grid_angle_deg: np.ndarray | None = None
    grid_distance_mm: np.ndarray | None = None  # sampled clearance (0 where they overlap)
    driver_angle_deg: float | None = None  # the driver joint's own coordinate at angle_deg

    def passes(self, required_mm: float = 0.0) -> bool:
        return not self.interferences and self.min_distance_mm >= required_mm

    def to_json(self, required_mm: float = 0.0) -> dict:
        return {
            "part_a": self.pair.a,
            "part_b": self.pair.b,
            "min_distance_mm": self.min_distance_mm,
            "angle_deg": self.angle_deg,
            "point_a_mm": list(map(float, self.point_a_mm)),
            "point_b_mm": list(map(float, self.point_b_mm)),
            "required_mm": required_mm,
            "pass": self.passes(required_mm),
            "interferences": [
                {
                    "start_deg": i.start_deg,
                    "end_deg": i.end_deg,
                    "depth_mm": i.depth_mm,
                    "angle_deg": i.angle_deg,
                    "volume_mm3": i.volume_mm3,
                    "point_a_mm": list(map(float, i.point_a_mm)),
                    "point_b_mm": list(map(float, i.point_b_mm)),
                }
                for i in self.interferences
            ],
        }


class ClearanceSweep:
    """Clearance of fixed part pairs over the cycle of one model.

    Built once (shapes, fcl BVHs) and run as often as needed: a variant edits the model's
    fields in place (:mod:`mechanism.inspection.variants`) and calls :meth:`run` again.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        pairs: Sequence[Pair],
        driver: str | None = None,
        revolutions: float = 1.0,
        resolution_deg: float = DEFAULT_RESOLUTION_DEG,
        travel=None,
        frame=None,
    ):
        """``travel`` (mechanism.kinematics.travel.Travel): a driver that rocks is swept once from
        the lower end of its travel to the upper (``revolutions`` is then ignored). ``frame``
        (zero_rad, direction: a machine's ShaftFrame): angles are reported as the described
        shaft angle ``direction (q - zero)``, and a revolution starts at the shaft's zero."""
        if not (0 < resolution_deg <= 30):
            raise UserError(f"resolution {resolution_deg} deg: expected a value in (0, 30]")
        if not (0 < revolutions <= 100):
            raise UserError(f"cycle of {revolutions} revolutions: expected a value in (0, 100]")
        driver = named_joint(driver)
        joint_dof(model, driver)
        self.model = model
        self.data = mujoco.MjData(model)
        self.driver = driver
        self.pairs = list(pairs)
        names = sorted({name for pair in self.pairs for name in (pair.a, pair.b)})
        self.shapes = {name: PartShape(model, name) for name in names}
        self.zero, self.direction = (
            (float(frame.zero_rad), float(frame.direction)) if frame is not None else (0.0, 1.0)
        )
        self.periodic = travel is None or travel.rotates
        if self.periodic:
            # increasing joint positions
            self.angles = self.zero + cycle_angles(revolutions, resolution_deg)
            self.period = np.radians(360.0 * revolutions)
            self._start = model.qpos0.copy()
        else:
            self.angles = travel.samples(np.radians(resolution_deg))
            self.period = (
                (self.angles[-1] - self.angles[0]) * len(self.angles) / (len(self.angles) - 1)
            )
            approach(model, self.data, driver, float(self.angles[0]))
            self._start = self.data.qpos.copy()

    # -- one pose --------------------------------------------------------------------
    def _pose(self, angle: float, start: np.ndarray) -> None:
        self.data.qpos[:] = start
        solve_pose(self.model, self.data, {self.driver: float(angle)})
        for shape in self.shapes.values():
            shape.update(self.data)

    def distance_at(self, pair: Pair, angle: float, start: np.ndarray):
        """Exact distance [m] and closest points (world, m) of ``pair`` with the driver at
        ``angle``, assembled starting from the pose ``start`` (keep it near: same branch)."""
        self._pose(angle, start)
        return self.shapes[pair.a].distance(self.shapes[pair.b])

    # -- the cycle -------------------------------------------------------------------
    def run(self, full_curve: bool = False, progress: bool = False) -> list[PairClearance]:
        """Sample the cycle, then refine minima and interferences for every pair.

        The exact distance is computed only at samples that can matter: a sample is
        skipped when a lower bound of the distance anywhere within ±1 sample (the convex
        hulls' distance minus how far the two parts' points travel in one step) is above
        the smallest exact distance found, so far-apart stretches of the cycle cost one
        hull query each. ``full_curve`` computes every sample (for plots).
        """
        import sys

        from tqdm import tqdm

        n = len(self.angles)
        step = self.period / n
        # shown only on a terminal and only once the check has taken 2 s (many pairs, fine steps)
        with tqdm(
            total=n + len(self.pairs),
            desc="clearance",
            unit="step",
            file=sys.stderr,
            leave=False,
            disable=not progress or None,
            delay=2.0,
        ) as bar:
            poses, lower, travel = self._sample(bar.update)
            results = self._pairs(poses, lower, travel, step, full_curve, bar.update)
        self._start = poses[0].copy()  # the next run (a variant) starts near this branch
        return results

    def _pairs(self, poses, lower, travel, step, full_curve: bool, tick) -> list[PairClearance]:
        n = len(self.angles)
        results = []
        for k, pair in enumerate(self.pairs):
            # over the step before or after
            dip = SPEED_MARGIN * np.maximum(travel[k], np.roll(travel[k], 1))
            reach = lower[k] - dip  # no exact distance within ±1 sample can be smaller
            exact = np.full(n, np.nan)
            smallest = np.inf
            for i in np.argsort(reach, kind="stable"):
                if reach[i] > smallest and not full_curve:
                    break
                self._set_pose(poses[i])
                exact[i] = self.shapes[pair.a].distance(self.shapes[pair.b])[0]
                smallest = min(smallest, exact[i])
            results.append(self._pair_result(pair, exact, dip, poses, step))
            tick(1)
        return results

    def _sample(self, tick=lambda count: None):
        """Poses over the grid; per pair a convex-hull lower bound of the distance at each
        sample and how far any point of the two parts travels from one sample to the next
        [m] (geom displacement plus rotation times the geom's bounding radius)."""
        n, model, data = len(self.angles), self.model, self.data
        poses = np.empty((n, model.nq))
        lower = np.empty((len(self.pairs), n))
        geoms = sorted({g for shape in self.shapes.values() for g in shape.geoms})
        position = np.empty((n, len(geoms), 3))
        rotation = np.empty((n, len(geoms), 3, 3))
        data.qpos[:] = self._start
        velocity = np.zeros(model.nv)
        fromto = np.empty(6)
        for i, angle in enumerate(self.angles):
            if i >= 2:  # linear predictor from the last two poses: one Newton step is then enough
                mujoco.mj_differentiatePos(model, velocity, 1.0, poses[i - 2], poses[i - 1])
                mujoco.mj_integratePos(model, data.qpos, velocity, 1.0)
            solve_pose(model, data, {self.driver: float(angle)})
            poses[i] = data.qpos
            position[i] = data.geom_xpos[geoms]
            rotation[i] = data.geom_xmat[geoms].reshape(-1, 3, 3)
            for k, pair in enumerate(self.pairs):
                hull = min(
                    mujoco.mj_geomDistance(model, data, ga, gb, HULL_DISTMAX_M, fromto)
                    for ga in self.shapes[pair.a].geoms
                    for gb in self.shapes[pair.b].geoms
                )
                lower[k, i] = max(hull - HULL_TOLERANCE_M, 0.0)
            tick(1)
        # travel of each geom from sample i to i + 1 (periodic)
        shift = np.linalg.norm(np.roll(position, -1, axis=0) - position, axis=2)
        relative = np.einsum("ngji,ngjk->ngik", rotation, np.roll(rotation, -1, axis=0))
        turn = np.arccos(np.clip((np.trace(relative, axis1=2, axis2=3) - 1) / 2, -1.0, 1.0))
        reach = shift + turn * model.geom_rbound[geoms]
        index = {g: j for j, g in enumerate(geoms)}
        part_travel = {
            name: reach[:, [index[g] for g in shape.geoms]].max(axis=1)
            for name, shape in self.shapes.items()
        }
        travel = np.array([part_travel[pair.a] + part_travel[pair.b] for pair in self.pairs])
        return poses, lower, travel

    def _set_pose(self, qpos: np.ndarray) -> None:
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        for shape in self.shapes.values():
            shape.update(self.data)

    def _pair_result(
        self, pair: Pair, exact: np.ndarray, dip: np.ndarray, poses: np.ndarray, step: float
    ) -> PairClearance:
        n = len(self.angles)
        known = np.nan_to_num(exact, nan=np.inf)  # skipped samples are far (their bound says so)
        smallest = known.min()
        hit = known <= 0.0

        def before(i):
            return (i - 1) % n if self.periodic else max(i - 1, 0)

        def after(i):
            return (i + 1) % n if self.periodic else min(i + 1, n - 1)

        minima = [
            int(i)
            for i in np.flatnonzero(np.isfinite(known) & ~hit)
            if known[i] <= known[before(i)]
            and known[i] <= known[after(i)]
            and known[i] - dip[i] <= smallest
        ]
        minima = sorted(minima, key=lambda i: known[i])[:MINIMA_REFINED]
        overlaps = [
            _Overlap(
                [self.angles[first] + step * k for k in range((last - first) % n + 1)],
                [poses[(first + k) % n] for k in range((last - first) % n + 1)],
            )
            for first, last in (_periodic_runs(hit) if self.periodic else true_runs(hit))
        ]
        best = None
        for i in minima:
            angle, value, pa, pb = self._refine_minimum(pair, i, poses, step)
            if value <= 0.0:  # an overlap between two samples, found by the refinement
                overlaps.append(_Overlap([angle], [poses[i]]))
            elif best is None or value < best[1]:
                best = (angle, value, pa, pb)
        interferences = sorted(
            (self._interference(pair, o, step) for o in overlaps), key=lambda i: i.start_deg
        )
        if interferences:
            deepest = max(interferences, key=lambda item: item.depth_mm)
            result = PairClearance(
                pair,
                -deepest.depth_mm,
                deepest.angle_deg,
                deepest.point_a_mm,
                deepest.point_b_mm,
                interferences,
            )
        else:
            # no overlap: the smallest sample is a minimum, and its refinement did not find one either
            assert best is not None
            angle, value, pa, pb = best
            result = PairClearance(pair, value * 1e3, self._degrees(angle), pa * 1e3, pb * 1e3)
        result.grid_angle_deg = np.array([self._degrees(a) for a in self.angles])
        result.driver_angle_deg = float(
            np.degrees(self.zero + self.direction * np.radians(result.angle_deg))
        )
        result.grid_distance_mm = exact * 1e3
        return result

    def _degrees(self, angle: float) -> float:
        """The reported angle [deg] of a driver position: the described shaft angle."""
        shaft = self.direction * (angle - self.zero)
        return float(np.degrees(shaft % self.period if self.periodic else shaft))

    def _within(self, low: float, high: float) -> tuple[float, float]:
        """An angle interval kept inside the travel of a driver that rocks."""
        if self.periodic:
            return low, high
        return max(low, float(self.angles[0])), min(high, float(self.angles[-1]))

    def _refine_minimum(self, pair: Pair, i: int, poses: np.ndarray, step: float):
        start = poses[i]
        center = self.angles[i]
        found = minimize_scalar(
            lambda angle: self.distance_at(pair, angle, start)[0],
            bounds=self._within(center - step, center + step),
            method="bounded",
            options={"xatol": ANGLE_TOLERANCE_RAD},
        )
        candidates = [
            (float(found.x), *self.distance_at(pair, float(found.x), start)),
            (center, *self.distance_at(pair, center, start)),
        ]
        return min(candidates, key=lambda item: item[1])

    def _boundary(
        self, pair: Pair, free_angle: float, hit_angle: float, start: np.ndarray
    ) -> float:
        """Bisection for the angle where the parts start to overlap."""
        while abs(hit_angle - free_angle) > BOUNDARY_TOLERANCE_RAD:
            middle = 0.5 * (free_angle + hit_angle)
            if self.distance_at(pair, middle, start)[0] <= 0.0:
                hit_angle = middle
            else:
                free_angle = middle
        return hit_angle

    def _volume(self, pair: Pair, angle: float, start: np.ndarray) -> float:
        self._pose(angle, start)
        return overlap_volume(self.shapes[pair.a], self.shapes[pair.b], self.data)

    def _depth(self, pair: Pair, angle: float, start: np.ndarray):
        self._pose(angle, start)
        return penetration(self.shapes[pair.a], self.shapes[pair.b], self.data)

    def _interference(self, pair: Pair, overlap: "_Overlap", step: float) -> Interference:
        inside, starts = overlap.angles, overlap.starts
        whole_cycle = len(inside) * step >= self.period - 1e-9
        if whole_cycle:
            lo, hi = self.angles[0], self.angles[0] + self.period
        else:
            lo = self._boundary(pair, inside[0] - step, inside[0], starts[0])
            hi = self._boundary(pair, inside[-1] + step, inside[-1], starts[-1])
            if (
                not self.periodic
            ):  # the overlap runs up to an end of the travel: no boundary beyond it
                lo = lo if inside[0] > self.angles[0] else float(self.angles[0])
                hi = hi if inside[-1] < self.angles[-1] else float(self.angles[-1])
        # the worst angle is where the overlap volume peaks (one mesh boolean per trial,
        # far cheaper than a depth): the best sample, refined by Brent; depth is measured there
        volumes = [self._volume(pair, a, s) for a, s in zip(inside, starts)]
        k = int(np.nanargmax(volumes)) if np.isfinite(volumes).any() else 0
        angle, start = inside[k], starts[k]
        if not whole_cycle and np.isfinite(
            volumes[k]
        ):  # NaN: a mesh is not closed, no volume or depth
            found = minimize_scalar(
                lambda x: -self._volume(pair, x, start),
                bounds=(max(angle - step, lo), min(angle + step, hi)),
                method="bounded",
                options={"xatol": ANGLE_TOLERANCE_RAD},
            )
            if -found.fun > volumes[k]:
                angle = float(found.x)
        deepest = self._depth(pair, angle, start)
        if not whole_cycle and np.isfinite(deepest.depth):
            # the deepest angle can differ a little from the largest volume (a point sliding along a face)
            found = minimize_scalar(
                lambda x: -self._depth(pair, x, start).depth,
                bounds=(max(angle - step, lo), min(angle + step, hi)),
                method="bounded",
                options={"xatol": DEPTH_ANGLE_TOLERANCE_RAD},
            )
            if -found.fun > deepest.depth:
                angle, deepest = float(found.x), self._depth(pair, float(found.x), start)
        start_deg = self._degrees(lo if self.direction > 0 else hi)
        return Interference(
            start_deg,
            start_deg + float(np.degrees(hi - lo)),
            deepest.depth * 1e3,
            self._degrees(angle),
            deepest.volume * 1e9,
            deepest.point_a * 1e3,
            deepest.point_b * 1e3,
        )


@dataclass
class _Overlap:
    """Driver angles (increasing, possibly past one period) where two parts overlap, and
    for each a nearby pose to start the pose solver from."""

    angles: list[float]
    starts: list[np.ndarray]


def _periodic_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in a periodic boolean array as (first, last) index pairs."""
    n = len(mask)
    if not mask.any():
        return []
    if mask.all():
        return [(0, n - 1)]
    start = int(np.flatnonzero(~mask)[0])  # rotate so that the scan starts outside a run
    runs, first = [], None
    for k in range(1, n + 1):
        i = (start + k) % n
        if mask[i] and first is None:
            first = i
        if not mask[i] and first is not None:
            runs.append((first, (i - 1) % n))
            first = None
    return runs


@dataclass
class ClearanceReport:
    results: list[PairClearance]
    required_mm: float
    driver: str
    revolutions: float
    resolution_deg: float

    @property
    def passed(self) -> bool:
        return all(result.passes(self.required_mm) for result in self.results)

    def to_json(self) -> dict:
        return {
            "format": "mechanism-clearance/1",
            "driver": self.driver,
            "revolutions": self.revolutions,
            "resolution_deg": self.resolution_deg,
            "required_mm": self.required_mm,
            "pass": self.passed,
            "pairs": [result.to_json(self.required_mm) for result in self.results],
        }

    def rows(self) -> list[dict]:
        rows = []
        for result in self.results:
            deepest = max(result.interferences, key=lambda i: i.depth_mm, default=None)
            rows.append(
                {
                    "part_a": result.pair.a,
                    "part_b": result.pair.b,
                    "min_distance_mm": result.min_distance_mm,
                    f"{self.driver}_angle_deg": result.angle_deg,
                    **{f"point_a_{c}_mm": v for c, v in zip("xyz", result.point_a_mm)},
                    **{f"point_b_{c}_mm": v for c, v in zip("xyz", result.point_b_mm)},
                    "interferences": len(result.interferences),
                    "max_penetration_mm": deepest.depth_mm if deepest else 0.0,
                    "interference_deg": sum(i.end_deg - i.start_deg for i in result.interferences),
                    "required_mm": self.required_mm,
                    "pass": int(result.passes(self.required_mm)),
                }
            )
        return rows


def check_clearance(
    model: mujoco.MjModel,
    pairs: Sequence[Pair] | None = None,
    revolutions: float = 1.0,
    resolution_deg: float = DEFAULT_RESOLUTION_DEG,
    required_mm: float = 0.0,
    driver: str | None = None,
    travel=None,
    description=None,
    progress: bool = False,
) -> ClearanceReport:
    """Minimum clearance and interferences of ``pairs`` (default: all moving pairs) over
    ``revolutions`` turns of ``driver`` (or once over its ``travel`` where it rocks);
    ``progress``: a bar on stderr once it takes 2 s."""
    from mechanism.machine.machine import inspection_frame, inspection_travel

    pairs = list(pairs) if pairs else all_pairs(model)
    driver = named_joint(driver)
    travel = travel or inspection_travel(model, driver, description)
    frame = inspection_frame(model, driver, description, travel)
    sweep = ClearanceSweep(model, pairs, driver, revolutions, resolution_deg, travel, frame)
    return ClearanceReport(
        sweep.run(progress=progress), required_mm, driver, revolutions, resolution_deg
    )


def write_rows(path: str | os.PathLike, rows: Sequence[dict], comments: Sequence[str] = ()) -> None:
    """A CSV of mixed text/number rows (part names, variant names), atomically."""
    import csv

    from mechanism.files.outputs import atomic_file

    if not rows:
        raise ValueError("no rows to write")
    with atomic_file(path) as handle:
        for line in comments:
            handle.write(f"# {line}\n")
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow(
                {k: (f"{v:.9g}" if isinstance(v, float) else v) for k, v in row.items()}
            )


def write_json(path: str | os.PathLike, payload: dict) -> None:
    from mechanism.files.outputs import atomic_file

    with atomic_file(path) as handle:
        json.dump(payload, handle, indent=2)
        handle.write("\n")
