"""Conversion time against its unavoidable parts, measured in the same run.

For each export: the whole conversion versus (a) reading the geometry files alone with
trimesh/cascadio and (b) compiling the finished MJCF with MuJoCo. A ratio near 1 to (a)+(b)
means the converter adds little on top of the libraries it uses. Where the export has STEP
parts, (a) as the converter does it (worker processes, one per core) against the same files
read one after another in this process.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _seconds(function) -> float:
    started = time.perf_counter()
    function()
    return time.perf_counter() - started


def _exports(scratch: Path):
    from tests.helpers.exports import FourBar  # the hand-written test export

    yield "four-bar (gen-1, STL)", FourBar().export(scratch)
    shared = REPO.parent / "shared" / "cad-exports"
    for relative in ("legs-creo-firstgen/LEGS_MECHANISM.xml", "youbot-onshape/youBot.xml"):
        if (shared / relative).exists():
            yield relative.split("/")[0], shared / relative


def main() -> None:
    import mujoco

    from mechanism.converters import convert, read
    from mechanism.converters.geometry import _read, load_meshes

    with tempfile.TemporaryDirectory() as scratch:
        scratch = Path(scratch)
        exports = list(_exports(scratch))
        # imports and first-call costs are not conversion time
        convert(exports[0][1], scratch / "warm-up")
        for label, export in exports:
            out = scratch / label.split()[0]
            total = _seconds(lambda: convert(export, out))
            geometry = _seconds(lambda: load_meshes(read(export)))
            model_file = next(out.glob("*.xml"))
            compile_ = _seconds(lambda: mujoco.MjModel.from_xml_path(str(model_file)))
            print(
                f"{label:28s} convert {total:7.2f} s   geometry {geometry:7.2f} s   compile {compile_:6.2f} s   "
                f"convert / (geometry + compile) = {total / (geometry + compile_):5.2f}"
            )
            files = {p.geometry for p in read(export).real_parts if p.geometry is not None}
            if any(path.suffix.lower() in (".step", ".stp") for path in files):
                serial = _seconds(lambda: [_read(path) for path in files])
                print(
                    f"{'':28s} geometry one file after another {serial:7.2f} s: "
                    f"in worker processes {serial / geometry:4.2f}x faster"
                )


if __name__ == "__main__":
    main()
