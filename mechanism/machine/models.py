"""Where models live and how they are loaded (every load error is a UserError).

Shipped machines live in the repository's top-level ``assets/`` (the design card's layout),
one name per machine: ``machines/<name>.toml`` (the description, whose ``model`` names its
MJCF), ``mjcf/`` (every machine's MJCF side by side, each with ``<name>_scene.xml`` and a
``<name>.md`` with its provenance, menagerie style), ``meshes/<name>/``, ``cad/<name>/export/``
(the CAD export the MJCF was converted from) and ``measurements/<name>/``. The wheel installs the same tree as ``mechanism/assets/``, so the
relative paths inside it (a description's ``model``, an MJCF's ``meshdir``) hold in both.
A description's ``model`` may also name a CAD export: it is converted on first use into a
cache folder keyed by the export's content hash.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from mechanism.errors import UserError


def _assets_root() -> Path:
    package = Path(__file__).resolve().parent.parent
    installed = package / "assets"  # the wheel maps the top-level assets/ here
    return installed if installed.is_dir() else package.parent / "assets"


ASSETS = _assets_root()
MACHINES = ASSETS / "machines"
DEFAULT_MACHINE = "sapphire870"
DEFAULT_DESCRIPTION = MACHINES / f"{DEFAULT_MACHINE}.toml"
MAX_EXPORT_FOLDER_BYTES = 1 << 30


def shipped_machines() -> list[str]:
    return sorted(p.stem for p in MACHINES.glob("*.toml"))


def shipped_description(name: str) -> Path:
    return MACHINES / f"{name}.toml"


def shipped_folder(kind: str, name: str) -> Path:
    """A shipped machine's folder of one kind: ``meshes``, ``cad`` or ``measurements``
    (the MJCF of every machine lies in one folder: ``shipped_model``)."""
    return ASSETS / kind / name


def shipped_model(name: str) -> Path:
    """The MJCF a shipped machine's description names (``assets/mjcf/<file>.xml``)."""
    import tomllib

    with open(shipped_description(name), "rb") as handle:
        model = tomllib.load(handle)["machine"]["model"]
    return Path(os.path.normpath(MACHINES / model))


def shipped_scene(name: str) -> Path:
    """A shipped machine's scene (the MJCF on a floor, with lights): ``assets/mjcf/<name>_scene.xml``."""
    return ASSETS / "mjcf" / f"{name}_scene.xml"


DEFAULT_MODEL = shipped_model(DEFAULT_MACHINE)


def shipped_export(name: str) -> Path | None:
    """The CAD export a shipped machine's MJCF was converted from, if it ships one."""
    exports = sorted((shipped_folder("cad", name) / "export").glob("*.xml"))
    return exports[0] if exports else None


def model_path(path: str | os.PathLike | None = None) -> Path:
    """The MJCF to use: the given one, or the shipped machine's."""
    path = Path(path) if path else DEFAULT_MODEL
    if not path.exists():
        raise UserError(f"model {path}: no such file")
    if path.is_dir():
        raise UserError(f"model {path}: is a directory, expected an MJCF file")
    return path


def is_mjcf(path: Path) -> bool:
    with open(path, "rb") as handle:
        head = handle.read(4096).lstrip(b"\xef\xbb\xbf \t\r\n")
    while head.startswith(b"<?") or head.startswith(b"<!--"):
        end = head.find(b"?>" if head.startswith(b"<?") else b"-->")
        if end < 0:
            break
        head = head[end + (2 if head.startswith(b"<?") else 3) :].lstrip()
    return head.startswith(b"<mujoco")


def export_digest(export: Path) -> str:
    """Hash of the export and every file beside it (geometry, couplings side-car)."""
    digest = hashlib.sha256()
    total = 0
    for path in sorted(p for p in export.parent.rglob("*") if p.is_file()):
        total += path.stat().st_size
        if total > MAX_EXPORT_FOLDER_BYTES:
            raise UserError(
                f"CAD export folder {export.parent}: larger than {MAX_EXPORT_FOLDER_BYTES >> 30} GiB"
            )
        digest.update(str(path.relative_to(export.parent)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:20]


def converted_model(
    export: Path, drivers: tuple[str, ...] = (), ground: str | None = None, up: str | None = None
) -> Path:
    """The MJCF of a CAD export (``drivers`` kept as tree joints, ``ground`` fixed to the world, ``up``
    the export's up axis, None: its gravity vector, else z), converted once per content and cached
    (mechanism.files.cache: checked against its manifest at each use, rebuilt when damaged)."""
    from mechanism.converters import ExportError, convert
    from mechanism.files.cache import cached_folder
    from mechanism.native import cache_root

    extra = ([f"ground={ground}"] if ground else []) + ([f"up={up}"] if up else [])
    key = hashlib.sha256("\0".join([export_digest(export), *drivers, *extra]).encode()).hexdigest()[
        :20
    ]
    folder = cache_root() / "models" / f"{export.stem}-{key}"

    def build(tmp: Path) -> None:
        try:
            convert(export, tmp, name=export.stem, drivers=drivers, ground=ground, up=up)
        except ExportError as exc:
            raise UserError(str(exc)) from None

    cached_folder(folder, key, build, f"CAD export {export}")
    return folder / f"{export.stem}.xml"


def resolve_model(description) -> Path:
    """The MJCF behind a description (converting a CAD export when needed)."""
    path = Path(description.model)
    if not path.is_file():
        raise UserError(
            f"machine description {description.where('machine', 'model')}: no such file {path}"
        )
    machine = description.section("machine")
    return (
        path
        if is_mjcf(path)
        else converted_model(
            path,
            (description.motor_joint, description.shaft_joint),
            machine.get("ground"),
            machine.get("up"),
        )
    )


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
