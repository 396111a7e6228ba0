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

from mechanism.errors import UserError
from mechanism.lazy import lazy_exports

__version__ = "0.2.0"

_lazy_names, __getattr__, _lazy_dir = lazy_exports(
    __name__,
    {
        "api": (
            "Machine",
            "MachineConfig",
            "NeedleMotion",
            "SimulationResult",
            "ToolMotion",
            "VoltageProfile",
            "atomic_dir",
            "clearance",
            "conversion_summary",
            "convert",
            "diagnose",
            "diagnosis_report",
            "driven_inertia_kgm2",
            "identify",
            "inspect",
            "inspect_recording",
            "load_machine",
            "needle_motion",
            "plot_needle",
            "plot_simulation",
            "plot_sweep",
            "plot_tool_motion",
            "probe",
            "read_recording",
            "read_table",
            "shipped_export",
            "shipped_folder",
            "shipped_machines",
            "shipped_model",
            "shipped_scene",
            "simulate",
            "sweep",
            "tool_motion",
            "view",
            "write_bench_recording",
            "write_needle_csv",
            "write_table",
            "write_tool_motion_csv",
        ),
        "machine.description": ("read_description",),
        "files.cache": ("cache_info", "clear_cache"),
    },
)
__all__ = ["UserError", "__version__", *_lazy_names]


def __dir__() -> list[str]:
    return sorted(__all__)
