"""Matplotlib set up for headless use; figures are saved atomically."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from mechanism.files.outputs import atomic_path  # noqa: E402


def save_figure(fig, path: str | os.PathLike, dpi: int = 120) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(
            tmp,
            dpi=dpi,
            bbox_inches="tight",
            format=os.path.splitext(str(path))[1].lstrip(".") or "png",
        )
    plt.close(fig)
