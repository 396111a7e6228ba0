"""Rigid poses (rotation + translation) in the world frame of the export, in metres."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mechanism.converters.errors import ExportError


def orthonormal(matrix, where: str) -> np.ndarray:
    """The rotation nearest to ``matrix`` (exports print rotations to a few digits).

    A matrix far from a rotation, or a mirrored (left-handed) one, is an export error:
    MuJoCo frames cannot be mirrored.
    """
    matrix = np.asarray(matrix, dtype=float).reshape(3, 3)
    if not np.all(np.isfinite(matrix)):
        raise ExportError(f"{where}: rotation matrix has NaN/inf entries")
    u, s, vt = np.linalg.svd(matrix)
    if np.any(np.abs(s - 1.0) > 1e-3):
        raise ExportError(
            f"{where}: orientation is not a rotation matrix (singular values {np.round(s, 4).tolist()})"
        )
    rotation = u @ vt
    if np.linalg.det(rotation) < 0:
        raise ExportError(
            f"{where}: orientation is mirrored (left-handed frame); MuJoCo frames cannot be mirrored"
        )
    return rotation


@dataclass(frozen=True)
class Pose:
    """``world_point = rotation @ local_point + position``."""

    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        object.__setattr__(self, "rotation", np.asarray(self.rotation, dtype=float).reshape(3, 3))
        object.__setattr__(self, "position", np.asarray(self.position, dtype=float).reshape(3))

    def __matmul__(self, other: "Pose") -> "Pose":
        return Pose(self.rotation @ other.rotation, self.rotation @ other.position + self.position)

    def inverse(self) -> "Pose":
        return Pose(self.rotation.T, -self.rotation.T @ self.position)

    def apply(self, point) -> np.ndarray:
        return self.rotation @ np.asarray(point, dtype=float) + self.position

    def relative_to(self, parent: "Pose") -> "Pose":
        """This pose expressed in ``parent``'s frame."""
        return parent.inverse() @ self
