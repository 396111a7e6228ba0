"""The inspection steps of ``make demo`` on the shipped sewing machine, one call each.

:func:`demo_probes` (crank pin and needle-bar loads, needle tip motion over a cycle),
:func:`demo_clearance` (needle vs hook and needle vs needle plate, and a mistimed-hook
variant), :func:`demo_view` (the animation). :func:`demo` runs all three into a folder and
returns the files it wrote, for the demo's index page.
"""

from __future__ import annotations

import os
from pathlib import Path

CRANK_PIN = "crank_pin"  # the joint between the crank and the crank link
NEEDLE_BAR = "needle_bar"  # the needle bar's joint in its bushing
NEEDLE_TIP = "needle_tip"
PAIRS = "needle:hook,needle:needle_plate"
REQUIRED_MM = 0.0  # the shipped machine's hook point runs 0-0.1 mm from the needle (service manuals)
MISTIMED_HOOK_DEG = 40.0  # hook advanced by 40 deg of hook rotation (20 deg of arm)


def demo_probes(out: Path, model_path: str | os.PathLike | None = None, speed_rpm: float = 600.0) -> list[Path]:
    from mechanism.inspection.probes import Probe, run_probes

    probes = [
        Probe(CRANK_PIN, "force"),
        Probe(CRANK_PIN, "torque"),
        Probe(NEEDLE_BAR, "force"),
        Probe(NEEDLE_TIP, "position"),
        Probe(NEEDLE_TIP, "acceleration"),
    ]
    result = run_probes(probes, model_path, speed_rpm=speed_rpm)
    csv, png = out / "probes.csv", out / "probes.png"
    result.write_csv(csv)
    result.plot(png, probes)
    return [csv, png]


def demo_clearance(out: Path, model_path: str | os.PathLike | None = None) -> list[Path]:
    import numpy as np

    from mechanism.inspection.clearance import check_clearance, parse_pairs, write_json, write_rows
    from mechanism.machine.models import load_model
    from mechanism.inspection.variants import VariantSet, parameter, run_variants

    model = load_model(model_path)
    pairs = parse_pairs(PAIRS, model)
    report = check_clearance(model, pairs, required_mm=REQUIRED_MM)
    csv, report_json = out / "clearance.csv", out / "clearance.json"
    write_rows(csv, report.rows())
    write_json(report_json, report.to_json())
    variants = VariantSet([parameter("hook_timing_deg")], ["nominal", "mistimed hook"], np.array([[0.0], [MISTIMED_HOOK_DEG]]))
    batch = run_variants(model, variants, pairs[:1], REQUIRED_MM, progress=False)
    variants_csv = out / "variants.csv"
    write_rows(variants_csv, batch.table())
    return [csv, report_json, variants_csv]


def demo_view(out: Path, model_path: str | os.PathLike | None = None, frames: int = 120) -> list[Path]:
    from mechanism.inspection.viewer import view

    html = out / "machine.html"
    view(html, model_path, frames=frames, probe_names=[NEEDLE_TIP], pairs=PAIRS.split(",")[0])
    return [html]


def demo(out: str | os.PathLike, model_path: str | os.PathLike | None = None) -> list[Path]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return demo_probes(out, model_path) + demo_clearance(out, model_path) + demo_view(out, model_path)
