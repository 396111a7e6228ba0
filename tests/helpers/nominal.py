"""Drive nominals for tests: the shipped sewing machine's
and a scaled machine of another size, and the sysid/testbench entry points bound to them."""

from __future__ import annotations

import functools
from dataclasses import replace

from mechanism.dynamics.lumped import DriveNominal


def sapphire_nominal() -> DriveNominal:
    """The shipped machine's drive as the package gives it (the thesis's numbers: motor
    R 1.1 ohm, Kt 0.017, Ke 0.021, 8:1; tests compare against the thesis separately)."""
    from mechanism.api import drive_nominal

    return drive_nominal(None)


SAPPHIRE = sapphire_nominal()

# A press: 20x the inertia, a 12:1 gear, a stronger motor (0.5 ohm, Kt = Ke 0.05), 6x the
# Coulomb friction and viscous friction a tenth of the back-emf damping (as in the sewing machine)
PRESS = replace(
    SAPPHIRE.scaled(
        inertia=20.0,
        ratio=12.0,
        torque=6.0,
        resistance_ohm=0.5,
        torque_constant_Nm_per_A=0.05,
        back_emf_V_s_per_rad=0.05,
    ),
    viscous_shaft_Nm_s_per_rad=0.072,
)


def bench_recording(*args, nominal: DriveNominal = SAPPHIRE, **kwargs):
    from mechanism.testbench import make_recording

    return make_recording(*args, nominal=nominal, **kwargs)


def identify(*args, nominal: DriveNominal = SAPPHIRE, **kwargs):
    from mechanism.sysid.identification import identify as run

    return run(*args, nominal=nominal, **kwargs)


def diagnose(*args, nominal: DriveNominal = SAPPHIRE, **kwargs):
    from mechanism.sysid.diagnosis import diagnose as run

    return run(*args, nominal=nominal, **kwargs)


@functools.lru_cache(maxsize=None)
def effects(nominal: DriveNominal = SAPPHIRE):
    from mechanism.sysid.effects import library

    return library(nominal)
