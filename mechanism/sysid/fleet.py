"""Fleet diagnosis: many bench recordings (one per machine of a production line) diagnosed
in one batch, and the spread of what was fitted across the fleet.

:func:`diagnose_fleet` runs :func:`mechanism.sysid.diagnosis.diagnose` on every recording
(``mechanism.batch``: local processes or a Ray cluster) and writes, into one folder:

- ``<recording>.json`` per recording: the JSON ``mechanism diagnose --json`` writes for it
  alone (a recording that is not identifiable gets the same "not identifiable" JSON);
- ``summary.csv``: one row per recording: status, effects found, baseline and final rmse,
  every fitted parameter (names with units), the wall time, and the error line of a
  recording that could not be diagnosed (a bad recording never stops the batch);
- ``summary.html``: that table, the distribution of each fitted parameter across the
  fleet (a strip plot per parameter) and its outliers: robust z-score
  ``0.6745 (x - median) / MAD`` above :data:`OUTLIER_Z` (Iglewicz and Hoaglin), among at
  least :data:`OUTLIER_MIN_RECORDINGS` recordings.
"""

from __future__ import annotations

import csv
import html
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from mechanism.batch.runner import Backend
from mechanism.errors import UserError
from mechanism.files.limits import usable_cores

OUTLIER_Z = 3.5
OUTLIER_MIN_RECORDINGS = 5  # fewer: the MAD of a handful of values says nothing
SUMMARY_CSV = "summary.csv"
SUMMARY_HTML = "summary.html"


@dataclass
class FleetResult:
    out_dir: Path
    rows: list[dict]  # one per recording, in input order (summary.csv)
    outliers: list[dict] = field(default_factory=list)  # {recording, parameter, value, robust_z}
    seconds: float = 0.0

    @property
    def diagnosed(self) -> int:
        return sum(1 for row in self.rows if row["status"] == "ok")


def recording_paths(arguments: Sequence[str | os.PathLike]) -> list[Path]:
    """Files as given, and every recording of a folder (sorted by name): each file a reader
    takes by its name (``*.csv``, ``*.csv.gz``, ``*.mat``, ``*.parquet``, ...) except JSON,
    which a folder also holds as outputs and truth files (name JSON recordings one by one)."""
    from mechanism.files.formats import detect_format

    def is_recording(p: Path) -> bool:
        try:
            return p.is_file() and detect_format(p)[0] != "json"
        except UserError:
            return False

    paths: list[Path] = []
    for argument in arguments:
        path = Path(argument)
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if is_recording(p))
            if not found:
                raise UserError(
                    f"folder {path}: no recordings in it (*.csv, *.csv.gz, *.mat, *.parquet, *.tdms, ...)"
                )
            paths.extend(found)
        elif path.is_file():
            paths.append(path)
        else:
            raise UserError(f"recording {path}: no such file or folder")
    return paths


def _unique_names(paths: Sequence[Path]) -> list[str]:
    """The file stems, with ``_2``, ``_3``, ... for stems that repeat (files of several folders)."""
    from mechanism.files.formats import COMPRESSIONS

    names: list[str] = []
    seen: dict[str, int] = {}  # stem -> how often it came so far
    for path in paths:
        stem = Path(
            path.name[: -len(path.suffix)] if path.suffix.lower() in COMPRESSIONS else path.name
        ).stem  # rec.csv.gz: rec
        seen[stem] = seen.get(stem, 0) + 1
        names.append(stem if seen[stem] == 1 else f"{stem}_{seen[stem]}")
    return names


# -- one recording (runs in a worker) ----------------------------------------------------------


def _diagnose_one(options: dict, path: str) -> dict:
    """Diagnose one recording; a recording that cannot be diagnosed gives its error line."""
    from mechanism.sysid.diagnosis import diagnose, not_identifiable_json
    from mechanism.sysid.identification import NotIdentifiable
    from mechanism.sysid.recording import read_recording

    start = time.perf_counter()
    outcome: dict = {"json": None, "error": None}
    options = dict(options)
    recording_map = options.pop("recording_map", None)
    try:
        rec = read_recording(path, recording_map)
        try:
            outcome["json"] = diagnose(rec, **options).to_json()
        except NotIdentifiable as exc:
            outcome["json"] = not_identifiable_json(rec.source, str(exc), rec.reading)
            outcome["error"] = f"not identifiable: {exc}"
    except UserError as exc:
        outcome["error"] = str(exc)
    except Exception as exc:  # noqa: BLE001 - one recording's failure must not stop the fleet
        outcome["error"] = f"{type(exc).__name__}: {exc}"
    outcome["time_s"] = time.perf_counter() - start
    return outcome


