"""The dozen calls a notebook user needs, lifted to ``import mechanism``.

Each takes a :class:`~mechanism.machine.machine.Machine` (from :func:`load_machine`) or
nothing for the shipped Sapphire 870, and returns a result object with unit-named fields.
"""

from __future__ import annotations

import os

from mechanism.dynamics.simulation import SimulationResult
from mechanism.machine.machine import Machine, MachineConfig, load_machine
from mechanism.physics.inputs import VoltageProfile


def simulate(machine: Machine | None = None, voltage_V: float | VoltageProfile = 12.0, duration_s: float = 2.0, *,
             start_angle_rad: float = 0.0, sample_rate_hz: float = 1000.0, reduced: bool = False,
             progress: bool = False) -> SimulationResult:
    """Run ``machine`` (default: the shipped one, cold) from rest under a voltage or profile.
    ``reduced=True`` integrates the exact 1-DOF equation instead of the full multibody model."""
    from mechanism.dynamics.reduced import ReducedModel
    from mechanism.dynamics.simulation import simulate as full

    machine = machine or load_machine()
    if reduced:
        return ReducedModel(machine).simulate(voltage_V, duration_s, start_angle_rad=start_angle_rad,
                                              sample_rate_hz=sample_rate_hz)
    return full(voltage_V, duration_s, machine=machine, start_angle_rad=start_angle_rad,
                sample_rate_hz=sample_rate_hz, progress=progress)


def convert(export: str | os.PathLike, out_dir: str | os.PathLike, **options):
    """CAD export -> MJCF in ``out_dir`` (mechanism.converters.convert)."""
    from mechanism.converters import convert as run

    return run(export, out_dir, **options)


__all__ = ["Machine", "MachineConfig", "SimulationResult", "VoltageProfile", "convert", "load_machine", "simulate"]
