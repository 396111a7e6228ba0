"""CAD assembly export -> MJCF.

Readers (first- and second-generation Simscape Multibody XML, STL/STEP geometry) each
produce one neutral in-memory assembly; one writer turns an assembly into MJCF through
``mujoco.MjSpec``. Converters never import the simulator (``mechanism``).

    converters.read(path) -> Assembly                     # inspect an export
    converters.convert(path, outdir, name=None, mesh_dir=None) -> ConversionReport
"""

from mechanism.converters.assembly import Assembly
from mechanism.converters.convert import ConversionReport, convert
from mechanism.converters.errors import ExportError
from mechanism.converters.load import read

__all__ = ["Assembly", "ConversionReport", "ExportError", "convert", "read"]
