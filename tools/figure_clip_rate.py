"""docs/figures/clip-rate.png: the rate of a clipped gyroscope axis in a flown rotor loss.

A Bebop 2 loses rotor 0 at 5 s with a ±500 °/s gyroscope and robust in the loop (seed 0, the
defaults of ``quadest fly``); per body axis the true rate, the gyroscope's reading and the rate
the controller read (the reading within range, the predicted rate where it clipped).

    python tools/figure_clip_rate.py [OUT]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from quadest.flight import fly  # noqa: E402
from quadest.sim import Failure, build_config  # noqa: E402


def main(out: str = "docs/figures/clip-rate.png") -> None:
    cfg = build_config("bebop2").with_overrides({"gyro.range": math.radians(500.0)})
    kw = dict(estimator="robust", vehicle="bebop2", config=cfg, seed=0, duration=9.0, failure=Failure(0, 5.0))
    f = fly("rotor-loss", **kw)
    t = f.recording.t
    show = (t > 4.8) & (t < 9.0)
    fig, axes = plt.subplots(3, 1, figsize=(8, 6.5), sharex=True)
    for j, (ax, name) in enumerate(zip(axes, "xyz")):
        ax.plot(t[show], f.states[show, 10 + j], "k", lw=1.6, label="true")
        ax.plot(t[show], f.recording.gyr[show, j], color="tab:red", lw=1, label="gyroscope (±500 °/s)")
        ax.plot(t[show], f.rate_est[show, j], "--", color="tab:blue", lw=1, label="read by the controller")
        ax.set_ylabel(f"ω_{name} (rad/s)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="lower right", fontsize=8)
    axes[-1].set_xlabel("time (s); rotor 0 lost at 5 s")
    s = f.summary
    err = " / ".join("-" if e is None else f"{e:.2f}" for e in s["clip_rate_error_rms_rad_s"])
    fig.suptitle(
        f"robust in the loop, seed 0: {s['status']}; {100 * s['gyro_clipped_share']:.0f} % clipped after the loss, "
        f"rate error there {err} rad/s RMS",
        fontsize=9,
    )
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
