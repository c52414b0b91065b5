"""Saving a figure like every other output: atomically (:mod:`quadest.data.files`)."""

from __future__ import annotations

from pathlib import Path

from quadest.data.files import atomic_output
from quadest.extras import need

FORMATS = ("png", "pdf", "svg", "jpg", "jpeg")


def pyplot():
    """matplotlib's pyplot on the Agg backend (files, no screen); one line naming the [plot]
    extra where matplotlib is not installed."""
    need("matplotlib", "drawing plots").use("Agg")
    return need("matplotlib.pyplot", "drawing plots")


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (format from the extension: png, pdf, svg, jpg) and close it."""
    plt = pyplot()
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in FORMATS:
        plt.close(fig)
        raise ValueError(f"{path}: a figure is written as {', '.join('.' + f for f in FORMATS)}")
    try:
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format=fmt)
    finally:
        plt.close(fig)
    return path
