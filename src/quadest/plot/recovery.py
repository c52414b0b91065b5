"""Recovery figures: the paper's Figs 1-3."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from quadest.plot.save import pyplot, save_figure
from quadest.recovery.logic import angle_deg, true_gravity_dir
from quadest.rotation import quat_conj, quat_rotate

if TYPE_CHECKING:
    from quadest.data.recording import Recording
    from quadest.recovery.logic import RecoveryResult


def plot_recovery(res: RecoveryResult, rec: Recording, path: str | Path, title: str = "") -> str | Path:
    """Angle error of every hypothesis and of the most likely one (Fig 3, top), the hypothesis
    probabilities (Fig 3, bottom) and estimated against true body velocity (Fig 2)."""
    plt = pyplot()

    t = res.t - res.t[0]
    k0 = res.detect_index if res.detect_index is not None else 0
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True, constrained_layout=True)
    ax = axes[0]
    if rec.true_q is not None and res.hypothesis_dirs is not None:
        g_true = true_gravity_dir(rec.true_q)
        H = res.hypothesis_dirs.shape[1]
        for i in range(H):
            ax.plot(t, angle_deg(res.hypothesis_dirs[:, i], g_true), color="0.75", lw=0.5)
    if rec.true_q is not None:
        ax.plot(
            t,
            angle_deg(res.gravity_dir, true_gravity_dir(rec.true_q)),
            color="tab:blue",
            lw=1.5,
            label="most likely / nominal",
        )
        ax.set_ylabel("gravity direction error [deg]")
        ax.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    if res.probabilities is not None:
        ax.plot(t, res.probabilities, lw=0.7)
    ax.set_ylabel("hypothesis probability")
    ax = axes[2]
    colors = ("tab:red", "tab:green", "tab:blue")
    for j, a in enumerate("xyz"):
        ax.plot(t, res.velocity[:, j], color=colors[j], lw=1.2, label=f"estimated v_{a}")
    if rec.true_vel is not None:
        vb = quat_rotate(quat_conj(rec.true_q), rec.true_vel)
        for j, a in enumerate("xyz"):
            ax.plot(t, vb[:, j], color=colors[j], lw=0.8, ls="--", label=f"true v_{a}")
    ax.set_ylabel("body velocity [m/s]")
    ax.legend(loc="upper right", fontsize=7, ncol=2)
    axes[-1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        for state, te in res.events[1:]:
            if state in ("thrown", "nominal"):
                ax.axvline(te - res.t[0], color="k", ls=":", lw=0.8)
    if res.detect_index is not None:
        axes[0].set_xlim(max(0.0, t[k0] - 0.3), t[-1])
    axes[0].set_title(title or "state estimate recovery (dotted: throw detected, converged)")
    save_figure(fig, path)
    return path


def plot_recovery_histograms(runs: dict, path: str | Path) -> str | Path:
    """Gravity-direction and velocity errors at convergence over throws, per model case (Fig 1)."""
    plt = pyplot()

    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), constrained_layout=True)
    for name, summaries in runs.items():
        g = [s["gravity_err_deg"] for s in summaries if "gravity_err_deg" in s]
        v = [s["vel_err_mps"] for s in summaries if "vel_err_mps" in s]
        axes[0].hist(g, bins=np.linspace(0, max(30, max(g, default=0)), 31), histtype="step", lw=1.4, label=name)
        axes[1].hist(v, bins=30, histtype="step", lw=1.4, label=name)
    axes[0].set_xlabel("gravity direction error at convergence [deg]")
    axes[1].set_xlabel("velocity error at convergence [m/s]")
    for ax in axes:
        ax.set_ylabel("throws")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    save_figure(fig, path)
    return path
