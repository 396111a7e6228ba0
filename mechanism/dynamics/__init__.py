"""Dynamics: the full multibody run (mujoco.rollout), the reduced 1-DOF model, the lumped drive."""

from mechanism.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "simulation": (
            "simulate",
            "simulate_batch",
            "SimulationResult",
            "plot_simulation",
            "MAX_DURATION_S",
        ),
        "reduced": ("ReducedModel", "reduced_model"),
        "lumped": ("DriveNominal", "MotorConstants"),
    },
)
