"""The journal of a running sweep: rows appended as they finish, so an interrupted sweep resumes."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mechanism.errors import UserError
from mechanism.inspection.variants import VariantSet
from mechanism.machine.machine import Machine

JOURNAL_FORMAT = "mechanism-sweep-journal/1"


def journal_path(csv_path: str | os.PathLike) -> Path:
    """Where a sweep writing ``csv_path`` keeps its rows until it is complete."""
    csv_path = Path(csv_path)
    return csv_path.with_name(csv_path.name + ".partial")


def sweep_fingerprint(machine: Machine, variants: VariantSet, options: Any) -> str:
    """What makes two sweeps the same: machine (description and model file), variants, run."""
    digest = hashlib.sha256()
    digest.update(repr(replace(machine.description, path=None)).encode())
    digest.update(Path(machine.model_path).read_bytes())
    digest.update(repr(machine.config).encode())
    digest.update(json.dumps([[p.name, p.target] for p in variants.parameters]).encode())
    digest.update(json.dumps(variants.names).encode())
    digest.update(np.ascontiguousarray(variants.values, dtype=float).tobytes())
    digest.update(repr(options).encode())
    return digest.hexdigest()


def read_journal(path: str | os.PathLike, fingerprint: str) -> dict[int, dict[str, Any]]:
    """The rows an interrupted sweep left (a torn last line, from a kill mid-write, is dropped)."""
    path = Path(path)
    if not path.exists():
        return {}
    from mechanism.files.limits import read_bounded

    lines = (
        read_bounded(path, "sweep journal", 1 << 30).decode("utf-8", errors="replace").split("\n")
    )
    try:
        header = json.loads(lines[0])
    except json.JSONDecodeError:
        header = None
    if not isinstance(header, dict) or header.get("format") != JOURNAL_FORMAT:
        raise UserError(f"{path}: not a sweep journal; delete it or choose another --csv")
    if header.get("fingerprint") != fingerprint:
        raise UserError(
            f"{path}: left by a different sweep (other machine, variants or run options); delete it to start "
            "over, or resume with the same inputs"
        )
    done = {}
    for line in lines[1:]:
        try:
            entry = json.loads(line)
            done[int(entry["index"])] = dict(entry["row"])
        except (json.JSONDecodeError, KeyError, TypeError, ValueError):
            continue  # the torn line a kill leaves behind
    return done


def journal_write_error(path: str | os.PathLike, exc: OSError) -> UserError:
    """A failed journal write (a full disk) as one line: the rows written so far are kept."""
    from mechanism.files.outputs import disk_problem

    cause = disk_problem(exc) or exc.strerror or str(exc)
    return UserError(
        f"sweep journal {path}: cannot write it, {cause}; the rows done so far are kept there, "
        "and --resume continues the sweep once the cause is fixed"
    )


@contextlib.contextmanager
def open_journal(path: str | os.PathLike, fingerprint: str, fresh: bool):
    """The journal open for appending rows (a fresh one starts with its header)."""
    path = Path(path)
    try:
        handle = _open(path, fingerprint, fresh)
    except OSError as exc:
        raise journal_write_error(path, exc) from None
    try:
        yield handle
    finally:
        try:
            handle.close()
        except OSError as exc:
            raise journal_write_error(path, exc) from None


def _open(path: Path, fingerprint: str, fresh: bool):
    if fresh:
        path.parent.mkdir(parents=True, exist_ok=True)  # as the CSV's own folder will be
        with open(path, "w", encoding="utf-8") as handle:
            handle.write(json.dumps({"format": JOURNAL_FORMAT, "fingerprint": fingerprint}) + "\n")
    else:
        text = path.read_bytes()
        if not text.endswith(b"\n"):  # drop the torn line before appending
            path.write_bytes(text[: text.rfind(b"\n") + 1])
    return open(path, "a", encoding="utf-8")
