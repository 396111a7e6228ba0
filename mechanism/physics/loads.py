"""Loads on the sewing machine besides friction: fabric, belt tension, feeding.

- Fabric: a stack of ``layers`` on the needle plate. While the needle point is below the
  stack's top surface the fabric resists the needle: a piercing force that builds up over
  the point's taper on the way down (until the blade is through the stack), and a smaller
  drag while withdrawing. Applied to the needle at its point by the compiled passive
  callback (native/machine.c), so the arm feels it through the real linkage geometry.
  Magnitudes: ~0.6 N per layer of medium cotton for a size-80 needle (order of published
  needle-penetration forces, 1-5 N for a few layers); thesis fig. 37 shows the resulting
  speed dips with 12 layers.
- Belt tension (thesis fig. 15: at 12 V the three settings span roughly 500-560 rpm, harder
  is slower): extra bearing friction from the belt preload, as arm-side Coulomb friction.
- Feeding (thesis fig. 38: the feed mechanism adds friction): extra Coulomb friction on the
  lower shaft that drives the feed dogs.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from mechanism.errors import UserError
from mechanism.physics._numeric import numeric_block

NUMERIC_NAME = "mechanism_needle_load"


@dataclass(frozen=True)
class FabricLoad:
    layers: int = 0
    layer_thickness_mm: float = 0.35
    piercing_force_per_layer_N: float = 0.6
    drag_fraction: float = 0.3
    point_taper_mm: float = 2.0

    def __post_init__(self):
        if self.layers < 0 or self.layers > 100:
            raise UserError(f"number of fabric layers must be between 0 and 100, got {self.layers}")

    @property
    def thickness_m(self) -> float:
        return self.layers * self.layer_thickness_mm * 1e-3

    @property
    def piercing_force_N(self) -> float:
        return self.layers * self.piercing_force_per_layer_N

    def force(self, depth_m, velocity_m_s):
        """Resisting force [N] on the needle (positive up) for depth below the fabric top
        and the needle's vertical velocity: numpy mirror of native/machine.c."""
        depth = np.asarray(depth_m, dtype=float)
        v = np.asarray(velocity_m_s, dtype=float)
        ramp = self.point_taper_mm * 1e-3
        engaged = np.clip(depth / ramp, 0.0, 1.0)
        piercing = (v < 0) & (depth < self.thickness_m + ramp)
        magnitude = (
            np.where(piercing, self.piercing_force_N, self.drag_fraction * self.piercing_force_N)
            * engaged
        )
        return np.where(depth > 0, -magnitude * v / np.sqrt(v * v + 1e-6), 0.0)

    def apply_to_spec(self, spec: mujoco.MjSpec) -> None:
        if self.layers:
            spec.add_numeric(name=NUMERIC_NAME, data=np.zeros(9))

    def bind(self, model: mujoco.MjModel, needle_site: str, fabric_base_z_m: float) -> None:
        if not self.layers:
            return
        site = model.site(needle_site)
        model.numeric(NUMERIC_NAME).data[:] = [
            1.0,
            float(site.id),
            float(model.site_bodyid[site.id]),
            fabric_base_z_m + self.thickness_m,
            self.thickness_m,
            self.piercing_force_N,
            self.drag_fraction * self.piercing_force_N,
            self.point_taper_mm * 1e-3,
            1e-3,
        ]


def python_needle_load(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """The needle-load part of native/machine.c in Python (fallback without a compiler)."""
    p = numeric_block(model, NUMERIC_NAME)
    if p is None:
        return
    site, body = int(p[1]), int(p[2])
    top, thickness, down, up, ramp, eps = p[3:9]
    tip = data.site_xpos[site]
    depth = top - tip[2]
    if depth <= 0:
        return
    velocity = np.zeros(6)
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, site, velocity, 0)
    vz = velocity[5]
    engaged = min(depth / ramp, 1.0)
    piercing = vz < 0 and depth < thickness + ramp
    magnitude = (down if piercing else up) * engaged
    force = np.array([0.0, 0.0, -magnitude * vz / np.sqrt(vz * vz + eps * eps)])
    mujoco.mj_applyFT(model, data, force, np.zeros(3), tip.copy(), body, data.qfrc_passive)
