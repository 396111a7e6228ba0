"""The machine: its description (TOML), the Machine every verb takes, roles, shipped models."""

from mechanism.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "machine": ("Machine", "MachineConfig", "load_machine"),
        "description": (
            "MachineDescription",
            "read_description",
            "parse_description",
            "SCHEMA",
            "schema_markdown",
        ),
        "roles": ("guess_roles", "guess_driver"),
        "draft": ("draft_description",),
        "models": (
            "DEFAULT_DESCRIPTION",
            "DEFAULT_MODEL",
            "shipped_description",
            "shipped_export",
            "shipped_folder",
            "shipped_machines",
            "shipped_model",
            "shipped_scene",
            "load_model",
            "load_spec",
            "resolve_model",
        ),
    },
)
