"""mechanism: CAD assembly export -> MuJoCo simulation you can trust, inspect and correct.

The library is organised one noun per module (simulation, friction, probes, clearance,
identification, diagnosis, ...); the CLI in :mod:`mechanism.cli` is a thin shell over it.
"""

from mechanism.errors import UserError

__all__ = ["UserError"]
__version__ = "0.1.0"