def _summary_row(name: str, outcome: dict) -> dict:
    data = outcome["json"]
    row = {
        "recording": name,
        "status": "error" if outcome["error"] else "ok",
        "effects": "",
        "baseline_rmse_rad_s": math.nan,
        "final_rmse_rad_s": math.nan,
    }
    if data and data.get("identifiable"):
        row.update(
            effects="+".join(data["final"]["effects"]),
            baseline_rmse_rad_s=data["baseline"]["rmse"],
            final_rmse_rad_s=data["final"]["rmse"],
        )
        row.update(data["final"]["params"])  # parameter names carry their units
    row["time_s"] = outcome["time_s"]
    row["error"] = outcome["error"] or ""
    return row


# -- the fleet --------------------------------------------------------------------------------


def diagnose_fleet(
    paths: Sequence[str | os.PathLike],
    out_dir: str | os.PathLike,
    workers: int = 1,
    backend: Backend = "local",
    ray_address: str | None = None,
    progress: bool = True,
    on_recording: Callable[[str, dict], None] | None = None,
    **diagnose_options,
) -> FleetResult:
    """Diagnose every recording (files, or folders of ``*.csv``) into ``out_dir``; see the
    module docstring. ``diagnose_options`` go to ``diagnose`` (``baseline``, ``candidates``,
    ``model_path``; ``recording_map``: a RecordingMap for every file). Each recording's JSON is written (into the folder being built) when it is done;
    ``on_recording(name, summary_row)`` sees each one then."""
    from mechanism.batch import BatchLost, check_options, run_batch
    from mechanism.files.outputs import atomic_dir

    check_options(backend, workers)
    files = recording_paths(paths)
    names = _unique_names(files)
    options = {"workers": _fit_workers(backend, workers), **diagnose_options}
    # one output transaction: the folder (earlier files kept) appears complete or not at all
    with atomic_dir(out_dir, keep=True) as folder:

        def done(index: int, outcome: dict) -> None:
            if outcome["json"] is not None:
                _write_json(folder / f"{names[index]}.json", outcome["json"])
            if on_recording is not None:
                on_recording(names[index], _summary_row(names[index], outcome))

        start = time.perf_counter()
        try:
            outcomes = run_batch(
                _diagnose_one,
                [str(p) for p in files],
                shared=options,
                workers=workers,
                backend=backend,
                ray_address=ray_address,
                on_result=done,
                progress=progress,
                desc="recordings",
                unit="recording",
            )
        except BatchLost as exc:  # per recording: which were not diagnosed (nothing is published)
            lost = ", ".join(names[i] for i in exc.unfinished)
            raise UserError(
                f"{exc}; recordings not diagnosed: {lost}; nothing was written, run the fleet again"
            ) from None
        rows = [_summary_row(name, outcome) for name, outcome in zip(names, outcomes)]
        result = FleetResult(Path(out_dir), rows, find_outliers(rows), time.perf_counter() - start)
        write_summary_csv(folder / SUMMARY_CSV, rows)
        write_summary_html(folder / SUMMARY_HTML, result)
    return result


def _fit_workers(backend: Backend, workers: int) -> int | None:
    """Fit workers inside one diagnosis: alone, its default (as a single run); beside other
    local workers, a share of the cores; on Ray, the one CPU its task holds."""
    if backend != "local":
        return 1
    return None if workers == 1 else max(1, usable_cores() // workers)


def _write_json(path: Path, data: dict) -> None:
    from mechanism.files.outputs import atomic_file

    with atomic_file(path) as handle:
        json.dump(data, handle, indent=2)


def parameter_columns(rows: Sequence[dict]) -> list[str]:
    """The fitted parameters of the fleet, in order of first appearance."""
    fixed = {
        "recording",
        "status",
        "effects",
        "baseline_rmse_rad_s",
        "final_rmse_rad_s",
        "time_s",
        "error",
    }
    return list(dict.fromkeys(key for row in rows for key in row if key not in fixed))


def write_summary_csv(path: Path, rows: Sequence[dict]) -> None:
    from mechanism.files.outputs import atomic_file

    header = [
        "recording",
        "status",
        "effects",
        "baseline_rmse_rad_s",
        "final_rmse_rad_s",
        *parameter_columns(rows),
        "time_s",
        "error",
    ]
    with atomic_file(path) as handle:
        handle.write(
            "# one row per recording; rmse: RMS arm-velocity residual on the held-out half [rad/s]; "
            "parameters: the final fit (blank where a recording's model has no such parameter)\n"
        )
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(header)
        for row in rows:
            writer.writerow([_cell(row.get(name, "")) for name in header])


def _cell(value) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.9g}"
    return str(value)


# -- outliers and the report ------------------------------------------------------------------


def robust_z(values: np.ndarray) -> np.ndarray:
    """0.6745 (x - median) / MAD; zero where MAD is zero and x is the median, inf elsewhere."""
    values = np.asarray(values, dtype=float)
    deviation = values - np.median(values)
    mad = np.median(np.abs(deviation))
    if mad == 0:
        return np.where(deviation == 0, 0.0, np.copysign(np.inf, deviation))
    return 0.6745 * deviation / mad


