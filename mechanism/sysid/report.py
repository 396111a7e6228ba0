"""HTML reports for ``identify`` and ``diagnose``: plots and sentences, read from results.

Nothing here fits or simulates: the :class:`Traces` (measured and predicted velocity over
the whole recording) are produced by identification/diagnosis, and this module only
bins, plots and writes them.
"""

from __future__ import annotations

import html
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mechanism.files.outputs import atomic_dir


@dataclass
class Traces:
    """Velocity over the whole recording: measured, and each model's prediction."""

    time_s: np.ndarray
    arm_angle_rad: np.ndarray
    voltage_V: np.ndarray
    measured_rad_s: np.ndarray
    predicted_rad_s: dict  # label -> prediction
    ratio: float = 8.0  # motor turns per shaft turn (the machine's: the callers pass it)
    zero_meaning: str = "the described zero"


def _profile(x, y, bins, lo, hi):
    ok = np.isfinite(y)
    x, y = x[ok], y[ok]
    edges = np.linspace(lo, hi, bins + 1)
    idx = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    count = np.bincount(idx, minlength=bins)
    mean = np.bincount(idx, weights=y, minlength=bins) / np.maximum(count, 1)
    rms = np.sqrt(np.bincount(idx, weights=y * y, minlength=bins) / np.maximum(count, 1))
    centres = 0.5 * (edges[1:] + edges[:-1])
    keep = count > 20
    return centres[keep], mean[keep], rms[keep]


def _plots(traces: Traces, folder: Path) -> list[tuple[str, str]]:
    from scipy.signal import welch

    from mechanism.files.plotting import plt, save_figure

    t, w = traces.time_s, traces.measured_rad_s
    labels = list(traces.predicted_rad_s)
    residuals = {k: w - traces.predicted_rad_s[k] for k in labels}
    speed = np.abs(w)
    top = max(np.percentile(speed, 99), 1e-6)
    moving = speed > 0.1 * top
    out = []

    fig, axes = plt.subplots(2, 1, figsize=(11, 6.5))
    axes[0].plot(t, w, lw=0.6, color="k", label="recording")
    for k in labels:
        axes[0].plot(t, traces.predicted_rad_s[k], lw=0.6, label=k)
    axes[0].set_ylabel("arm velocity [rad/s]")
    axes[0].legend(loc="upper right")
    axes[0].set_title("recording vs models (each 1 s segment restarts from the measured velocity)")
    # a 2 s window at the fastest plateau shows the ripple
    i0 = int(np.argmax(np.convolve(speed, np.ones(2000) / 2000, mode="same")))
    sl = slice(max(0, i0 - 1000), min(len(t), i0 + 1000))
    axes[1].plot(t[sl], w[sl], lw=0.8, color="k", label="recording")
    for k in labels:
        axes[1].plot(t[sl], traces.predicted_rad_s[k][sl], lw=0.8, label=k)
    axes[1].set_xlabel("time [s]")
    axes[1].set_ylabel("arm velocity [rad/s]")
    axes[1].set_title("2 s at the highest speed")
    save_figure(fig, folder / "velocity.png")
    out.append(("velocity.png", "Recording against the models"))

    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5))
    for k in labels:
        r = residuals[k]
        axes[0, 0].plot(t, r, lw=0.4, label=k)
        c, m, _ = _profile(
            np.mod(traces.arm_angle_rad[moving], 2 * np.pi), r[moving], 72, 0, 2 * np.pi
        )
        axes[0, 1].plot(np.degrees(c), m, label=k)
        c, m, _ = _profile(
            np.mod(traces.ratio * traces.arm_angle_rad[moving], 2 * np.pi),
            r[moving],
            72,
            0,
            2 * np.pi,
        )
        axes[1, 0].plot(np.degrees(c), m, label=k)
        c, _, rms = _profile(speed, r, 20, 0, top * 1.001)
        axes[1, 1].plot(c, rms, marker=".", label=k)
    axes[0, 0].set(
        xlabel="time [s]", ylabel="velocity residual [rad/s]", title="residual over time"
    )
    axes[0, 1].set(
        xlabel=f"shaft angle [deg] (0 = {traces.zero_meaning})",
        ylabel="mean residual [rad/s]",
        title="phase-averaged over the shaft angle",
    )
    axes[1, 0].set(
        xlabel=f"motor angle [deg] ({traces.ratio:g} per shaft revolution)",
        ylabel="mean residual [rad/s]",
        title="phase-averaged over the motor angle",
    )
    axes[1, 1].set(
        xlabel="arm speed [rad/s]", ylabel="RMS residual [rad/s]", title="residual against speed"
    )
    for ax in axes.flat:
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, folder / "residuals.png")
    out.append(("residuals.png", "Where the residual lives, before and after"))

    fig, ax = plt.subplots(figsize=(11, 3.5))
    dt = float(t[1] - t[0])
    spectra = {
        k: welch(np.nan_to_num(residuals[k]), fs=1 / dt, nperseg=min(4096, len(t))) for k in labels
    }
    # an exact fit leaves no power: a log axis would have nothing to show (and matplotlib says so)
    logarithmic = any(np.any(p > 0) for _, p in spectra.values())
    for k, (f, p) in spectra.items():
        if logarithmic:
            ax.semilogy(f, np.where(p > 0, p, np.nan), lw=0.8, label=k)
        else:
            ax.plot(f, p, lw=0.8, label=k)
    ax.set(
        xlabel="frequency [Hz]",
        ylabel="PSD [(rad/s)^2/Hz]",
        title="residual spectrum (resonances, shaft-rate harmonics)",
    )
    ax.legend()
    save_figure(fig, folder / "spectrum.png")
    out.append(("spectrum.png", "Residual spectrum"))
    return out


