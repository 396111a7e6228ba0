"""mechanism: CAD assembly export -> MuJoCo simulation you can trust, inspect and correct.

    import mechanism
    machine = mechanism.load_machine()                      # or load_machine("my_machine.toml")
    run = mechanism.simulate(machine, voltage_V=12, duration_s=2)
    print(run.mean_speed_rpm)

The public API is the names in ``__all__`` (docs/api.md has one example each); the
subpackages group the rest by concern: converters, kinematics, physics, machine, dynamics,
inspection, sysid, steppers, testbench. Names are imported on first use, so the command
line starts fast.
"""

from __future__ import annotations

import importlib

from mechanism.errors import UserError

__version__ = "0.2.0"

_LAZY = {name: "mechanism.api" for name in (
    "Machine", "MachineConfig", "NeedleMotion", "SimulationResult", "VoltageProfile", "atomic_dir", "clearance",
    "conversion_summary", "convert", "diagnose", "diagnosis_report", "driven_inertia_kgm2", "identify", "inspect",
    "load_machine", "needle_motion", "plot_needle", "plot_simulation", "plot_sweep", "probe", "read_table",
    "shipped_machines", "simulate", "sweep", "view", "write_bench_recording", "write_needle_csv", "write_table")}
_LAZY["read_description"] = "mechanism.machine.description"

__all__ = ["UserError", "__version__", *sorted(_LAZY)]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'mechanism' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
