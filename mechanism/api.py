"""The calls a notebook user needs, lifted to ``import mechanism`` (docs/api.md: one example each).

Each takes a :class:`~mechanism.machine.machine.Machine` (from :func:`load_machine`; None
is the shipped Sapphire 870) and returns a result object with unit-named fields.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from mechanism.dynamics.simulation import SimulationResult, plot_simulation
from mechanism.files.outputs import atomic_dir
from mechanism.files.tables import read_table, write_table
from mechanism.inspection.tool import ToolMotion, tool_motion
from mechanism.inspection.tool import plot as plot_tool_motion
from mechanism.inspection.tool import write_csv as write_tool_motion_csv
from mechanism.machine.machine import Machine, MachineConfig, load_machine
from mechanism.machine.models import (
    shipped_export,
    shipped_folder,
    shipped_machines,
    shipped_model,
    shipped_scene,
)
from mechanism.physics.inputs import VoltageProfile

if TYPE_CHECKING:  # option names only: the modules load where they run
    from mechanism.batch.runner import Backend
    from mechanism.sysid.lumped_baseline import Baseline


def simulate(
    machine: Machine | None = None,
    voltage_V: float | VoltageProfile = 12.0,
    duration_s: float = 2.0,
    *,
    start_angle_rad: float = 0.0,
    sample_rate_hz: float = 1000.0,
    reduced: bool = False,
    progress: bool = False,
) -> SimulationResult:
    """Run ``machine`` (default: the shipped one, cold) from rest under a voltage or profile.
    ``reduced=True`` integrates the exact 1-DOF equation instead of the full multibody model."""
    from mechanism.dynamics.reduced import ReducedModel
    from mechanism.dynamics.simulation import simulate as full

    machine = machine or load_machine()
    if reduced:
        return ReducedModel(machine).simulate(
            voltage_V, duration_s, start_angle_rad=start_angle_rad, sample_rate_hz=sample_rate_hz
        )
    return full(
        voltage_V,
        duration_s,
        machine=machine,
        start_angle_rad=start_angle_rad,
        sample_rate_hz=sample_rate_hz,
        progress=progress,
    )


def convert(export: str | os.PathLike, out_dir: str | os.PathLike, **options):
    """CAD export -> MJCF in ``out_dir`` (options: name, mesh_dir, up); returns the report."""
    from mechanism.converters import convert as run

    return run(export, out_dir, **options)


def conversion_summary(report) -> list[str]:
    """What ``mechanism convert`` prints: the conversion, the moving mass and the reflected inertia."""
    from mechanism.machine.roles import drive_lines

    return report.summary_lines(extra=drive_lines(report.mjcf_path, report.degrees_of_freedom))


def probe(
    machine: Machine | None = None,
    probes: Sequence[str] = (),
    *,
    speed_rpm: float = 600.0,
    voltage_V: float | None = None,
    duration_s: float | None = None,
):
    """Probes ``"name:quantity"`` (position, velocity, acceleration, force, torque) over one
    kinematic shaft revolution at ``speed_rpm``, or along a simulation under ``voltage_V``."""
    from mechanism.inspection.probes import Probe, run_probes

    machine = machine or load_machine()
    parsed = [
        Probe(name, quantity) for name, _, quantity in (text.rpartition(":") for text in probes)
    ]
    return run_probes(
        parsed,
        machine.model_path,
        voltage_V,
        duration_s,
        speed_rpm,
        driver=machine.shaft_joint,
        description=machine.description,
    )


def clearance(
    machine: Machine | None = None,
    pairs: str | Sequence[str] = (),
    *,
    required_mm: float = 0.0,
    resolution_deg: float = 0.5,
):
    """Minimum clearance of part pairs ``"A:B"`` over a shaft revolution (exact shapes)."""
    from mechanism.inspection.clearance import check_clearance, parse_pairs
    from mechanism.machine.models import load_model

    machine = machine or load_machine()
    model = load_model(machine.model_path)
    text = pairs if isinstance(pairs, str) else ",".join(pairs)
    return check_clearance(
        model,
        parse_pairs(text, model),
        resolution_deg=resolution_deg,
        required_mm=required_mm,
        driver=machine.shaft_joint,
    )


def sweep(
    machine: Machine | None,
    variants: str | os.PathLike | dict,
    *,
    voltage_V: float = 12.0,
    duration_s: float = 2.0,
    workers: int = 1,
    backend: Backend = "local",
    progress: bool = False,
    **options,
):
    """Dynamic design variants (a variants file or its JSON document as a dict: flywheel
    ``inertia:<joint>_kgm2``, counterweight ``mass:<part>_kg``, ``motor:<key>``, ``friction:<joint>:<key>``,
    ``voltage_V``, ...), each run from rest on the reduced model; ``.table()`` gives one row per
    variant with speed, ripple, settling, current. Options: ray_address, journal, resume."""
    from mechanism.inspection.sweep import SweepOptions, run_sweep
    from mechanism.inspection.variants import read_variants, variants_from_document

    machine = machine or load_machine()
    presets = machine.description.variant_presets
    variant_set = (
        variants_from_document(variants, presets)
        if isinstance(variants, dict)
        else read_variants(variants, presets)
    )
    return run_sweep(
        machine,
        variant_set,
        SweepOptions(voltage_V=voltage_V, duration_s=duration_s, layers=machine.config.layers),
        workers=workers,
        backend=backend,
        progress=progress,
        **options,
    )


def plot_sweep(
    result, path: str | os.PathLike, x: str | None = None, group: str | None = None
) -> Path:
    """Speed, ripple, settling time and peak current of a sweep against one parameter, a line per value of another."""
    from mechanism.inspection.sweep import plot_sweep as run

    return run(result, path, x, group)


def driven_inertia_kgm2(machine: Machine | None = None) -> float:
    """The shaft side's own inertia (without the motor rotor's share): the scale of a flywheel."""
    from mechanism.inspection.sweep_metrics import driven_inertia_kgm2 as run

    return run(machine or load_machine())


def view(machine: Machine | None = None, html: str | os.PathLike | None = None, **options) -> dict:
    """A self-contained meshcat animation of one shaft revolution (options: frames,
    probe_names, pairs, voltage, duration_s, recording, serve)."""
    from mechanism.inspection.viewer import view as run

    machine = machine or load_machine()
    return run(
        html,
        machine.model_path,
        driver=machine.shaft_joint,
        description=machine.description,
        **options,
    )


def inspect(machine: Machine | None = None, out: str | os.PathLike = "inspection") -> list[Path]:
    """The machine's described inspection ([inspect]: probes, clearance, a faulty variant, the animation)."""
    from mechanism.inspection.steps import demo

    return demo(out, machine or load_machine())


