"""Mass properties: checking CAD inertias, repairing impossible ones, and combining parts exactly.

Inertia tensors here are 3x3 about the centre of mass, world axes, kg*m^2. A physical
tensor is symmetric with principal moments that are positive and satisfy the triangle
inequality (each moment at most the sum of the other two).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mechanism.tolerances import INERTIA_RELATIVE_TOLERANCE as RELATIVE_TOLERANCE


def principal(inertia) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (ascending) and axes (columns, right-handed)."""
    moments, axes = np.linalg.eigh(0.5 * (np.asarray(inertia) + np.asarray(inertia).T))
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    return moments, axes


def shift(mass: float, offset) -> np.ndarray:
    """Parallel-axis term: add to an inertia about the CoM to get it about a point ``-offset`` away."""
    offset = np.asarray(offset, dtype=float)
    return mass * (offset @ offset * np.eye(3) - np.outer(offset, offset))


def violation(inertia, resolution: float = 0.0) -> str | None:
    """Why ``inertia`` is not physical (beyond the export's rounding), or None."""
    inertia = np.asarray(inertia, dtype=float)
    if not np.all(np.isfinite(inertia)):
        return "has NaN/inf entries"
    scale = max(float(np.max(np.abs(inertia))), 1e-300)
    tolerance = RELATIVE_TOLERANCE * scale + 3 * resolution
    if np.max(np.abs(inertia - inertia.T)) > tolerance:
        return "is not symmetric"
    moments, _ = principal(inertia)
    if moments[0] < -tolerance:
        return f"has a negative principal moment ({_fmt(moments)} kg*m^2)"
    if moments[0] + moments[1] < moments[2] - tolerance:
        return f"violates the triangle inequality ({_fmt(moments)} kg*m^2: {moments[2]:.4g} > {moments[0]:.4g} + {moments[1]:.4g})"
    return None


def _fmt(values) -> str:
    return ", ".join(f"{v:.4g}" for v in values)


def clamp_to_physical(inertia, floor: float = 0.0) -> np.ndarray:
    """The nearest physical tensor for one that is off only by rounding: symmetrised, moments
    raised to ``floor`` and the triangle inequality restored."""
    moments, axes = principal(inertia)
    moments = np.maximum(moments, floor)
    moments[2] = min(moments[2], moments[0] + moments[1])
    return axes @ np.diag(moments) @ axes.T


def sphere(mass: float, volume: float) -> np.ndarray:
    """Inertia of a uniform solid sphere of the given mass and volume."""
    radius = (3.0 * volume / (4.0 * np.pi)) ** (1.0 / 3.0)
    return 0.4 * mass * radius**2 * np.eye(3)


def box_half_sizes(mass: float, inertia) -> tuple[np.ndarray, np.ndarray]:
    """Half-sizes and orientation (principal axes) of the uniform box with this mass and inertia."""
    moments, axes = principal(inertia)
    if mass <= 0:
        return np.full(3, 1e-3), axes
    total = moments.sum()
    squares = 6.0 * (total - 2.0 * moments) / mass  # a^2 = 6 (Iyy + Izz - Ixx) / m
    largest = max(float(squares.max()), 1e-6)
    squares = np.maximum(squares, 1e-4 * largest)  # a flat box still gets a visible thickness
    return 0.5 * np.sqrt(squares), axes


@dataclass
class MassProperties:
    mass: float
    com: np.ndarray
    inertia: np.ndarray  # about com, world axes


def combine(items) -> MassProperties:
    """Exact mass properties of rigidly joined parts (``items``: (mass, com, inertia) tuples)."""
    items = list(items)
    mass = float(sum(m for m, _, _ in items))
    if mass <= 0:
        return MassProperties(
            0.0, np.asarray(items[0][1], dtype=float) if items else np.zeros(3), np.zeros((3, 3))
        )
    com = sum(m * np.asarray(c, dtype=float) for m, c, _ in items) / mass
    inertia = np.zeros((3, 3))
    for m, c, inertia_i in items:
        inertia += np.asarray(inertia_i, dtype=float) + shift(m, np.asarray(c, dtype=float) - com)
    return MassProperties(mass, com, 0.5 * (inertia + inertia.T))


STEEL_DENSITY = 7850.0  # kg/m^3, only to size a repair when the export states no volume


def repair_parts(assembly, meshes: dict) -> None:
    """Replace every non-physical part inertia (beyond the export's rounding), with a warning
    naming the part, the offending moments and what replaced them."""
    for part in assembly.real_parts:
        if part.mass <= 0:
            part.inertia = np.zeros((3, 3))
            continue
        problem = violation(part.inertia, part.inertia_resolution)
        if problem is None:
            continue
        replacement, method = _replacement(part, meshes.get(part.key))
        part.inertia = replacement
        moments, _ = principal(replacement)
        assembly.warn(
            f"part {part.name}: the export's inertia tensor {problem}; replaced by {method} "
            f"(principal moments {_fmt(moments)} kg*m^2), check the part's mass properties in CAD"
        )


def _replacement(part, mesh) -> tuple[np.ndarray, str]:
    if mesh is not None:
        import trimesh

        shape = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)
        if shape.volume > 0 and shape.is_watertight:
            tensor = np.asarray(shape.moment_inertia) * (part.mass / shape.mass)
            tensor = part.frame.rotation @ tensor @ part.frame.rotation.T
            if violation(tensor) is None:
                return tensor, "the inertia of its mesh at the export's mass"
    if part.volume:
        return sphere(part.mass, part.volume), "a uniform sphere of the part's volume and mass"
    return sphere(part.mass, part.mass / STEEL_DENSITY), "a uniform steel sphere of the part's mass"
