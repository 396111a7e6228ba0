"""Physics: the DC motor and its supply, friction laws, fabric loads, voltage inputs."""

from mechanism.lazy import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "motor": ("DCMotor", "SupplyLimit", "Thermal"),
        "friction": ("FrictionLaw", "FrictionSet"),
        "loads": ("FabricLoad",),
        "inputs": ("VoltageProfile", "DutyMap"),
    },
)
