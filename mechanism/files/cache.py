"""The cache of what mechanism builds once: converted CAD exports and compiled C kernels.

Location: ``$MECHANISM_CACHE/mechanism`` if set, else ``$XDG_CACHE_HOME/mechanism``, else
``~/.cache/mechanism`` (:func:`cache_root`, also ``mechanism.native.cache_root``); ``models/`` holds converted
exports (one folder per export content and driver joints), ``native/`` compiled kernels.

Every entry is built in a temporary and put in place atomically, with a manifest
(``.manifest.json`` in a folder entry, ``NAME.sha256`` beside a file entry) holding the
SHA-256 of each file and the key the entry was built for. An entry is checked against its
manifest before each use: a truncated, edited or foreign entry (a folder copied in from
another key, a file without its manifest) is rebuilt with a ``warning:`` line. The cache is
bounded (``$MECHANISM_CACHE_MAX_MB``, default 1024 MiB): after a new entry, the least
recently used others are removed until it fits. ``mechanism cache clear`` (:func:`clear_cache`)
empties it; ``mechanism cache info`` says where it is and how large.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import shutil
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from mechanism.errors import UserError

MANIFEST = ".manifest.json"
MANIFEST_FORMAT = "mechanism-cache-entry/1"
DEFAULT_MAX_MB = 1024
KINDS = ("models", "native")


def cache_root() -> Path:
    """Where mechanism keeps what it builds once (compiled kernels, converted CAD exports):
    ``$MECHANISM_CACHE/mechanism``, else ``$XDG_CACHE_HOME/mechanism``, else ``~/.cache/mechanism``."""
    root = (
        os.environ.get("MECHANISM_CACHE")
        or os.environ.get("XDG_CACHE_HOME")
        or Path.home() / ".cache"
    )
    return Path(root) / "mechanism"


def max_bytes() -> int:
    """The cache's bound (``$MECHANISM_CACHE_MAX_MB``, default 1024 MiB)."""
    text = os.environ.get("MECHANISM_CACHE_MAX_MB", "").strip()
    if not text:
        return DEFAULT_MAX_MB << 20
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        raise UserError(f"$MECHANISM_CACHE_MAX_MB must be a positive number of MiB, got {text!r}")
    return int(value * 2**20)


def file_hash(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _folder_hashes(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): file_hash(p)
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name != MANIFEST
    }


# ---------------------------------------------------------------- folder entries


def seal_folder(folder: Path, key: str) -> None:
    """Write ``folder``'s manifest: the hash of each of its files and the ``key`` it was built for."""
    document = {"format": MANIFEST_FORMAT, "key": key, "files": _folder_hashes(folder)}
    (folder / MANIFEST).write_text(json.dumps(document, indent=1, sort_keys=True))


def folder_problem(folder: Path, key: str) -> str | None:
    """None when ``folder`` is a whole entry built for ``key``, else what is wrong with it."""
    try:
        document = json.loads((folder / MANIFEST).read_text())
    except FileNotFoundError:
        return "it has no manifest (left half-written, or not made by mechanism)"
    except (OSError, ValueError) as exc:
        return f"its manifest is unreadable ({exc.__class__.__name__})"
    if not isinstance(document, dict) or document.get("format") != MANIFEST_FORMAT:
        return "its manifest is not one mechanism writes"
    if document.get("key") != key:
        return "it was built from other content (a foreign entry)"
    recorded = document.get("files")
    try:
        actual = _folder_hashes(folder)
    except OSError as exc:
        return f"it cannot be read ({exc.strerror})"
    if not isinstance(recorded, dict):
        return "its manifest lists no files"
    for name in sorted(set(recorded) | set(actual)):
        if name not in actual:
            return f"{name} is missing"
        if name not in recorded:
            return f"{name} was added after it was built"
        if recorded[name] != actual[name]:
            return f"{name} was truncated or edited (its content hash differs)"
    return None


