"""Recording files as benches write them: named numeric columns out of CSV/TSV (plain or
``.gz``/``.bz2``/``.xz``/``.zip`` of one file), MATLAB ``.mat`` (v5 through scipy; v7.3/HDF5
through h5py), Parquet and Feather (pyarrow), LabVIEW TDMS (npTDMS), and JSON (an array of
records, JSON lines, or a key holding either).

Every reader is bounded as :func:`mechanism.files.limits.read_bounded` is: the file's bytes
are counted as read, a compressed stream is counted as it is decompressed (a zip bomb stops
at the input limit, a zip member's declared size is checked first), and the values a file
declares (matrix dimensions, row counts, channel lengths) are checked with
:func:`~mechanism.files.limits.check_elements` before anything is allocated. A malformed
file is one :class:`~mechanism.errors.UserError`; a missing optional library says which
extra installs it.

What comes back is a :class:`Columns`: names as the file writes them (struct fields and
groups joined with ``.``, a MATLAB matrix's columns as ``name(:,j)``, a TDMS channel as
``group/channel`` or its name alone when unique, a TDMS waveform's time track as
``group/channel.time``), values as float arrays or, for text columns (ISO time stamps), lists of
strings that :meth:`Columns.numeric` converts when a column is used. Unused columns never
fail a read. :func:`write_columns` writes the formats the test bench offers.
"""

from __future__ import annotations

import bz2
import csv
import gzip
import io
import itertools
import json
import logging
import lzma
import math
import os
import re
import zipfile
import zlib
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import IO, Callable, Iterator, Literal, Mapping, Sequence, get_args

import numpy as np

from mechanism.errors import UserError
from mechanism.files.limits import (
    check_elements,
    max_input_bytes,
    read_bounded,
    read_stream_bounded,
)
from mechanism.files.tables import header_comments

# format name -> (file name endings, optional extra or None, library, module)
FORMATS = {
    "csv": ((".csv", ".tsv", ".txt", ".dat"), None),
    "mat": ((".mat",), None),
    "parquet": ((".parquet", ".pq"), "parquet"),
    "feather": ((".feather", ".arrow", ".ipc"), "parquet"),
    "tdms": ((".tdms",), "tdms"),
    "json": ((".json", ".jsonl", ".ndjson"), None),
}
COMPRESSIONS = (".gz", ".bz2", ".xz", ".zip")
WriteFormat = Literal["csv", "csv.gz", "parquet", "mat"]  # what write_columns writes
WRITE_FORMATS: tuple[WriteFormat, ...] = get_args(WriteFormat)
MAX_MATRIX_COLUMNS = 64  # a MATLAB matrix wider than this is not a signal table


@dataclass
class Columns:
    """Named columns of one file, and the ``key: value`` metadata it carries."""

    columns: dict[str, object]  # name -> float array, or a list of str (text)
    metadata: dict[str, str] = field(default_factory=dict)
    label: str = "recording"
    format: str = "csv"
    compression: str | None = None

    @property
    def names(self) -> list[str]:
        return list(self.columns)

    def find(self, name: str) -> str | None:
        """The column's name as stored: ``name`` itself, or a matrix column written
        ``m[:, 0]``/``m[0]`` (0-based) or ``m(1)`` for ``m(:,1)`` (MATLAB's 1-based form)."""
        if name in self.columns:
            return name
        compact = name.replace(" ", "")
        if compact in self.columns:
            return compact
        match = _INDEXED.match(compact)
        if match:
            base, index = match.group(1), int(match.group(3))
            column = index + 1 if match.group(2) == "[" else index
            for candidate in (f"{base}(:,{column})", f"{base}({column})"):
                if candidate in self.columns:
                    return candidate
        return None

    def __contains__(self, name: str) -> bool:
        return self.find(name) is not None

    def length(self, name: str) -> int:
        return len(self.columns[self.find(name) or name])  # type: ignore[arg-type]

    def numeric(self, name: str) -> np.ndarray:
        """The column as floats; an ISO 8601 time-stamp column as seconds since its first stamp."""
        name = self.find(name) or name
        values = self.columns[name]
        if isinstance(values, np.ndarray):
            return values
        return _text_to_numbers(values, f"{self.label}: column {name}")  # type: ignore[arg-type]


_INDEXED = re.compile(r"^(.+?)([\[(])(?::,)?(\d+)[\])]$")


