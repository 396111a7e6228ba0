"""Where models live and how they are loaded (every load error is a UserError)."""

from __future__ import annotations

import os
from pathlib import Path

from mechanism.errors import UserError

REPO_ROOT = Path(__file__).resolve().parent.parent
ASSETS = REPO_ROOT / "assets"
DEFAULT_MODEL = ASSETS / "mjcf" / "sewing_machine.xml"


def model_path(path: str | os.PathLike | None = None) -> Path:
    """The MJCF to use: the given one, or the shipped sewing machine."""
    path = Path(path) if path else DEFAULT_MODEL
    if not path.exists():
        raise UserError(f"model {path}: no such file")
    if path.is_dir():
        raise UserError(f"model {path}: is a directory, expected an MJCF file")
    return path


def load_spec(path: str | os.PathLike | None = None):
    """An editable ``mujoco.MjSpec`` of the model."""
    import mujoco

    path = model_path(path)
    try:
        return mujoco.MjSpec.from_file(str(path))
    except Exception as exc:  # mujoco raises ValueError with a multi-line message
        raise UserError(f"model {path}: {' '.join(str(exc).split())}") from None


def load_model(path: str | os.PathLike | None = None):
    """A compiled ``mujoco.MjModel`` of the model."""
    spec = load_spec(path)
    try:
        return spec.compile()
    except Exception as exc:
        raise UserError(f"model {model_path(path)}: {' '.join(str(exc).split())}") from None
