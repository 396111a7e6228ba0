"""Two MJCF files that describe the same model, to the precision a CAD export carries.

A regenerated conversion is compared with the committed one number by number, not byte by
byte: the last bits of a centre of mass or a loop anchor come out of numpy's and trimesh's
arithmetic, whose rounding moves between releases (an anchor on an axis came out 5.491385e-12
or 5.491382e-12 m off it, where the model's lengths are centimetres)."""

from __future__ import annotations

from pathlib import Path

import defusedxml.ElementTree as ET
import numpy as np

RELATIVE = 1e-9  # of the attribute's largest entry: nine of the ten digits the converter writes


def _numbers(text: str) -> np.ndarray | None:
    try:
        return np.array([float(token) for token in text.split()])
    except ValueError:
        return None


def difference(a: Path, b: Path, relative: float = RELATIVE) -> str | None:
    """Where the models in ``a`` and ``b`` differ (element, attribute, values), or None."""
    left, right = list(ET.parse(a).getroot().iter()), list(ET.parse(b).getroot().iter())
    if len(left) != len(right):
        return f"{len(left)} elements against {len(right)}"
    for x, y in zip(left, right):
        where = f"<{x.tag} name={x.get('name')!r}>"
        if x.tag != y.tag or sorted(x.attrib) != sorted(y.attrib):
            return f"{where} against <{y.tag} name={y.get('name')!r}> {sorted(y.attrib)}"
        for key, value in x.attrib.items():
            u, v = _numbers(value), _numbers(y.attrib[key])
            if u is None or v is None or u.shape != v.shape:
                if value != y.attrib[key]:
                    return f"{where} {key}: {value!r} against {y.attrib[key]!r}"
                continue
            scale = max(
                float(np.max(np.abs(u), initial=0.0)), float(np.max(np.abs(v), initial=0.0))
            )
            if np.any(np.abs(u - v) > relative * scale):
                return f"{where} {key}: {value} against {y.attrib[key]}"
    return None
