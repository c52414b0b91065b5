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
    if not factory().streaming:  # an acausal estimator (robust-offline): batch only
        streaming_samples = 0
    factory().run(rec)  # compile / warm up
    best = np.inf
    for _ in range(repeat):
        f = factory()
        t0 = time.perf_counter()
        f.run(rec)
        best = min(best, time.perf_counter() - t0)
    n = min(streaming_samples, len(rec))
    if n == 0:
        return {"batch_us": 1e6 * best / len(rec), "stream_us": None}
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


PAIRED_PEERS = ("vqf", "vqf-offline", "imufusion")
"""The peers timed in pairs: those whose package runs compiled code. ahrs's filters are Python
loops, 10-400 times slower than any quadest filter: pairs would add minutes and nothing their
absolute figures do not show."""
PAIRS = 10
"""Pairs of runs behind each paired ratio (:func:`paired_ratio`)."""
PAIR_SAMPLES = 10000
"""Samples of the recording a paired batch run covers (the Python-loop peers take seconds on
more), and per-sample calls a paired streaming run makes."""


def paired_ratio(time_a, time_b, pairs: int = PAIRS) -> dict:
    """``time_a() / time_b()`` over ``pairs`` pairs run interleaved, the order alternating (A B,
    B A, ...) so that neither always runs first: on a shared machine both see the same load.
    Returns the median ratio and its spread (10th / 90th percentiles, min, max)."""
    ratios = []
    for i in range(pairs):
        if i % 2 == 0:
            a, b = time_a(), time_b()
        else:
            b, a = time_b(), time_a()
        ratios.append(a / b)
    r = np.asarray(ratios)
    p10, p90 = np.percentile(r, [10, 90])
    return {
        "median": float(np.median(r)),
        "p10": float(p10),
        "p90": float(p90),
        "min": float(r.min()),
        "max": float(r.max()),
        "pairs": pairs,
    }


def _batch_seconds(name, rec):
    """A timer of one batch run of the estimator ``name`` over ``rec`` (warmed up once)."""
    make_filter(name).run(rec)

    def once():
        f = make_filter(name)
        t0 = time.perf_counter()
        f.run(rec)
        return time.perf_counter() - t0

    return once


def _stream_seconds(name, rec):
    """A timer of ``update`` called from Python on every row of ``rec``: quadest's filters
    through :meth:`Estimator.update`, VQF through its own ``update`` (FLU rows converted
    beforehand, the magnetometer where it has a sample: the package's call, no wrapper)."""
    dt = float(np.median(np.diff(rec.t)))
    if name == "vqf":
        from vqf import VQF

        g, a, m = (np.ascontiguousarray(vec_frd_to_flu(v)) for v in (rec.gyr, rec.acc, rec.mag))
        rows = [(gk, ak, mk if np.isfinite(mk[0]) else None) for gk, ak, mk in zip(g, a, m)]

        def once():
            f = VQF(dt)
            t0 = time.perf_counter()
            for gk, ak, mk in rows:
                if mk is None:
                    f.update(gk, ak)
                else:
                    f.update(gk, ak, mk)
            return time.perf_counter() - t0

        return once
    rows = list(zip(rec.gyr, rec.acc, rec.mag))

    def once():
        f = make_filter(name, declination=0.035)
        f.update(*rows[0], dt=dt)  # the first call: the C extension takes over from here
        t0 = time.perf_counter()
        for g, a, m in rows:
            f.update(g, a, m, dt=dt)
        return time.perf_counter() - t0

    return once


def paired_speeds(names, rec, pairs: int = PAIRS) -> dict:
    """Each quadest filter in ``names`` against each peer of :data:`PAIRED_PEERS` in ``names``, timed in interleaved
    pairs on the same :data:`PAIR_SAMPLES` samples: ``{"filter/peer": {"batch": ratio,
    "stream": ratio or None}}`` (:func:`paired_ratio`; below 1 the filter is faster). Streaming
    is paired with VQF, the one peer whose package has a per-sample call in compiled code."""
    part = rec.select(slice(0, min(len(rec), PAIR_SAMPLES)))
    ours = [n for n in names if not estimator_class(n).peer]
    peers = [n for n in names if n in PAIRED_PEERS]
    out = {}
    for a in ours:
        for b in peers:
            batch = paired_ratio(_batch_seconds(a, part), _batch_seconds(b, part), pairs)
            streams = b == "vqf" and estimator_class(a).streaming
            stream = paired_ratio(_stream_seconds(a, part), _stream_seconds(b, part), pairs) if streams else None
            out[f"{a}/{b}"] = {"batch": batch, "stream": stream}
    if "robust-offline" in ours and "robust" in ours:  # its two passes and the fusion against one pass
        batch = paired_ratio(_batch_seconds("robust-offline", part), _batch_seconds("robust", part), pairs)
        out["robust-offline/robust"] = {"batch": batch, "stream": None}
    return out