_STYLE = (
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}td,th{padding:2px 10px;text-align:left}"
    "table{border-collapse:collapse}tr:nth-child(even){background:#f3f3f3}img{max-width:100%}code{background:#eee}"
)


def _param_table(params: dict, unc: dict | None = None) -> str:
    rows = []
    for k, v in params.items():
        u = (unc or {}).get(k)
        us = "" if u is None or not np.isfinite(u) else f"&plusmn; {u:.2g}"
        rows.append(f"<tr><td><code>{html.escape(k)}</code></td><td>{v:.5g} {us}</td></tr>")
    return "<table>" + "".join(rows) + "</table>"


def write_report(
    folder: str | os.PathLike,
    title: str,
    summary_json: dict,
    traces: Traces,
    sections: list[tuple[str, str]],
) -> Path:
    """Write ``folder/index.html`` with plots, ``sections`` (heading, HTML) and the JSON."""
    folder = Path(folder)
    with atomic_dir(folder) as tmp:
        plots = _plots(traces, tmp)
        body = [f"<h1>{html.escape(title)}</h1>"]
        for heading, content in sections:
            body.append(f"<h2>{html.escape(heading)}</h2>{content}")
        for name, caption in plots:
            body.append(
                f"<h2>{html.escape(caption)}</h2><img src='{name}' alt='{html.escape(caption)}'>"
            )
        body.append(
            f"<h2>Result (JSON)</h2><pre>{html.escape(json.dumps(summary_json, indent=2, default=float))}</pre>"
        )
        (tmp / "index.html").write_text(
            f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body>{''.join(body)}</body></html>",
            encoding="utf-8",
        )
        (tmp / "result.json").write_text(
            json.dumps(summary_json, indent=2, default=float), encoding="utf-8"
        )
    return folder / "index.html"


def diagnosis_report(diagnosis, folder) -> Path:
    """The ``diagnose --report`` page: findings with their evidence, then the plots."""
    data = diagnosis.to_json()
    findings = diagnosis.findings
    if findings:
        items = "".join(
            f"<li><b>{html.escape(f.effect.name)}</b>{' (generic)' if f.effect.generic else ''}: "
            f"{html.escape(f.evidence)}</li>"
            for f in findings
        )
        verdict = f"<ol>{items}</ol>"
    else:
        verdict = (
            "<p>Nothing is missing: no candidate effect lowered the validation error of the baseline "
            "by the required margin.</p>"
        )
    base, final = diagnosis.baseline, diagnosis.final
    rmse = (
        f"<p>Validation rmse: baseline {base.rmse_val:.4g} rad/s, final {final.rmse_val:.4g} rad/s "
        f"(ratio {final.rmse_val / base.rmse_val:.2f}).</p>"
    )
    rounds = ""
    for i, r in enumerate(diagnosis.rounds, 1):
        cells = "".join(
            f"<tr><td>{html.escape(k)}</td><td>{v:.4g}</td></tr>"
            for k, v in sorted(r.items(), key=lambda kv: kv[1])
        )
        rounds += f"<h3>round {i}</h3><table><tr><th>candidate</th><th>validation rmse [rad/s]</th></tr>{cells}</table>"
    left = diagnosis.unexplained
    if left is not None:
        rmse += (
            f"<h3>What is left unexplained</h3><p>The final residual, {left.rmse:.3g} rad/s, is "
            f"{left.rmse / left.floor.rmse:.1f} times the recording's own noise floor ({left.floor.rmse:.2g} rad/s: "
            f"encoder quantisation and sensor scatter). It shows {html.escape(left.sentence)}.</p>"
        )
    sections = [
        ("What is missing", verdict + rmse),
        ("Baseline parameters", _param_table(base.values, base.uncertainties)),
        ("Final parameters", _param_table(final.values, final.uncertainties)),
        ("Candidates tried", rounds),
    ]
    return write_report(
        folder,
        f"Diagnosis of {Path(diagnosis.recording.source).name}",
        data,
        diagnosis.traces,
        sections,
    )


def identification_report(result, folder) -> Path:
    data = result.to_json()
    sections = [
        (
            "Fitted parameters",
            _param_table(result.fit.values, result.fit.uncertainties)
            + f"<p>Validation rmse {result.fit.rmse_val:.4g} rad/s (fit part {result.fit.rmse_fit:.4g}).</p>",
        )
    ]
    return write_report(
        folder,
        f"Identification of {Path(result.recording.source).name}",
        data,
        result.traces,
        sections,
    )