def detect_format(path: str | os.PathLike) -> tuple[str, str | None]:
    """(format, compression) from the file name; UserError for an unknown ending."""
    name = Path(path).name.lower()
    compression = next((c for c in COMPRESSIONS if name.endswith(c)), None)
    if compression:
        name = name[: -len(compression)]
    for fmt, (endings, _) in FORMATS.items():
        if name.endswith(endings):
            if compression and fmt not in ("csv", "json"):
                raise UserError(
                    f"recording {path}: a compressed {fmt} file ({compression}) is not read; "
                    f"{fmt} compresses inside the file"
                )
            return fmt, compression
    if compression:  # rec.gz, rec.zip: text inside
        return "csv", compression
    known = ", ".join(e for endings, _ in FORMATS.values() for e in endings)
    raise UserError(
        f"recording {path}: unknown file type; expected one of {known} (csv/tsv/json also as .gz, .bz2, .xz, .zip)"
    )


def read_columns(
    path: str | os.PathLike, what: str = "recording", records: str | None = None
) -> Columns:
    """Every column of a recording file (see the module docstring). ``records``: for JSON,
    the key (dotted for nested objects) holding the list of records."""
    path = Path(path)
    label = f"{what} {path}"
    fmt, compression = detect_format(path)
    raw = read_bounded(path, what)
    if compression:
        raw = _decompress(raw, compression, label)
    readers: dict[str, Callable[[bytes, str], tuple[dict, dict]]] = {
        "csv": _read_csv,
        "mat": _read_mat,
        "parquet": _read_parquet,
        "feather": _read_feather,
        "tdms": _read_tdms,
        "json": lambda data, where: _read_json(data, where, records),
    }
    try:
        columns, metadata = readers[fmt](raw, label)
    except UserError:
        raise
    except MemoryError:
        raise UserError(f"{label}: too large to read into memory") from None
    except Exception as exc:  # noqa: BLE001 - a third-party reader's complaint about a malformed file
        raise UserError(f"{label}: not a readable {fmt} file ({_one_line(exc)})") from None
    if not columns:
        raise UserError(f"{label}: no numeric columns found")
    return Columns(columns, metadata, label, fmt, compression)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text[:200]


