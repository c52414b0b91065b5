"""How fast the flying vehicle runs (``quadest benchmark sim``; a benchmark, never a timed test):
the closed loop with an estimator and the fault-tolerant controller in it, and the SE(3) circle
flown by quadest and by RotorPy in the same run."""

from __future__ import annotations

import time

from quadest.flight.common import SIM_RATE_HZ
from quadest.flight.crosscheck import crosscheck, rotorpy_available
from quadest.flight.fly import fly
from quadest.sim import build_config


def time_closed_loop(estimator: str = "afckf", duration: float = 20.0, repeat: int = 3) -> dict:
    """The rotor-loss flight (fault-tolerant controller) with ``estimator`` in the loop, sensors
    at the simulation rate (the bebop2 preset's with its IMU at 1 kHz): the best of ``repeat``
    runs after a warm-up, the compiled loop alone and the whole ``fly`` call (sensor draws,
    the controller's model, the recording and its checks)."""
    cfg = build_config("bebop2", {"imu.rate_hz": SIM_RATE_HZ})
    fly("rotor-loss", estimator=estimator, duration=1.0, config=cfg)  # compile
    loop, total = float("inf"), float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        f = fly("rotor-loss", estimator=estimator, duration=duration, config=cfg)
        total = min(total, time.perf_counter() - t0)
        loop = min(loop, f.timing["loop_s"])
    return {
        "estimator": estimator,
        "controller": "ftc",
        "rate_hz": SIM_RATE_HZ,
        "duration_s": duration,
        "status": f.summary["status"],
        "loop_s": loop,
        "total_s": total,
        "loop_x_real_time": duration / loop,
        "total_x_real_time": duration / total,
        "loop_us_per_step": 1e6 * loop / (duration * SIM_RATE_HZ),
    }


def benchmark_sim(duration: float = 20.0, rotorpy_duration: float = 10.0, estimator: str = "afckf") -> dict:
    """Both measurements; the RotorPy one when RotorPy is installed."""
    out = {"closed_loop": time_closed_loop(estimator, duration)}
    if rotorpy_available():
        out["rotorpy"] = crosscheck(duration=rotorpy_duration, rate_hz=SIM_RATE_HZ)
    return out
