"""CAD assembly export -> MJCF.

Readers (first- and second-generation Simscape Multibody XML, STL/STEP geometry) each
produce one neutral in-memory assembly; one writer turns an assembly into MJCF through
``mujoco.MjSpec``. Converters never import the simulator (``mechanism``).
"""

from converters.errors import ExportError

__all__ = ["ExportError"]