def _needs(module: str, extension: str, extra: str, package: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise UserError(
            f"reading {extension} needs {package}: pip install 'mechanism[{extra}]'"
        ) from None


def require_pyarrow(extension: str = ".parquet"):
    """pyarrow, or the one-line error naming the extra that installs it."""
    return _needs("pyarrow", extension, "parquet", "pyarrow")


# -- compression ------------------------------------------------------------------------------


def _decompress(raw: bytes, compression: str, label: str) -> bytes:
    limit = max_input_bytes()
    too_big = UserError(
        f"{label}: decompresses to more than the input limit of {limit // 2**20} MiB "
        f"(raise it with MECHANISM_MAX_INPUT_MB)"
    )
    if compression == ".zip":
        try:
            archive = zipfile.ZipFile(io.BytesIO(raw))
            members = [m for m in archive.infolist() if not m.is_dir()]
        except (zipfile.BadZipFile, OSError, ValueError) as exc:
            raise UserError(f"{label}: not a readable zip archive ({_one_line(exc)})") from None
        if len(members) != 1:
            raise UserError(
                f"{label}: a zip archive must hold exactly one file, this one holds {len(members)}"
            )
        member = members[0]
        if member.file_size > limit:
            raise too_big
        try:
            stream: IO[bytes] = archive.open(member)
        except (
            zipfile.BadZipFile,
            OSError,
            ValueError,
            RuntimeError,
            NotImplementedError,
            zlib.error,
        ) as exc:
            raise UserError(f"{label}: not a readable zip archive ({_one_line(exc)})") from None
    else:
        source = io.BytesIO(raw)
        stream = (
            gzip.GzipFile(fileobj=source)
            if compression == ".gz"  # type: ignore[assignment]
            else bz2.BZ2File(source)
            if compression == ".bz2"
            else lzma.LZMAFile(source)
        )
    try:
        with stream:
            return read_stream_bounded(stream, limit, too_big)
    except UserError:
        raise
    except (
        OSError,
        EOFError,
        lzma.LZMAError,
        zipfile.BadZipFile,
        ValueError,
        RuntimeError,
        NotImplementedError,
        zlib.error,
    ) as exc:
        raise UserError(
            f"{label}: corrupt or truncated {compression} data ({_one_line(exc)})"
        ) from None


# -- text tables --------------------------------------------------------------------------------


def _text_to_numbers(values: Sequence[str], label: str) -> np.ndarray:
    out = np.empty(len(values))
    stamps = False
    first = None
    for i, cell in enumerate(values):
        if cell is None:
            raise UserError(f"{label}: missing from record {i + 1}")
        cell = str(cell).strip()
        try:
            out[i] = float(cell)
            if not stamps:
                continue
        except ValueError:
            pass
        try:
            stamp = datetime.fromisoformat(cell.replace("Z", "+00:00"))
        except ValueError:
            raise UserError(f"{label}, value {i + 1}: not a number ({cell[:20]!r})") from None
        if i and not stamps:
            raise UserError(f"{label}, value {i + 1}: a time stamp among numbers ({cell[:20]!r})")
        stamps = True
        if first is None:
            first = stamp
        try:
            out[i] = (
                stamp - first
            ).total_seconds()  # exact to the microsecond, unlike epoch seconds in a float
        except TypeError:
            raise UserError(
                f"{label}, value {i + 1}: time stamps with and without a time zone"
            ) from None
    if not np.all(np.isfinite(out)):
        i = int(np.flatnonzero(~np.isfinite(out))[0])
        raise UserError(f"{label}, value {i + 1}: NaN or inf is not allowed")
    return out


def _read_csv(raw: bytes, label: str):
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise UserError(f"{label}: not UTF-8 text") from None
    del raw
    lines = text.splitlines()
    metadata, start = header_comments(lines, label)
    first = lines[start]
    delimiter = "\t" if "\t" in first else ";" if ";" in first else "," if "," in first else None
    rows: Iterator[list[str]]
    if delimiter is None:  # columns separated by spaces (.dat, .txt)
        rows = (line.split() for line in lines[start:])
    else:
        rows = csv.reader(lines[start:], delimiter=delimiter)
    try:
        header = [name.strip() for name in next(rows)]
    except csv.Error as exc:
        raise UserError(f"{label}: cannot read the header line ({exc})") from None
    except StopIteration:
        raise UserError(f"{label}: empty (no header line)") from None
    headerless = all(_is_number(name, delimiter) for name in header)
    if headerless:  # numbers only: the columns are col1, col2, ...
        first_row = header
        rows = itertools.chain([first_row], rows)
        header = [f"col{j + 1}" for j in range(len(header))]
        metadata["columns"] = "none in the file: named col1, col2, ..."
    if len(set(header)) != len(header):
        raise UserError(f"{label}: duplicated column names in the header")
    check_elements(float(len(lines) - start) * len(header), label)
    body = lines[start if headerless else start + 1 :]
    numbers = _numeric_body(body, delimiter, len(header)) if delimiter is not None else None
    if numbers is not None:
        return dict(zip(header, numbers)), metadata
    # cells are converted to floats every CHUNK_ROWS rows (text kept only for columns that are text)
    columns = [_ColumnBuilder(delimiter in ("\t", ";")) for _ in header]
    block: list[list[str]] = [[] for _ in header]
    try:
        for row_number, row in enumerate(rows, start=start + (1 if headerless else 2)):
            if not row or all(not c.strip() for c in row) or row[0].lstrip().startswith("#"):
                continue
            if len(row) != len(header):
                raise UserError(
                    f"{label}: line {row_number} has {len(row)} fields, the header has {len(header)}"
                )
            for cells, cell in zip(block, row):
                cells.append(cell)
            if len(block[0]) >= CHUNK_ROWS:
                for builder, cells in zip(columns, block):
                    builder.add(cells)
                block = [[] for _ in header]
    except csv.Error as exc:
        raise UserError(f"{label}: malformed CSV ({exc})") from None
    del lines
    for builder, cells in zip(columns, block):
        builder.add(cells)
    return {name: builder.values() for name, builder in zip(header, columns)}, metadata


CHUNK_ROWS = 65536


def _numeric_body(body: list[str], delimiter: str, n_columns: int) -> list[np.ndarray] | None:
    """The columns of a body of numbers only (no quotes, no comment lines, every line with
    ``n_columns`` fields), read by numpy's compiled reader, or None: the general reader below
    then takes the file (decimal commas, text columns, quotes, comments and the error messages
    are its). The csv module's row objects cost ten times the numbers' conversion on a minute of
    1 kHz samples."""
    text = "\n".join(body)
    if "#" in text or '"' in text or not text.strip():
        return None
    try:
        table = np.loadtxt(
            io.StringIO(text),
            delimiter=delimiter,
            comments=None,
            quotechar=None,
            dtype=np.float64,
            ndmin=2,
        )
    except ValueError:
        return None
    if table.shape[1] != n_columns:
        return None
    return [np.ascontiguousarray(column) for column in table.T]


class _ColumnBuilder:
    """One CSV column: float chunks while every cell is a number (decimal commas too where
    the separator is not a comma), else its cells as text."""

    def __init__(self, decimal_comma: bool):
        self.decimal_comma = decimal_comma
        self.chunks: list[np.ndarray] = []
        self.text: list[str] | None = None

    def add(self, cells: list[str]) -> None:
        if self.text is not None:
            self.text.extend(cells)
            return
        try:
            self.chunks.append(np.array(cells, dtype=float))
            return
        except ValueError:
            pass
        if self.decimal_comma:
            try:
                self.chunks.append(np.array([c.replace(",", ".") for c in cells], dtype=float))
                return
            except ValueError:
                pass
        self.text = [repr_number(v) for chunk in self.chunks for v in chunk] + list(cells)
        self.chunks = []

    def values(self) -> object:
        if self.text is not None:
            return self.text
        return np.concatenate(self.chunks) if self.chunks else np.empty(0)


def repr_number(value: float) -> str:
    return repr(float(value))


def _is_number(text: str, delimiter: str | None) -> bool:
    try:
        float(text.replace(",", ".") if delimiter in ("\t", ";") else text)
    except ValueError:
        return False
    return True


# -- JSON ---------------------------------------------------------------------------------------


def _read_json(raw: bytes, label: str, records: str | None):
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise UserError(f"{label}: not UTF-8 text") from None
    del raw
    # every value is a Python object of about four float64s: bound them before parsing
    check_elements(4.0 * (text.count(",") + text.count("\n") + 1), label)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        if not exc.msg.startswith("Extra data"):
            raise UserError(f"{label}: not valid JSON ({_one_line(exc)})") from None
        try:  # JSON lines: one record per line
            data = [json.loads(line) for line in text.splitlines() if line.strip()]
        except json.JSONDecodeError as exc2:
            raise UserError(f"{label}: not valid JSON lines ({_one_line(exc2)})") from None
    except RecursionError:
        raise UserError(f"{label}: not valid JSON (nested too deeply)") from None
    del text
    metadata: dict[str, str] = {}
    if records:
        for key in records.split("."):
            if not isinstance(data, dict) or key not in data:
                found = (
                    ", ".join(map(str, list(data)[:12]))
                    if isinstance(data, dict)
                    else type(data).__name__
                )
                raise UserError(
                    f"{label}: no key {key!r} holding the records (records = {records!r}); found {found}"
                )
            data = data[key]
    elif isinstance(data, dict) and not all(isinstance(v, list) for v in data.values()):
        lists = [k for k, v in data.items() if isinstance(v, list) and v and isinstance(v[0], dict)]
        if len(lists) == 1:  # the one list of records in the object
            metadata["records"] = str(lists[0])
            data = data[lists[0]]
    if isinstance(data, dict) and data and all(isinstance(v, list) for v in data.values()):
        check_elements(float(sum(len(v) for v in data.values())), label)
        flat_columns = {str(k): v for k, v in data.items()}  # columns of values
    elif isinstance(data, list):
        if not data:
            raise UserError(f"{label}: no records")
        flat_columns = {}
        check_elements(
            float(len(data)) * max(1, len(data[0]) if isinstance(data[0], dict) else 1), label
        )
        for i, record in enumerate(data):
            if not isinstance(record, dict):
                raise UserError(
                    f"{label}: record {i + 1} is {type(record).__name__}, expected an object of named values"
                )
            for name, value in _flatten(record).items():
                column = flat_columns.setdefault(name, [None] * i)
                column.append(value)
            for column in flat_columns.values():
                if len(column) < i + 1:
                    column.append(None)
    else:
        hint = '; name the key holding them with records = "..."' if isinstance(data, dict) else ""
        raise UserError(f"{label}: expected a list of records{hint}")
    columns: dict[str, object] = {}
    for name, values in flat_columns.items():
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            columns[name] = np.asarray(values, dtype=float)
        elif all(
            v is None or (isinstance(v, (int, float, str)) and not isinstance(v, bool))
            for v in values
        ):
            # numbers as text, time stamps, gaps
            columns[name] = [v if v is None else str(v) for v in values]
    return columns, metadata


def _flatten(record: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in record.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


# -- MATLAB -------------------------------------------------------------------------------------


def _read_mat(raw: bytes, label: str):
    if (
        raw[:128].find(b"MATLAB 7.3") >= 0
        or raw[:8] == b"\x89HDF\r\n\x1a\n"
        or raw[512:520] == b"\x89HDF\r\n\x1a\n"
    ):
        return _read_mat73(raw, label)
    import scipy.io

    raw = _inflate_mat5(raw, label)
    try:
        found = scipy.io.whosmat(io.BytesIO(raw))
    except Exception as exc:  # noqa: BLE001
        raise UserError(f"{label}: not a readable MATLAB file ({_one_line(exc)})") from None
    check_elements(float(sum(math.prod(shape) for _, shape, _ in found)), label)
    data = scipy.io.loadmat(
        io.BytesIO(raw), squeeze_me=True, struct_as_record=False, mat_dtype=False
    )
    columns: dict[str, object] = {}
    metadata: dict[str, str] = {}
    for name, value in data.items():
        if isinstance(value, str):
            metadata[name.removeprefix("meta_")] = value
        elif not name.startswith("__"):
            _mat_value(columns, name, value, label)
    return columns, metadata


def _inflate_mat5(raw: bytes, label: str) -> bytes:
    """The MAT v5 file with every compressed variable inflated, bounded by the input limit
    (a compressed variable may claim any size; scipy would inflate it whole): the file
    scipy then reads holds every byte it can allocate from."""
    import struct

    if len(raw) < 128:
        raise UserError(f"{label}: not a MATLAB file (shorter than its 128-byte header)")
    order = {b"IM": "<", b"MI": ">"}.get(raw[126:128])
    if order is None:
        raise UserError(f"{label}: not a MATLAB v5 file (no byte-order mark in the header)")
    limit = max_input_bytes()
    parts, total, at = [raw[:128]], 128, 128
    while at + 8 <= len(raw):
        kind, size = struct.unpack(order + "II", raw[at : at + 8])
        end = at + 8 + size
        if end > len(raw):
            raise UserError(
                f"{label}: truncated (a variable claims {size} bytes, {len(raw) - at - 8} remain)"
            )
        if kind == 15:  # miCOMPRESSED: inflate at most what the limit leaves
            inflater = zlib.decompressobj()
            try:
                element = inflater.decompress(raw[at + 8 : end], limit - total + 1)
            except zlib.error as exc:
                raise UserError(
                    f"{label}: corrupt compressed variable ({_one_line(exc)})"
                ) from None
            if len(element) > limit - total:
                raise UserError(
                    f"{label}: a compressed variable inflates past the input limit of {limit // 2**20} MiB "
                    f"(raise it with MECHANISM_MAX_INPUT_MB)"
                )
            parts.append(element)
            total += len(element)
            at = end
        else:
            padded = end + (-size % 8)
            parts.append(raw[at : min(padded, len(raw))])
            total += min(padded, len(raw)) - at
            at = padded
    return b"".join(parts)


def _mat_value(columns: dict, name: str, value, label: str, depth: int = 0) -> None:
    from scipy.io.matlab import mat_struct

    if depth > 8:
        return
    if isinstance(value, mat_struct):
        for key in value._fieldnames:
            _mat_value(columns, f"{name}.{key}", getattr(value, key), label, depth + 1)
        return
    if isinstance(value, np.ndarray) and value.dtype == object:
        if value.ndim == 1 and value.size <= MAX_MATRIX_COLUMNS:
            for i, item in enumerate(value):
                _mat_value(columns, f"{name}({i + 1})", item, label, depth + 1)
        return
    _numeric_array(columns, name, value)


def _numeric_array(columns: dict, name: str, value) -> None:
    array = np.asarray(value)
    if array.dtype.kind not in "iufb" or array.size < 2:
        return
    array = array.astype(float)
    if array.ndim == 1:
        columns[name] = array
    elif array.ndim == 2:
        if array.shape[1] > array.shape[0]:
            array = array.T
        if array.shape[1] == 1:
            columns[name] = array[:, 0]
        elif array.shape[1] <= MAX_MATRIX_COLUMNS:
            for j in range(array.shape[1]):
                columns[f"{name}(:,{j + 1})"] = array[:, j].copy()


def _read_mat73(raw: bytes, label: str):
    h5py = _needs("h5py", ".mat v7.3", "mat73", "h5py")
    columns: dict[str, object] = {}
    with h5py.File(io.BytesIO(raw), "r") as handle:
        datasets = []

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and not name.startswith("#"):
                datasets.append((name, obj))

        handle.visititems(visit)
        check_elements(float(sum(math.prod(d.shape) for _, d in datasets)), label)
        for name, dataset in datasets:
            kind = dataset.attrs.get("MATLAB_class", b"double")
            kind = kind.decode() if isinstance(kind, bytes) else str(kind)
            if kind in ("char", "cell", "struct", "logical") or dataset.dtype.kind not in "iuf":
                continue
            _numeric_array(columns, name.replace("/", "."), np.asarray(dataset[()]))
    return columns, {}


# -- Arrow --------------------------------------------------------------------------------------


def _arrow_columns(table, label: str) -> dict:
    columns: dict[str, object] = {}
    for name in table.column_names:
        column = table.column(name)
        kind = str(column.type)
        if kind.startswith(("int", "uint", "float", "double", "halffloat", "bool")):
            if column.null_count:
                continue
            columns[name] = np.asarray(column.to_numpy(), dtype=float)
        elif kind.startswith("timestamp"):
            columns[name] = column.cast("int64").to_numpy().astype(float) * _timestamp_seconds(kind)
        elif kind in ("string", "large_string"):
            columns[name] = [str(v) for v in column.to_pylist()]
    return columns


def _timestamp_seconds(kind: str) -> float:
    unit = kind[len("timestamp[") :].split(",")[0].rstrip("]")
    return {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}.get(unit, 1e-9)


def _read_parquet(raw: bytes, label: str):
    _needs("pyarrow", ".parquet", "parquet", "pyarrow")
    import pyarrow as pa
    import pyarrow.parquet as pq

    handle = pq.ParquetFile(pa.BufferReader(raw))
    meta = handle.metadata
    check_elements(float(meta.num_rows) * meta.num_columns, label)
    total = sum(meta.row_group(i).total_byte_size for i in range(meta.num_row_groups))
    if total > max_input_bytes():
        raise UserError(
            f"{label}: declares {total / 2**20:.3g} MiB of data, more than the input limit of "
            f"{max_input_bytes() // 2**20} MiB (raise it with MECHANISM_MAX_INPUT_MB)"
        )
    table = handle.read()
    metadata = {
        k.decode(errors="replace"): v.decode(errors="replace")
        for k, v in (table.schema.metadata or {}).items()
        if not k.startswith(b"ARROW:") and k != b"pandas"
    }
    return _arrow_columns(table, label), metadata


def _read_feather(raw: bytes, label: str):
    _needs("pyarrow", ".feather", "parquet", "pyarrow")
    import pyarrow as pa
    import pyarrow.ipc as ipc

    reader = ipc.open_file(pa.BufferReader(raw))
    batches, total = [], 0
    for i in range(reader.num_record_batches):
        batch = reader.get_batch(i)
        total += batch.num_rows * batch.num_columns
        check_elements(float(total), label)
        batches.append(batch)
    return _arrow_columns(pa.Table.from_batches(batches, schema=reader.schema), label), {}


# -- LabVIEW TDMS -------------------------------------------------------------------------------


def _read_tdms(raw: bytes, label: str):
    nptdms = _needs("nptdms", ".tdms", "tdms", "npTDMS")
    from nptdms.log import log_manager

    level = log_manager.log_level
    # its warnings about a damaged file would be third-party text on stderr
    log_manager.set_level(logging.ERROR)
    try:
        return _read_tdms_quietly(nptdms, raw, label)
    finally:
        log_manager.set_level(level)


def _check_tdms_segments(raw: bytes, label: str) -> None:
    """Each segment's lead-in states its length: a file that ends inside one is truncated
    (npTDMS would read what is there and only log a warning)."""
    import struct

    at = 0
    while at < len(raw):
        lead = raw[at : at + 28]
        if len(lead) < 28 or lead[:4] not in (b"TDSm", b"TDSh"):
            raise UserError(
                f"{label}: not a TDMS file, or truncated (no segment lead-in at byte {at})"
            )
        order = ">" if struct.unpack("<I", lead[4:8])[0] & (1 << 6) else "<"  # kTocBigEndian
        length = struct.unpack(order + "Q", lead[12:20])[0]
        if at + 28 + length > len(raw):
            raise UserError(
                f"{label}: truncated (a segment at byte {at} states {length} bytes, {len(raw) - at - 28} remain)"
            )
        at += 28 + length


def _read_tdms_quietly(nptdms, raw: bytes, label: str):
    _check_tdms_segments(raw, label)
    meta = nptdms.TdmsFile.read_metadata(io.BytesIO(raw))
    channels = [c for g in meta.groups() for c in g.channels()]
    check_elements(float(sum(len(c) for c in channels)), label)
    declared = {(g.name, c.name): len(c) for g in meta.groups() for c in g.channels()}
    data = nptdms.TdmsFile.read(io.BytesIO(raw))
    columns: dict[str, object] = {}
    names = [c.name for g in data.groups() for c in g.channels()]
    for group in data.groups():
        for channel in group.channels():
            values = channel[:]
            if len(values) < declared.get((group.name, channel.name), 0):
                raise UserError(
                    f"{label}: truncated (channel {group.name}/{channel.name} holds {len(values)} of its "
                    f"{declared[(group.name, channel.name)]} values)"
                )
            if len(values) < 2:
                continue
            if np.asarray(values).dtype.kind == "M":  # LabVIEW time stamps
                array = np.asarray(values).astype("datetime64[ns]").astype(np.int64) * 1e-9
            elif np.asarray(values).dtype.kind in "iufb":
                array = np.asarray(values, dtype=float)
            else:
                continue
            columns[f"{group.name}/{channel.name}"] = array
            if names.count(channel.name) == 1 and channel.name not in columns:
                columns[channel.name] = array  # a unique channel name alone is enough
            if "wf_increment" in channel.properties:
                columns[f"{group.name}/{channel.name}.time"] = channel.time_track()
    return columns, {}


# -- writing (the test bench) -------------------------------------------------------------------


def write_columns(
    path: str | os.PathLike,
    columns: Mapping[str, np.ndarray],
    comments: Sequence[str] = (),
    fmt: WriteFormat = "csv",
    metadata: Mapping[str, str] | None = None,
) -> Path:
    """Write named columns (units in the names) as ``fmt`` (one of :data:`WRITE_FORMATS`),
    atomically. CSV carries ``comments`` as ``#`` lines; Parquet and MAT carry ``metadata``
    (``key: value``) in the file's own metadata / a ``metadata`` text variable."""
    from mechanism.files.outputs import atomic_file, atomic_path
    from mechanism.files.tables import write_table

    path = Path(path)
    metadata = dict(metadata or {})
    if fmt == "csv":
        return write_table(path, columns, comments=comments, fmt="%.10g")
    if fmt == "csv.gz":
        text = io.StringIO()
        for line in comments:
            text.write(f"# {line}\n")
        writer = csv.writer(text, lineterminator="\n")
        writer.writerow(list(columns))
        for row in np.column_stack([np.asarray(v, dtype=float) for v in columns.values()]):
            writer.writerow(["%.10g" % v for v in row])
        with atomic_file(path, "wb") as handle:
            handle.write(gzip.compress(text.getvalue().encode(), mtime=0))
        return path
    if fmt == "parquet":
        pa = _needs("pyarrow", ".parquet", "parquet", "pyarrow")
        import pyarrow.parquet as pq

        table = pa.table({k: np.asarray(v, dtype=float) for k, v in columns.items()})
        table = table.replace_schema_metadata(
            {k.encode(): str(v).encode() for k, v in metadata.items()}
        )
        with atomic_path(path) as temporary:
            pq.write_table(table, temporary)
        return path
    if fmt == "mat":
        import scipy.io

        data: dict[str, object] = {
            k: np.asarray(v, dtype=float).reshape(-1, 1) for k, v in columns.items()
        }
        data.update({f"meta_{k}": str(v) for k, v in metadata.items()})
        with atomic_file(path, "wb") as handle:
            scipy.io.savemat(handle, data, do_compression=True)
        return path
    raise UserError(f"unknown recording format {fmt!r}; one of {', '.join(WRITE_FORMATS)}")
