"""Attitude error over time per axis for several estimators (like the AFCKF paper's Figs 2-7)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from quadest.evaluation.metrics import AXES, euler_errors
from quadest.plot.save import pyplot, save_figure


def plot_errors(
    t: ArrayLike, q_true: ArrayLike, results: dict, out_dir: str | Path, *, title: str = "", t_from: float | None = None
) -> list[Path]:
    """One PNG per axis in ``out_dir`` (``error_roll.png`` ...), every estimator as a line.
    Returns the paths."""
    plt = pyplot()

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    errs = {name: np.degrees(euler_errors(res.q, q_true)) for name, res in results.items()}
    paths = []
    for i, axis in enumerate(AXES):
        fig, ax = plt.subplots(figsize=(10, 3.6), constrained_layout=True)
        for name, e in errs.items():
            ax.plot(t, e[:, i], lw=0.7, label=name)
        if t_from is not None:
            ax.axvline(t[0] + t_from, color="k", ls=":", lw=0.8)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"{axis} error [deg]")
        ax.set_title(f"{axis} estimate error {title}".strip())
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=min(4, len(errs)), loc="upper right")
        path = out_dir / f"error_{axis}.png"
        save_figure(fig, path)
        paths.append(path)
    return paths
