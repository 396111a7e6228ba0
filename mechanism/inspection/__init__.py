"""Inspection: tool motion, probes, clearance, design variants, dynamic sweeps, the viewer."""

from mechanism.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "tool": ("ToolMotion", "tool_motion", "NeedleMotion", "needle_motion"),
        "probes": ("Probe", "ProbeResult", "run_probes", "plot_probes"),
        "clearance": ("Pair", "check_clearance", "parse_pairs", "all_pairs"),
        "variants": (
            "Parameter",
            "VariantSet",
            "parameter",
            "apply_parameter",
            "read_variants",
            "variants_from_document",
            "run_variants",
        ),
        "sweep": ("SweepOptions", "SweepResult", "run_sweep", "variant_machine", "plot_sweep"),
        "sweep_metrics": ("METRICS", "variant_metrics", "driven_inertia_kgm2"),
        "viewer": ("view",),
        "steps": ("demo",),
    },
)
