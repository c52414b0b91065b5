"""Overview figure of a recording: true attitude, body rates and the sensor signals."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from quadest.data.recording import Recording
from quadest.plot.save import pyplot, save_figure
from quadest.rotation import quat_to_euler


def plot_recording(rec: Recording, path: str | Path, title: str | None = None) -> str | Path:
    """Write a PNG/PDF/SVG with attitude (when truth is present), rates, accelerometer and
    magnetometer over time. Returns the path."""
    plt = pyplot()

    panels = (["att"] if rec.true_q is not None else []) + ["gyr", "acc"] + (["mag"] if rec.has_mag else [])
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, 2.4 * len(panels)), sharex=True, constrained_layout=True)
    axes = np.atleast_1d(axes)
    t = rec.t - rec.t[0]
    colors = ("tab:red", "tab:green", "tab:blue")
    for ax, panel in zip(axes, panels):
        if panel == "att":
            e = np.degrees(quat_to_euler(rec.true_q))
            for j, name in enumerate(("roll", "pitch", "yaw")):
                ax.plot(t, e[:, j], color=colors[j], lw=0.8, label=f"true {name}")
            ax.set_ylabel("attitude [deg]")
        elif panel in ("gyr", "acc"):
            meas, true = getattr(rec, panel), getattr(rec, "true_" + panel)
            for j, a in enumerate("xyz"):
                ax.plot(t, meas[:, j], color=colors[j], lw=0.5, alpha=0.7, label=f"{panel} {a}")
                if true is not None:
                    ax.plot(t, true[:, j], color=colors[j], lw=1.0, ls="--")
            ax.set_ylabel("body rate [rad/s]" if panel == "gyr" else "specific force [m/s²]")
        else:
            ok = np.isfinite(rec.mag[:, 0])
            for j, a in enumerate("xyz"):
                ax.plot(t[ok], rec.mag[ok, j], color=colors[j], lw=0.6, label=f"mag {a}")
            ax.set_ylabel(f"mag [{rec.meta.get('units', {}).get('mag', '?')}]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1].set_xlabel("time [s]")
    if title:
        axes[0].set_title(title + ("   (dashed: truth)" if rec.true_gyr is not None else ""))
    save_figure(fig, path)
    return path
