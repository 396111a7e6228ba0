"""Kinematics: closed-linkage poses, linkage tables over a shaft revolution, kinematic cycles."""

from mechanism.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "pose": ("solve_pose", "velocity_ratios", "PoseError", "joint_dof"),
        "linkage": ("LinkageTables", "compute_tables", "periodic_interp", "periodic_derivative"),
        "cycle": ("kinematic_cycle", "CycleStates", "cycle_angles"),
    },
)
