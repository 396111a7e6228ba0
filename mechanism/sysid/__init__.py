"""System identification: recordings, the lumped baseline, diagnosis of missing physics, fleets, reports."""

from mechanism.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "recording": ("Recording", "read_recording"),
        "recording_map": ("RecordingMap", "read_recording_map", "resolve_recording_map"),
        "inspect_recording": ("inspect_recording",),
        "identification": ("identify", "IdentificationResult", "NotIdentifiable"),
        "diagnosis": ("diagnose", "Diagnosis"),
        "fleet": ("diagnose_fleet", "FleetResult"),
        "report": ("diagnosis_report", "identification_report"),
        "nominal": ("machine_drive_nominal",),
    },
)
