"""Matplotlib set up for headless use; figures are saved atomically."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from mechanism.files.outputs import atomic_path  # noqa: E402


def save_figure(fig, path: str | os.PathLike, dpi: int = 120) -> None:
    """Save ``fig`` atomically and close it. Labels are fitted inside the figure by its layout
    engine (constrained, unless the figure has laid itself out): one drawing, where a "tight"
    bounding box draws the whole figure twice (a diagnosis report's three figures took 2-3 s)."""
    if fig.get_layout_engine() is None:
        fig.set_layout_engine("constrained")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=os.path.splitext(str(path))[1].lstrip(".") or "png")
    plt.close(fig)