def cached_folder(folder: Path, key: str, build, what: str) -> Path:
    """``folder`` as a checked cache entry: used as it is when whole, else (re)built by
    ``build(temporary_folder)`` and put in place atomically; the cache is then trimmed."""
    from mechanism.files.outputs import atomic_dir, transaction

    if folder.is_dir():
        problem = folder_problem(folder, key)
        if problem is None:
            _touch(folder)
            return folder
        warnings.warn(f"cache entry {folder} for {what}: {problem}; rebuilding it")
    with transaction(independent=True):  # published at once: the run reads it back
        with atomic_dir(folder) as tmp:
            build(Path(tmp))
            seal_folder(Path(tmp), key)
    prune(keep=folder)
    return folder


# ---------------------------------------------------------------- file entries


def _sidecar(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def file_problem(path: Path) -> str | None:
    """None when the file entry ``path`` matches its recorded hash, else what is wrong."""
    try:
        recorded = _sidecar(path).read_text().split()[0]
    except (OSError, IndexError):
        return "it has no recorded hash (left half-written, or not made by mechanism)"
    try:
        actual = file_hash(path)
    except OSError as exc:
        return f"it cannot be read ({exc.strerror})"
    return None if recorded == actual else "it was truncated or edited (its content hash differs)"


def install_file(temporary: Path, path: Path) -> None:
    """Put the finished file ``temporary`` at ``path`` with its hash (the hash last: a kill in
    between leaves a file without one, which the next use rebuilds)."""
    digest = file_hash(temporary)
    os.replace(temporary, path)
    side = _sidecar(path)
    tmp = side.with_name(f".{side.name}.{os.getpid()}.tmp")
    tmp.write_text(digest + "\n")
    os.replace(tmp, side)
    prune(keep=path)


# ---------------------------------------------------------------- size, clearing


@dataclass
class CacheInfo:
    root: Path
    entries: int
    bytes: int
    limit_bytes: int

    def describe(self) -> str:
        return (
            f"cache {self.root}: {self.entries} entries, {self.bytes / 2**20:.1f} MiB "
            f"(bound {self.limit_bytes / 2**20:.0f} MiB, set by MECHANISM_CACHE_MAX_MB)"
        )


def _size(path: Path) -> int:
    if path.is_dir() and not path.is_symlink():
        return sum(p.stat().st_size for p in path.rglob("*") if p.is_file() and not p.is_symlink())
    return path.lstat().st_size


def _entries() -> list[Path]:
    """The entries: folders in models/, files in native/ (a file's hash goes with it)."""
    found: list[Path] = []
    for kind in KINDS:
        with contextlib.suppress(OSError):
            found.extend(
                p
                for p in (cache_root() / kind).iterdir()
                if not p.name.startswith(".") and not p.name.endswith(".sha256")
            )
    return found


def _remove_entry(entry: Path) -> None:
    if entry.is_dir() and not entry.is_symlink():
        shutil.rmtree(entry, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            entry.unlink()
    with contextlib.suppress(OSError):
        _sidecar(entry).unlink()


def _touch(entry: Path) -> None:
    with contextlib.suppress(OSError):
        now = time.time()
        os.utime(entry, (now, now))


def info() -> CacheInfo:
    entries = _entries()
    total = 0
    for entry in entries:
        with contextlib.suppress(OSError):
            total += _size(entry)
    return CacheInfo(cache_root(), len(entries), total, max_bytes())


def prune(keep: Path | None = None) -> int:
    """Remove the least recently used entries until the cache fits its bound; never ``keep``.
    Returns the number of entries removed."""
    limit = max_bytes()
    sized = []
    for entry in _entries():
        with contextlib.suppress(OSError):
            sized.append((entry.stat().st_mtime, entry, _size(entry)))
    total = sum(size for _, _, size in sized)
    removed = 0
    for _, entry, size in sorted(sized, key=lambda item: item[0]):
        if total <= limit:
            break
        if keep is not None and entry == keep:
            continue
        _remove_entry(entry)
        total -= size
        removed += 1
    return removed


def clear_cache() -> CacheInfo:
    """Empty the cache (converted models, compiled kernels); returns what was there."""
    before = info()
    for kind in KINDS:
        folder = cache_root() / kind
        if folder.is_dir():
            shutil.rmtree(folder, ignore_errors=True)
            if folder.exists():
                raise UserError(f"cache {folder}: could not remove all of it (permissions?)")
    return before


cache_info = info
