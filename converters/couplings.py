"""The couplings side-car: belts, gears and worm gears that CAD mates do not carry.

``<export stem>.couplings.json`` next to the export (format in docs/architecture.md)::

    {"format": "mechanism-couplings/1",
     "couplings": [{"name": "motor_belt", "kind": "belt", "input": "MOTOR", "output": "MAIN_SHAFT",
                    "ratio": 8.0, "offset_deg": 0.0}]}

``q_input = ratio * q_output + offset``, joint positions measured from the assembly pose.
"""

from __future__ import annotations

import difflib
import json
import math
from pathlib import Path

from mechanism.converters.assembly import Assembly, Coupling
from mechanism.converters.errors import ExportError
from mechanism.converters.names import sanitize
from mechanism.converters.safety import MAX_SIDECAR_BYTES, read_bounded

FORMAT = "mechanism-couplings/1"
KEYS = {"name", "kind", "input", "output", "ratio", "offset_deg"}


def sidecar_path(export: Path) -> Path:
    export = Path(export)
    return export.with_name(f"{export.stem}.couplings.json")


def _number(entry: dict, key: str, where: str, default=None) -> float:
    value = entry.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ExportError(f"{where}: '{key}' must be a number, got {json.dumps(value)}")
    if not math.isfinite(value):
        raise ExportError(f"{where}: '{key}' must be finite, got {value}")
    return float(value)


def _text(entry: dict, key: str, where: str, default: str | None = None) -> str:
    value = entry.get(key, default)
    if not isinstance(value, str) or not value.strip():
        raise ExportError(f"{where}: '{key}' must be a non-empty string, got {json.dumps(value)}")
    return value.strip()


def _joint(assembly: Assembly, name: str, where: str, role: str):
    joint = assembly.joint(name)
    if joint is None:
        matches = [j for j in assembly.joints if not j.synthetic and sanitize(j.name) == name]
        joint = matches[0] if len(matches) == 1 else None
    if joint is None:
        names = sorted({j.name for j in assembly.joints if not j.synthetic})
        close = difflib.get_close_matches(name, names, n=3, cutoff=0.4) or names[:3]
        hint = f" (did you mean {', '.join(close)}?)" if close else " (the export has no joints)"
        raise ExportError(f"{where}: {role} joint '{name}' does not exist in the export{hint}")
    if joint.dof != 1:
        raise ExportError(
            f"{where}: {role} joint '{joint.name}' is a {joint.kind} joint with {joint.dof} degrees of "
            f"freedom; couplings need a 1-DOF revolute or prismatic joint"
        )
    return joint


def read_couplings(assembly: Assembly, path: Path | None = None) -> None:
    """Add the side-car's couplings to ``assembly`` (nothing if there is no side-car)."""
    path = Path(path) if path else sidecar_path(assembly.source)
    if not path.exists():
        return
    where = f"couplings side-car {path.name}"
    data = read_bounded(path, MAX_SIDECAR_BYTES, "couplings side-car")
    try:
        document = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ExportError(
            f"{where}: not valid JSON ({exc.__class__.__name__}: {str(exc)[:80]})"
        ) from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise ExportError(f'{where}: expected a JSON object with "format": "{FORMAT}"')
    entries = document.get("couplings", [])
    if not isinstance(entries, list):
        raise ExportError(f"{where}: 'couplings' must be a list")
    seen = set()
    for index, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise ExportError(f"{where}: coupling #{index + 1} must be a JSON object")
        here = f"{where}, coupling #{index + 1}"
        name = _text(entry, "name", here)
        here = f"{where}, coupling '{name}'"
        if name in seen:
            raise ExportError(f"{here}: the name is used twice")
        seen.add(name)
        unknown = sorted(set(entry) - KEYS)
        if unknown:
            assembly.warn(f"{here}: unknown key(s) {', '.join(unknown)} ignored")
        ratio = _number(entry, "ratio", here)
        if ratio == 0:
            raise ExportError(f"{here}: 'ratio' must not be zero")
        offset_deg = _number(entry, "offset_deg", here, 0.0)
        input_joint = _joint(assembly, _text(entry, "input", here), here, "input")
        output_joint = _joint(assembly, _text(entry, "output", here), here, "output")
        if input_joint is output_joint:
            raise ExportError(f"{here}: input and output are the same joint '{input_joint.name}'")
        if offset_deg and input_joint.primitives[0].kind != "hinge":
            raise ExportError(
                f"{here}: 'offset_deg' needs a revolute input joint, '{input_joint.name}' is {input_joint.kind}"
            )
        assembly.couplings.append(
            Coupling(
                name=name,
                kind=_text(entry, "kind", here, "coupling"),
                input=input_joint.name,
                output=output_joint.name,
                ratio=ratio,
                offset=math.radians(offset_deg),
            )
        )
