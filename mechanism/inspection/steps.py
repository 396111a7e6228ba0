"""The inspection steps of the demo on a described machine, one call each.

What is inspected comes from the description's ``[inspect]`` section (probes, clearance
pairs, the required clearance, the probe cycle's speed, a faulty design variant):
:func:`demo_probes`, :func:`demo_clearance` (and the faulty variant beside the nominal
design), :func:`demo_view` (the animation). :func:`demo` runs all three into a folder and
returns the files it wrote, for the demo's index page.
"""

from __future__ import annotations

import os
from pathlib import Path

from mechanism.errors import UserError

DEFAULT_PROBE_SPEED_RPM = 600.0


def _inspect(machine) -> dict:
    return machine.description.section("inspect")


def demo_probes(out: Path, machine) -> list[Path]:
    from mechanism.inspection.probes import Probe, run_probes

    specs = _inspect(machine).get("probes", [])
    if not specs:
        return []
    probes = [
        Probe(name, quantity) for name, _, quantity in (spec.rpartition(":") for spec in specs)
    ]
    speed = _inspect(machine).get("probe_speed_rpm", DEFAULT_PROBE_SPEED_RPM)
    result = run_probes(probes, machine.model_path, speed_rpm=speed, driver=machine.shaft_joint)
    csv, png = out / "probes.csv", out / "probes.png"
    result.write_csv(csv)
    result.plot(png, probes)
    return [csv, png]


def demo_clearance(out: Path, machine) -> list[Path]:
    import numpy as np

    from mechanism.inspection.clearance import check_clearance, parse_pairs, write_json, write_rows
    from mechanism.inspection.variants import VariantSet, parameter, run_variants
    from mechanism.machine.models import load_model

    inspect = _inspect(machine)
    if not inspect.get("clearance_pairs"):
        return []
    model = load_model(machine.model_path)
    required = inspect.get("required_clearance_mm", 0.0)
    pairs = parse_pairs(",".join(inspect["clearance_pairs"]), model)
    report = check_clearance(model, pairs, required_mm=required, driver=machine.shaft_joint)
    csv, report_json = out / "clearance.csv", out / "clearance.json"
    write_rows(csv, report.rows())
    write_json(report_json, report.to_json())
    written = [csv, report_json]
    if "mistimed_variant" in inspect:
        name, _, offset = inspect["mistimed_variant"].partition("=")
        try:
            value = float(offset)
        except ValueError:
            raise UserError(
                f"[inspect] mistimed_variant {inspect['mistimed_variant']!r}: expected 'parameter=offset'"
            ) from None
        param = parameter(name.strip(), presets=machine.description.variant_presets)
        variants = VariantSet(
            [param], ["nominal", f"{name.strip()} {value:+g}"], np.array([[0.0], [value]])
        )
        batch = run_variants(
            model, variants, pairs[:1], required, machine.shaft_joint, progress=False
        )
        variants_csv = out / "variants.csv"
        write_rows(variants_csv, batch.table())
        written.append(variants_csv)
    return written


def demo_view(out: Path, machine, frames: int = 120) -> list[Path]:
    from mechanism.inspection.viewer import view

    html = out / "machine.html"
    inspect = _inspect(machine)
    markers = [machine.tool_site] if machine.tool_site else []
    pairs = inspect.get("clearance_pairs", [])[:1]
    view(
        html,
        machine.model_path,
        frames=frames,
        probe_names=markers,
        pairs=pairs or None,
        driver=machine.shaft_joint,
        description=machine.description,
    )
    return [html]


def demo(out: str | os.PathLike, machine) -> list[Path]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return demo_probes(out, machine) + demo_clearance(out, machine) + demo_view(out, machine)