def format_paired(paired: dict, samples: int) -> list[str]:
    """:func:`paired_speeds` as lines: each pair's median ratio and its 10-90 % spread."""
    if not paired:
        return []
    pairs = next(iter(paired.values()))["batch"]["pairs"]
    out = [
        f"paired, filter time / peer time, interleaved over {pairs} pairs on {samples} samples "
        "(median [10th-90th percentile]; below 1 the filter is faster):",
        f"{'filter/peer':<24}{'batch':>24}{'streaming':>24}",
    ]
    for key, r in paired.items():
        cells = [
            "-" if v is None else f"{v['median']:.3g} [{v['p10']:.3g}-{v['p90']:.3g}]"
            for v in (r["batch"], r["stream"])
        ]
        out.append(f"{key:<24}{cells[0]:>24}{cells[1]:>24}")
    return out


def time_detector(duration: float = 60.0, repeat: int = 3, pairs: int = PAIRS, vqf: bool = True) -> dict:
    """The rotor-failure detector's batch run (rotor speeds given) on a flown bebop2 circle: µs
    per sample, best of ``repeat`` after a warm-up; and, with ``vqf``, its time against VQF's
    batch run on the same samples in interleaved pairs (:func:`paired_ratio`, the first
    :data:`PAIR_SAMPLES`; else None)."""
    f = fly("trajectory", seed=1, duration=duration, vehicle="bebop2")
    rec, speeds = f.recording, f.states[:, 13:]
    once = _detector_seconds(rec, speeds)
    best = min(once() for _ in range(repeat))
    if not vqf:
        return {"us": 1e6 * best / len(rec), "vqf": None}
    part = rec.select(slice(0, min(len(rec), PAIR_SAMPLES)))
    against = paired_ratio(_detector_seconds(part, speeds[: len(part)]), _batch_seconds("vqf", part), pairs)
    return {"us": 1e6 * best / len(rec), "vqf": against}


def _detector_seconds(rec, speeds):
    """A timer of one batch run of the detector over ``rec`` with the rotor speeds (warmed up once)."""
    vehicle = vehicle_preset("bebop2")
    Detector(vehicle).run(rec.t[:100], rec.gyr[:100], rec.acc[:100], speeds[:100])

    def once():
        det = Detector(vehicle)
        t0 = time.perf_counter()
        det.run(rec.t, rec.gyr, rec.acc, speeds)
        return time.perf_counter() - t0

    return once


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
        P = np.repeat(np.diag([9.0, 9, 9, 1, 1, 0.09])[None], n_hypotheses, axis=0)
        t0 = time.perf_counter()
        run_bank(
            (V, Qr, P, np.zeros(n_hypotheses), np.zeros(n_hypotheses), rec.gyr[0].copy()),
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


def benchmark_speed(names, duration: float = 60.0, on_result=None, pairs: int = PAIRS) -> dict:
    """µs per sample of each estimator on ``duration`` s of a simulated damaged-rotor flight
    (bebop2, seed 1): batch (best of 3 after a warm-up) and streaming; each quadest filter's
    time against each peer's, in interleaved pairs (:func:`paired_speeds`); and the recovery
    bank of 40 EKFs. ``on_result(name, figures)`` is called as each estimator finishes."""
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
    detector = time_detector(duration, pairs=pairs, vqf="vqf" in names)
    return {
        "samples": len(rec),
        "filters": out,
        "paired": paired_speeds(names, rec, pairs),
        "pair_samples": min(len(rec), PAIR_SAMPLES),
        "recovery_bank_40_us": time_bank(40),
        "detector_us": detector["us"],
        "detector_vs_vqf": detector["vqf"],
        "streaming_in_c": STREAM_C,
    }