def write_bench_recording(
    machine: Machine | None,
    effects: Sequence[str],
    seed: int,
    path: str | os.PathLike,
    duration_s: float = 60.0,
) -> Path:
    """A virtual bench recording of ``machine`` with concealed ``effects`` (the truth JSON beside
    it, whose path is returned)."""
    from mechanism.testbench import make_recording, write_recording

    recording = make_recording(
        list(effects), seed=seed, duration_s=duration_s, nominal=drive_nominal(machine)
    )
    return write_recording(recording, Path(path))[1]


def read_recording(
    recording: str | os.PathLike,
    machine: Machine | None = None,
    recording_map: str | os.PathLike | None = None,
):
    """A bench recording in any format the readers take (CSV/TSV plain or compressed, MATLAB,
    Parquet/Feather, TDMS, JSON), its columns and units by ``recording_map`` (a TOML with a
    ``[recording]`` table), else by the machine description's ``[recording]``, else by the
    default names. ``Recording.reading`` says what was read and done."""
    from mechanism.sysid.recording import read_recording as run
    from mechanism.sysid.recording_map import resolve_recording_map

    description = machine.description if machine is not None else None
    return run(
        recording,
        resolve_recording_map(description, recording_map),
        motor_joint=machine.motor_joint if machine is not None else None,
    )


