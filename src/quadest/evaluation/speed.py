"""How fast the estimators run (``quadest benchmark speed``; a benchmark, never a timed test):
microseconds per sample in batch and in streaming use, quadest's filters and the peers on the
same simulated recording, and the recovery bank."""

from __future__ import annotations

import time

import numpy as np

from quadest.detect import Detector
from quadest.filters import estimator_class, make_filter
from quadest.filters.base import STREAM_C
from quadest.flight import fly
from quadest.models import vehicle_preset
from quadest.recovery.logic import RecoveryParams, run_bank, shortest_arc
from quadest.recovery.sphere import spread_points
from quadest.rotation.frames import vec_frd_to_flu
from quadest.sim import aero_model, build_config, simulate


def time_estimator(factory, rec, *, repeat: int = 3, streaming_samples: int = 2000) -> dict:
    """Microseconds per sample in batch and in streaming use (``update`` called from Python on
    the first ``streaming_samples`` rows), each the best of ``repeat`` runs after a warm-up (the
    machines are shared: the best run is the one least disturbed). The rows are taken out of
    the recording's arrays beforehand: the time is ``update``'s, not numpy's indexing (about
    0.1 µs a row), for quadest's filters and VQF alike."""
    factory().run(rec)  # compile / warm up
    best = np.inf
    for _ in range(repeat):
        f = factory()
        t0 = time.perf_counter()
        f.run(rec)
        best = min(best, time.perf_counter() - t0)
    n = min(streaming_samples, len(rec))
    dt = np.diff(rec.t[: n + 1], prepend=rec.t[0])
    dt[0] = dt[1] if n > 1 else 0.0
    rows = list(zip(rec.gyr[:n], rec.acc[:n], rec.mag[:n], dt.tolist()))
    stream = np.inf
    for _ in range(repeat):
        f = factory()
        f.update(*rows[0][:3], dt=rows[0][3])
        t0 = time.perf_counter()
        for g, a, m, d in rows:
            f.update(g, a, m, dt=d)
        stream = min(stream, (time.perf_counter() - t0) / n)
    return {"batch_us": 1e6 * best / len(rec), "stream_us": 1e6 * stream}


def _peer_speed(name, rec) -> dict:
    """A peer's whole-recording call (best of two on up to 10 000 samples), and VQF's
    per-sample ``update`` from Python (the other peers' batch is that loop already)."""
    part = rec.select(slice(0, min(len(rec), 10000)))
    make_filter(name).run(part.select(slice(0, 200)))  # warm-up
    best = np.inf
    for _ in range(2):
        t0 = time.perf_counter()
        make_filter(name).run(part)
        best = min(best, time.perf_counter() - t0)
    us = best / len(part) * 1e6
    stream = us
    if name == "vqf":
        from vqf import VQF

        g, a = vec_frd_to_flu(part.gyr), vec_frd_to_flu(part.acc)
        f = VQF(float(np.median(np.diff(part.t))))
        n = min(len(part), 3000)
        rows = list(zip(np.ascontiguousarray(g[:n]), np.ascontiguousarray(a[:n])))
        stream = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            for gk, ak in rows:
                f.update(gk, ak)
            stream = min(stream, (time.perf_counter() - t0) / n * 1e6)
    return {"batch_us": us, "stream_us": stream}


def time_detector(duration: float = 60.0, repeat: int = 3) -> float:
    """µs per sample of the rotor-failure detector's batch run (rotor speeds given) on a flown
    bebop2 circle, best of ``repeat`` after a warm-up."""
    f = fly("trajectory", seed=1, duration=duration, vehicle="bebop2")
    rec, speeds = f.recording, f.states[:, 13:]
    Detector(vehicle_preset("bebop2")).run(rec.t[:100], rec.gyr[:100], rec.acc[:100], speeds[:100])
    best = np.inf
    for _ in range(repeat):
        det = Detector(vehicle_preset("bebop2"))
        t0 = time.perf_counter()
        det.run(rec.t, rec.gyr, rec.acc, speeds)
        best = min(best, time.perf_counter() - t0)
    return 1e6 * best / len(rec)


def time_bank(n_hypotheses: int = 40, duration: float = 20.0, seed: int = 1) -> float:
    """µs per IMU sample of the whole recovery bank advancing together (compiled loop over a
    simulated throw's free flight, after a warm-up; best of three)."""
    rec = simulate("throw", "fma", seed=seed, duration=duration)
    model = aero_model(build_config("fma"))
    p = RecoveryParams(n_hypotheses=n_hypotheses, beta2=-1.0)  # never converges: the bank runs on
    n = len(rec)
    bufs = dict(
        best_out=np.zeros(n, np.int64),
        sg_out=np.zeros(n),
        prob_out=np.empty((1, 1)),
        gd_out=np.zeros((n, 1, 3)),
        v_out=np.zeros((n, 3)),
    )

    def once():
        dirs = spread_points(n_hypotheses)
        V = np.zeros((n_hypotheses, 3))
        Qr = np.array([shortest_arc(d) for d in dirs])
        P = np.repeat(np.diag([9.0, 9, 9, 1, 1])[None], n_hypotheses, axis=0)
        t0 = time.perf_counter()
        run_bank(
            (V, Qr, P, np.zeros(n_hypotheses), rec.gyr[0].copy()),
            (rec.t, rec.gyr, rec.acc),
            1,
            p.bank_record(model.mass_kg),
            (model.A, model.B, model.C),
            p.beta2,
            tuple(bufs[k] for k in ("best_out", "sg_out", "prob_out", "gd_out", "v_out")),
            False,
        )
        return time.perf_counter() - t0

    once()
    return 1e6 * min(once() for _ in range(3)) / (n - 1)


def benchmark_speed(names, duration: float = 60.0, on_result=None) -> dict:
    """µs per sample of each estimator on ``duration`` s of a simulated damaged-rotor flight
    (bebop2, seed 1): batch (best of 3 after a warm-up) and streaming; and the recovery bank
    of 40 EKFs. ``on_result(name, figures)`` is called as each estimator finishes."""
    rec = simulate("damaged-rotor", "bebop2", seed=1, duration=duration)
    out = {}
    for name in names:
        if not estimator_class(name).peer:
            tm = time_estimator(lambda n=name: make_filter(n, declination=0.035), rec)
            out[name] = {"batch_us": tm["batch_us"], "stream_us": tm["stream_us"]}
        else:
            out[name] = _peer_speed(name, rec)
        if on_result is not None:
            on_result(name, out[name])
    return {
        "samples": len(rec),
        "filters": out,
        "recovery_bank_40_us": time_bank(40),
        "detector_us": time_detector(duration),
        "streaming_in_c": STREAM_C,
    }
