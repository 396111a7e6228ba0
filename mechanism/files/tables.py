"""Numeric CSV tables in and out: the one place CSV is parsed and written.

Input tables (voltage profiles, bench recordings, variant lists) are untrusted: they are
read with the standard ``csv`` module, every value must parse as a finite float, and every
problem becomes one :class:`~mechanism.errors.UserError` naming the file, line and column.
Output tables carry units in their column names (``time_s``, ``needle_z_mm``) so that a
spreadsheet or ``pandas.read_csv`` opens them as they are.
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np

from mechanism.errors import UserError
from mechanism.files.limits import read_bounded
from mechanism.files.outputs import atomic_file


@dataclass
class Table:
    """Columns of floats by name, plus the ``# key: value`` metadata from leading comments."""

    columns: dict[str, np.ndarray]
    metadata: dict[str, str] = field(default_factory=dict)
    source: str = "<table>"

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0


def read_table(
    path: str | os.PathLike,
    required: Sequence[str] = (),
    optional: Sequence[str] = (),
    aliases: Mapping[str, Sequence[str]] | None = None,
    min_rows: int = 1,
    what: str = "table",
) -> Table:
    """Read a numeric CSV with optional leading ``#`` comment lines and a header line.

    ``required`` columns must be present; ``optional`` ones are read when present; other
    columns are ignored (unknown columns never fail a read). ``aliases`` maps a canonical
    name to accepted alternatives (e.g. ``{"time": ["time_s"]}``). Raises UserError with
    the file name and line for anything malformed (missing column, non-numeric or
    non-finite value, ragged row, empty file).
    """
    path = Path(path)
    label = f"{what} {path}"
    data = read_bounded(path, what)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise UserError(f"{label}: not UTF-8 text") from None
    del data
    return parse_table(text, required, optional, aliases, min_rows, label)


def header_comments(lines: Sequence[str], label: str) -> tuple[dict[str, str], int]:
    """The ``# key: value`` comment lines before a table's header, as metadata, and the index of
    the header line (blank and other comment lines are skipped)."""
    metadata: dict[str, str] = {}
    start = 0
    while start < len(lines) and (
        lines[start].lstrip().startswith("#") or not lines[start].strip()
    ):
        comment = lines[start].lstrip().lstrip("#").strip()
        if ":" in comment:
            key, value = comment.split(":", 1)
            metadata[key.strip()] = value.strip()
        start += 1
    if start >= len(lines):
        raise UserError(f"{label}: empty (no header line)")
    return metadata, start


def parse_table(
    text: str,
    required: Sequence[str] = (),
    optional: Sequence[str] = (),
    aliases: Mapping[str, Sequence[str]] | None = None,
    min_rows: int = 1,
    label: str = "table",
) -> Table:
    """:func:`read_table` on text already read (``label`` names it in errors)."""
    lines = text.splitlines()
    metadata, start = header_comments(lines, label)
    reader = csv.reader(io.StringIO("\n".join(lines[start:])))
    try:
        header = [name.strip() for name in next(reader)]
    except (StopIteration, csv.Error) as exc:
        raise UserError(f"{label}: cannot read the header line ({exc})") from None
    if len(set(header)) != len(header):
        raise UserError(f"{label}: duplicated column names in the header")

    aliases = dict(aliases or {})
    index: dict[str, int] = {}
    for name in list(required) + list(optional):
        for candidate in [name, *aliases.get(name, ())]:
            if candidate in header:
                index[name] = header.index(candidate)
                break
    missing = [name for name in required if name not in index]
    if missing:
        raise UserError(
            f"{label}: missing required column(s) {', '.join(missing)}; header has {', '.join(header) or 'nothing'}"
        )

    values: dict[str, list[float]] = {name: [] for name in index}
    for row_number, row in enumerate(reader, start=start + 2):
        if not row or all(not cell.strip() for cell in row):
            continue
        if row[0].lstrip().startswith("#"):
            continue
        if len(row) != len(header):
            raise UserError(
                f"{label}: line {row_number} has {len(row)} fields, the header has {len(header)}"
            )
        for name, col in index.items():
            cell = row[col].strip()
            try:
                number = float(cell)
            except ValueError:
                raise UserError(
                    f"{label}: line {row_number}, column {header[col]}: not a number ({cell[:20]!r})"
                ) from None
            if not math.isfinite(number):
                raise UserError(
                    f"{label}: line {row_number}, column {header[col]}: value is {cell} (NaN/inf not allowed)"
                )
            values[name].append(number)
    n_rows = len(next(iter(values.values()))) if values else 0
    if n_rows < min_rows:
        raise UserError(f"{label}: {n_rows} data row(s), at least {min_rows} needed")
    return Table({name: np.asarray(v, dtype=float) for name, v in values.items()}, metadata, label)


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in a boolean column as (first, last) index pairs (no wrap-around)."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask).astype(int), [0]]))
    return list(
        zip(np.flatnonzero(edges == 1).tolist(), (np.flatnonzero(edges == -1) - 1).tolist())
    )


def check_increasing(time: np.ndarray, label: str, name: str = "time") -> None:
    """Strictly increasing sample times, else a UserError naming the first bad row."""
    steps = np.diff(time)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        i = int(bad[0])
        kind = "duplicated" if steps[i] == 0 else "decreasing"
        raise UserError(
            f"{label}: {name} is not strictly increasing ({kind} at data row {i + 2}: {time[i]} then {time[i + 1]})"
        )


def write_table(
    path: str | os.PathLike,
    columns: Mapping[str, Iterable[float]],
    comments: Sequence[str] = (),
    fmt: str = "%.9g",
) -> Path:
    """Write columns (names with units, e.g. ``time_s``) as CSV, atomically."""
    names = list(columns)
    data = [
        np.asarray(list(v) if not isinstance(v, np.ndarray) else v, dtype=float)
        for v in columns.values()
    ]
    n = {len(d) for d in data}
    if len(n) > 1:
        raise ValueError(f"columns of different lengths: {dict(zip(names, map(len, data)))}")
    path = Path(path)
    with atomic_file(path) as handle:
        for line in comments:
            handle.write(f"# {line}\n")
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(names)
        if data:
            matrix = np.column_stack(data)
            for row in matrix:
                writer.writerow([fmt % value for value in row])
    return path