def inspect_recording(
    recording: str | os.PathLike,
    machine: Machine | None = None,
    recording_map: str | os.PathLike | None = None,
) -> dict:
    """What a recording holds before any fit: columns found and chosen, units, rate, duration,
    each signal's range, the encoder step, gaps, and whether it excites the machine enough to
    identify each parameter (``mechanism inspect-recording``)."""
    from mechanism.sysid.inspect_recording import inspect_recording as run
    from mechanism.sysid.recording_map import resolve_recording_map

    description = machine.description if machine is not None else None
    return run(recording, resolve_recording_map(description, recording_map))


def identify(
    machine: Machine | None,
    recording: str | os.PathLike,
    recording_map: str | os.PathLike | None = None,
    *,
    baseline: Baseline = "lumped",
    **options,
):
    """Fit the machine's baseline (``"lumped"``: inertia, friction; or ``"multibody"``) to a
    bench recording (any format :func:`read_recording` takes)."""
    from mechanism.sysid.identification import identify as run

    return run(
        read_recording(recording, machine, recording_map),
        baseline,
        nominal=drive_nominal(machine),
        **options,
    )


def diagnose(
    machine: Machine | None,
    recording: str | os.PathLike,
    recording_map: str | os.PathLike | None = None,
    *,
    recording_name: str | None = None,
    baseline: Baseline = "lumped",
    **options,
):
    """Find the physics the machine's model is missing from a bench recording, model it, show the fit improve.
    ``recording_name``: how the outputs name the recording (default: the path as given), e.g. its
    path relative to the folder the outputs go to."""
    import dataclasses

    from mechanism.sysid.diagnosis import diagnose as run

    rec = read_recording(recording, machine, recording_map)
    if recording_name is not None:
        rec = dataclasses.replace(rec, source=recording_name)
    return run(rec, baseline, nominal=drive_nominal(machine), **options)


def drive_nominal(machine: Machine | None):
    """The machine's lumped drive numbers (:class:`~mechanism.dynamics.lumped.DriveNominal`) that
    identification, diagnosis and the test bench scale from, from its description and CAD model
    (mechanism.sysid.nominal; a description's ``[lumped]`` section, the whole machine as a lumped
    model identified it, gives inertia and friction). None: the shipped default machine's."""
    from mechanism.sysid.nominal import machine_drive_nominal

    return machine_drive_nominal(machine if machine is not None else load_machine())


# Deprecated aliases, the sewing machine's words from before the core spoke of shaft and tool:
# the very same objects as the generic names (docs/api.md lists them).
NeedleMotion = ToolMotion
needle_motion = tool_motion
plot_needle = plot_tool_motion
write_needle_csv = write_tool_motion_csv
DEPRECATED_ALIASES = {
    "NeedleMotion": "ToolMotion",
    "needle_motion": "tool_motion",
    "plot_needle": "plot_tool_motion",
    "write_needle_csv": "write_tool_motion_csv",
}


def diagnosis_report(result, folder: str | os.PathLike) -> Path:
    """The diagnosis's HTML report with its plots, in ``folder``."""
    from mechanism.sysid.report import diagnosis_report as run

    return run(result, folder)


__all__ = [
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
    "inspect_recording",
    "read_recording",
    "driven_inertia_kgm2",
    "diagnosis_report",
    "identify",
    "inspect",
    "write_bench_recording",
    "load_machine",
    "needle_motion",
    "plot_needle",
    "plot_simulation",
    "probe",
    "read_table",
    "plot_sweep",
    "shipped_export",
    "shipped_folder",
    "shipped_machines",
    "shipped_model",
    "shipped_scene",
    "simulate",
    "sweep",
    "tool_motion",
    "plot_tool_motion",
    "view",
    "write_needle_csv",
    "write_tool_motion_csv",
    "write_table",
]