def _parameter_values(rows: Sequence[dict], name: str) -> tuple[list[str], np.ndarray]:
    found = [
        (row["recording"], row[name])
        for row in rows
        if row["status"] == "ok" and isinstance(row.get(name), float)
    ]
    return [r for r, _ in found], np.array([v for _, v in found], dtype=float)


def find_outliers(rows: Sequence[dict]) -> list[dict]:
    """Recordings whose fitted parameter lies more than OUTLIER_Z robust z-scores from the
    fleet's median (parameters fitted on at least OUTLIER_MIN_RECORDINGS recordings)."""
    outliers = []
    for name in parameter_columns(rows):
        recordings, values = _parameter_values(rows, name)
        if len(values) < OUTLIER_MIN_RECORDINGS:
            continue
        for recording, value, z in zip(recordings, values, robust_z(values)):
            if abs(z) > OUTLIER_Z:
                outliers.append(
                    {
                        "recording": recording,
                        "parameter": name,
                        "value": float(value),
                        "robust_z": float(z),
                    }
                )
    return outliers


def _strip_plot(name: str, recordings: list[str], values: np.ndarray) -> str:
    """A strip plot of one parameter across the fleet as an inline PNG (base64)."""
    import base64
    import io

    from mechanism.files.plotting import plt

    z = robust_z(values) if len(values) >= OUTLIER_MIN_RECORDINGS else np.zeros(len(values))
    outlying = np.abs(z) > OUTLIER_Z
    jitter = np.random.default_rng(0).uniform(-0.25, 0.25, len(values))
    fig, ax = plt.subplots(figsize=(7, 1.6))
    ax.scatter(
        values[~outlying], jitter[~outlying], s=14, color="#3465a4", alpha=0.7, label="recording"
    )
    ax.scatter(
        values[outlying],
        jitter[outlying],
        s=30,
        color="#cc0000",
        marker="x",
        label=f"outlier (|robust z| > {OUTLIER_Z:g})",
    )
    for value, y, recording in zip(
        values[outlying], jitter[outlying], np.array(recordings)[outlying]
    ):
        ax.annotate(recording, (value, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.axvline(np.median(values), color="#888", lw=1, label="median")
    ax.set_yticks([])
    ax.set_ylim(-0.6, 0.6)
    ax.set_xlabel(name)
    ax.legend(fontsize=7, loc="upper right", ncol=3, frameon=False, bbox_to_anchor=(1, 1.45))
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def write_summary_html(path: Path, result: FleetResult) -> None:
    from mechanism.files.outputs import atomic_file
    from mechanism.sysid.report import _STYLE

    rows = result.rows
    body = [
        f"<h1>Fleet diagnosis: {result.diagnosed} of {len(rows)} recordings diagnosed</h1>",
        "<table><tr><th>recording</th><th>status</th><th>effects</th><th>baseline rmse [rad/s]</th>"
        "<th>final rmse [rad/s]</th><th>time [s]</th><th>error</th></tr>",
    ]
    for row in rows:
        cells = [
            row["recording"],
            row["status"],
            row["effects"] or "-",
            _cell(row["baseline_rmse_rad_s"]),
            _cell(row["final_rmse_rad_s"]),
            f"{row['time_s']:.1f}",
            row["error"],
        ]
        body.append("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in cells) + "</tr>")
    body.append("</table>")
    body.append(
        f"<h2>Outliers</h2><p>A recording is an outlier for a parameter when its robust z-score "
        f"0.6745&nbsp;(x&nbsp;&minus;&nbsp;median)&nbsp;/&nbsp;MAD exceeds {OUTLIER_Z:g} in magnitude "
        f"(MAD: median absolute deviation over the recordings that fitted the parameter; "
        f"at least {OUTLIER_MIN_RECORDINGS} needed).</p>"
    )
    if result.outliers:
        body.append(
            "<table><tr><th>recording</th><th>parameter</th><th>value</th><th>robust z</th></tr>"
            + "".join(
                f"<tr><td>{html.escape(o['recording'])}</td><td><code>{html.escape(o['parameter'])}</code></td>"
                f"<td>{o['value']:.5g}</td><td>{o['robust_z']:.1f}</td></tr>"
                for o in result.outliers
            )
            + "</table>"
        )
    else:
        body.append("<p>None.</p>")
    body.append("<h2>Fitted parameters across the fleet</h2>")
    for name in parameter_columns(rows):
        recordings, values = _parameter_values(rows, name)
        if len(values):
            body.append(
                f"<h3><code>{html.escape(name)}</code> ({len(values)} recordings, median {np.median(values):.5g})</h3>"
                f"<img alt='{html.escape(name)}' src='data:image/png;base64,{_strip_plot(name, recordings, values)}'>"
            )
    with atomic_file(path) as handle:
        handle.write(
            f"<!doctype html><html><head><meta charset='utf-8'><title>Fleet diagnosis</title><style>{_STYLE}</style>"
            f"</head><body>{''.join(body)}</body></html>"
        )
