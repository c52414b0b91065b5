"""The figure of a flown run: path, attitude and the estimate the controller flew with, rotor
speeds."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from quadest.plot.save import pyplot, save_figure
from quadest.rotation import quat_to_euler

if TYPE_CHECKING:
    from quadest.flight.common import Flight


def plot_flight(flight: Flight, path: str | Path, title: str = "") -> Path:
    """Top view and height of the path (true and estimated), roll and pitch (true and as the
    controller read them), rotor speeds; the failure and the end of a run that crashed marked."""
    plt = pyplot()

    rec, x, s = flight.recording, flight.states, flight.summary
    t = rec.t
    fig = plt.figure(figsize=(11, 8), constrained_layout=True)
    grid = fig.add_gridspec(3, 2, width_ratios=(1, 2))
    ax = fig.add_subplot(grid[:, 0])
    ax.plot(x[:, 1], x[:, 0], lw=0.8, label="true")
    ax.plot(flight.pv_est[:, 1], flight.pv_est[:, 0], lw=0.6, ls="--", label="estimated")
    ax.plot(x[0, 1], x[0, 0], "o", color="tab:green", label="start")
    ax.plot(x[-1, 1], x[-1, 0], "x", color="tab:red", label="end")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8)
    ax.set_title("path, top view")
    a1 = fig.add_subplot(grid[0, 1])
    a1.plot(t, -x[:, 2], label="height (true)")
    a1.plot(t, -flight.pv_est[:, 2], ls="--", lw=0.8, label="height (estimated)")
    a1.plot(t, np.linalg.norm(x[:, 0:2], axis=1), label="horizontal distance from origin")
    a1.set_ylabel("m")
    a1.legend(fontsize=8, loc="best")
    a2 = fig.add_subplot(grid[1, 1], sharex=a1)
    e_true = np.degrees(quat_to_euler(x[:, 6:10]))
    e_est = np.degrees(quat_to_euler(flight.q_est))
    for i, (name, c) in enumerate((("roll", "tab:blue"), ("pitch", "tab:orange"))):
        a2.plot(t, e_true[:, i], color=c, lw=0.8, label=f"{name} (true)")
        a2.plot(t, e_est[:, i], color=c, lw=0.6, ls="--", label=f"{name} (estimated)")
    a2.set_ylabel("deg")
    a2.legend(fontsize=8, ncol=2, loc="best")
    a3 = fig.add_subplot(grid[2, 1], sharex=a1)
    for i in range(x.shape[1] - 13):
        a3.plot(t, x[:, 13 + i], lw=0.8, label=f"rotor {i}")
    a3.set_ylabel("rotor speed (rad/s)")
    a3.set_xlabel("time (s)")
    a3.legend(fontsize=8, ncol=4, loc="best")
    failure = rec.meta.get("failure")
    for a in (a1, a2, a3):
        if failure:
            a.axvline(failure["time_s"], color="k", ls=":", lw=0.8)
        if s.get("status") != "survived":
            a.axvline(t[-1], color="tab:red", ls="-", lw=0.8)
    fig.suptitle(title or f"{s.get('scenario')} / {s.get('controller')} / {s.get('estimator')}: {s.get('reason')}")
    return save_figure(fig, path)
