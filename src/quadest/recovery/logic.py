"""The recovery logic (section V.A): detect a throw, run the bank of EKFs until the gravity
estimate has converged, then hand over to a nominal estimator.

States: ``waiting`` (until ``‖z_acc‖ < β1``, eq 37, holds for ``detect_samples`` consecutive
samples) → ``converging`` (the bank runs from the detection; the transition is reported as
``thrown``) → ``nominal`` (once ``S_g < β2``, eqs 38-39, and at least ``dwell_s`` after the
detection: the most likely hypothesis's mean and covariance, eq 35, initialise one EKF of the
same kind, which continues with attitude and velocity kept). The paper's detection is per
sample; requiring a few consecutive samples (default 3, i.e. 3 ms at 1 kHz) keeps a single
vibration spike from starting a recovery.

Two additions to the paper's logic, for a throw detected while the hand still holds the
vehicle (a hand that accelerates it downward faster than ``g − β1`` takes ‖z_acc‖ below β1;
before the release its acceleration falls again): while converging, ``rearm_samples``
consecutive samples with ``‖z_acc‖ ≥ β1`` return the logic to ``waiting`` and the bank starts
afresh at the next detection (a free-falling vehicle reads its aerodynamic force alone, well
below β1); and the handover waits ``dwell_s`` after the detection, so that a detection in the
hand is re-armed before the bank it started is handed over. Both apply in the loop
(:mod:`quadest.flight.phases`) and over a recording (:func:`recover`) through the same compiled
functions (:func:`count_samples`, :func:`handover_due`, :func:`restart_bank`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import njit
from quadest.conventions import GRAVITY
from quadest.models.aero import AeroModel
from quadest.records import check, describe, param
from quadest.recovery.bank import BankRecord, bank_step, gravity_body, summarize
from quadest.recovery.sphere import spread_points
from quadest.rotation import quat_conj, quat_rotate
from quadest.rotation.kernels import FASTMATH

if TYPE_CHECKING:
    from quadest.data.recording import Recording

_P = param
REARM_SAMPLES, DWELL_S, BARO_STD, BANK_BARO = 3, 0.5, 0.3, False  # defaults (RecoveryParams' fields say why)


@dataclass(frozen=True)
class RecoveryParams:
    n_hypotheses: int = _P(40, "-", "hypotheses of the bank (spread on the sphere)", "recovery paper, §V (N = 40)")
    beta1: float = _P(7.0, "m/s²", "throw detection: ‖z_acc‖ below this (eq 37)", "recovery paper, §V.A")
    beta2: float = _P(0.06, "-", "convergence: spherical variance S_g below this (eq 38)", "recovery paper, §V.A")
    detect_samples: int = _P(
        3,
        "samples",
        "consecutive samples below β1 to detect a throw",
        "chosen: 3 ms at 1 kHz keeps one vibration spike from starting a recovery",
    )
    rearm_samples: int = _P(
        REARM_SAMPLES,
        "samples",
        "while converging, consecutive samples with ‖z_acc‖ ≥ β1 that return the logic to waiting "
        "(the bank restarts at the next detection); 0: never (the paper's logic)",
        "chosen: as detect_samples; a hand still accelerating the vehicle reads ‖z_acc‖ ≥ β1 for "
        "tens of ms before the release, the free flight after it never (flown throws 101-150)",
        bounds="[0, 1e6]",
    )
    dwell_s: float = _P(
        DWELL_S,
        "s",
        "shortest time from the (latest) detection to the handover; 0: at once when S_g < β2 (the paper's)",
        "chosen on flown throws 101-150, not the reported 1-100: no handover in the hand and the "
        "gravity error at the handover within 5° median, 10° p90 there, for more fall (docs/recovery.md)",
        bounds="[0, 10]",
    )
    baro_std: float = _P(
        BARO_STD,
        "m",
        "barometer noise std the nominal EKF assumes (its height state, corrected by each reading, "
        "corrects its velocity); 0: the barometer is not read",
        "chosen: the sensor's 0.1 m noise and what its 50 ms lag makes of a few m/s of climb",
        bounds="[0, 100]",
    )
    bank_baro: bool = _P(
        BANK_BARO,
        "-",
        "the bank reads the barometer too: each hypothesis carries the height, each reading updates "
        "it and adds its term to the likelihood (noise baro_std; none when baro_std is 0)",
        "measured on flown throws 101-150 (docs/recovery.md)",
    )
    sigma_v0: float = _P(3.0, "m/s", "initial velocity std per axis (eq 20)", "chosen: the speeds of a hand throw")
    sigma_delta0: float = _P(
        1.0, "rad", "initial error-rotation std (eq 20)", "chosen on simulated throws 5000-5079 (not evaluated ones)"
    )
    acc_std: float = _P(
        2.0,
        "m/s²",
        "accelerometer noise std in Σ_acc, model error included (eq 27)",
        "chosen on simulated throws 5000-5079",
    )
    q_vel: float = _P(
        0.5,
        "(m/s²)² s",
        "velocity process noise intensity (aerodynamic model error)",
        "chosen on simulated throws 5000-5079",
    )
    q_att: float = _P(
        1e-4, "rad²/s", "error-rotation process noise intensity (gyro noise)", "chosen: a MEMS gyro's white noise"
    )
    gravity: float = _P(GRAVITY, "m/s²", "gravity", "standard gravity")

    def __post_init__(self):
        check(self, "recovery")

    def bank_record(self, mass: float) -> BankRecord:
        """What the compiled bank reads, by name."""
        return BankRecord(
            gravity=float(self.gravity),
            mass=float(mass),
            acc_var=float(self.acc_std**2),
            q_vel=float(self.q_vel),
            q_att=float(self.q_att),
            baro_var=float(self.baro_std**2) if self.bank_baro else 0.0,
        )

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


def shortest_arc(d) -> np.ndarray:
    """``q_nb`` that turns the body vector ``d`` onto the navigation z axis (eq 18 with the
    shortest-arc rotation of the paper's ref [19]); for ``d = −z`` a half turn about x."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    c = d[2]
    if c < -1.0 + 1e-12:
        return np.array([0.0, 1.0, 0.0, 0.0])
    axis = np.cross(d, [0.0, 0.0, 1.0])
    q = np.concatenate([[1.0 + c], axis])
    return q / np.linalg.norm(q)


def initial_bank(p: RecoveryParams, dirs):
    """The bank at the detection (eq 20): one hypothesis per gravity direction ``dirs`` (body),
    at rest, with the initial covariance (the height's: the barometer's variance); equal
    likelihoods; the heights not yet read (NaN). Returns ``(V, Q_ref, P, L, Z)``."""
    H = len(dirs)
    P0 = np.diag([p.sigma_v0**2] * 3 + [p.sigma_delta0**2] * 2 + [p.baro_std**2])
    Q = np.array([shortest_arc(d) for d in dirs])
    return np.zeros((H, 3)), Q, np.repeat(P0[None], H, axis=0), np.zeros(H), np.full(H, np.nan)


@njit(cache=True)
def count_samples(count, acc, beta1, below):
    """``count + 1`` when ``‖acc‖ < β1`` is ``below``, else 0: the consecutive samples below β1
    (the detection, eq 37) or at or above it (the re-arm)."""
    is_below = np.sqrt(acc[0] ** 2 + acc[1] ** 2 + acc[2] ** 2) < beta1
    return count + 1 if is_below == below else 0


@njit(cache=True)
def handover_due(sg, beta2, elapsed_s, dwell_s):
    """The handover: ``S_g < β2`` (eq 38) and at least ``dwell_s`` since the detection."""
    return sg < beta2 and elapsed_s >= dwell_s - 1e-9


@njit(cache=True)
def restart_bank(V, Qr, P, L, Z, Qr0, P0):
    """The bank back to its start (eq 20): every hypothesis at rest, at its reference attitude
    ``Qr0`` with the covariance ``P0``, equal likelihoods, the height not yet read."""
    for i in range(V.shape[0]):
        L[i] = 0.0
        Z[i] = np.nan
        for j in range(3):
            V[i, j] = 0.0
        for j in range(4):
            Qr[i, j] = Qr0[i, j]
        for r in range(P.shape[1]):
            for c in range(P.shape[2]):
                P[i, r, c] = P0[i, r, c]


@njit(cache=True, fastmath=FASTMATH)
def run_logic(bank, start, data, prm, model, logic, out, record_all):
    """The recovery logic over the recording ``(t, gyr, acc)`` (module doc): waiting, the bank
    ``(V, Qr, P, L, Z, w_prev)`` from each detection, back to waiting on a re-arm (the bank back to
    ``start`` ``(Qr0, P0)``), until the handover. ``logic``: ``(β1, detect_samples,
    rearm_samples, β2, dwell_s)``; ``model`` ``(A, B, C)``; per sample of the bank into ``out``
    ``(best, S_g, probabilities, gravity directions, velocity)`` (every hypothesis's with
    ``record_all``, else the best one's). Returns ``(latest detection, handover, detections,
    first detection)`` (−1: none)."""
    V, Qr, P, L, Z, w_prev = bank
    Qr0, P0 = start
    t, gyr, acc = data
    beta1, detect_samples, rearm_samples, beta2, dwell_s = logic
    prob = np.empty(V.shape[0])
    gd = np.empty((V.shape[0], 3))
    converging = False
    count, k_det, detections, first = 0, -1, 0, -1
    for k in range(len(t)):
        if not converging:
            count = count_samples(count, acc[k], beta1, True)
            if count < detect_samples:
                w_prev[0], w_prev[1], w_prev[2] = gyr[k, 0], gyr[k, 1], gyr[k, 2]
                continue
            converging, count, k_det, detections = True, 0, k, detections + 1
            first = k if first < 0 else first
        elif rearm_samples > 0:
            count = count_samples(count, acc[k], beta1, False)
            if count >= rearm_samples:
                converging, count = False, 0
                restart_bank(V, Qr, P, L, Z, Qr0, P0)
                w_prev[0], w_prev[1], w_prev[2] = gyr[k, 0], gyr[k, 1], gyr[k, 2]
                continue
        sg = bank_sample(bank, data, k, prm, model, out, record_all, prob, gd)
        if handover_due(sg, beta2, t[k] - t[k_det], dwell_s):
            return k_det, k, detections, first
    return k_det, -1, detections, first


@njit(cache=True, fastmath=FASTMATH)
def run_bank(bank, data, k0, prm, model, beta2, out, record_all):
    """The bank ``(V, Qr, P, L, Z, w_prev)`` over the recording ``(t, gyr, acc)`` from sample k0
    until S_g < β2 (returns that index) or the end (returns −1), with the aerodynamic ``model``
    ``(A, B, C)``; per sample into ``out`` ``(best, S_g, probabilities, gravity directions,
    velocity)`` (every hypothesis's with ``record_all``, else the best one's)."""
    n = bank[0].shape[0]
    prob = np.empty(n)
    gd = np.empty((n, 3))
    for k in range(k0, len(data[0])):
        if bank_sample(bank, data, k, prm, model, out, record_all, prob, gd) < beta2:
            return k
    return -1


@njit(cache=True, fastmath=FASTMATH)
def bank_sample(bank, data, k, prm, model, out, record_all, prob, gd):
    """One sample ``k`` of the bank (eqs 20-36) recorded into ``out`` (:func:`run_bank`);
    returns S_g. ``prob`` and ``gd`` are its work arrays."""
    V, Qr, P, L, Z, w_prev = bank
    t, gyr, acc = data
    best_out, sg_out, prob_out, gd_out, v_out = out
    dt = t[k] - t[k - 1] if k > 0 else t[1] - t[0]
    bank_step(bank, (gyr[k], acc[k], dt, True, np.nan), prm, model)
    best, sg = summarize(Qr, L, prm.gravity, prob, gd)
    best_out[k] = best
    sg_out[k] = sg
    for j in range(3):
        v_out[k, j] = V[best, j]
    if record_all:
        for i in range(V.shape[0]):
            prob_out[k, i] = prob[i]
            for j in range(3):
                gd_out[k, i, j] = gd[i, j]
    else:
        for j in range(3):
            gd_out[k, 0, j] = gd[best, j]
    return sg


@njit(cache=True, fastmath=FASTMATH)
def _run_single(single, data, k0, prm, model, out):
    """The nominal estimator: one EKF of the bank's kind (``single``: ``(V, Qr, P, L, w_prev)``)
    over ``data`` (``(t, gyr, acc)``) from k0 to the end, its gravity's direction and velocity
    into ``out`` (``(gd_out, v_out)``)."""
    V, Qr, P, L, w_prev = single
    t, gyr, acc = data
    gd_out, v_out = out
    gd = np.empty(3)
    Z = np.full(1, np.nan)  # no barometer in a recording
    for k in range(k0, len(t)):
        dt = t[k] - t[k - 1]
        bank_step((V, Qr, P, L, Z, w_prev), (gyr[k], acc[k], dt, True, np.nan), prm, model)
        gravity_body(Qr[0], 1.0, gd)
        for j in range(3):
            gd_out[k, j] = gd[j]
            v_out[k, j] = V[0, j]


@dataclass
class RecoveryResult:
    """What a recovery run found. Times in s; arrays per sample (NaN before detection)."""

    t: np.ndarray
    events: list  # [(state, time)]
    detect_index: int | None
    converge_index: int | None
    best: np.ndarray  # most likely hypothesis per sample (−1 outside the bank)
    s_g: np.ndarray  # spherical variance per sample (NaN outside the bank)
    gravity_dir: np.ndarray  # (N, 3) estimated gravity direction in the body (unit)
    velocity: np.ndarray  # (N, 3) estimated body velocity, m/s
    probabilities: np.ndarray | None = None  # (N, H) when recorded
    hypothesis_dirs: np.ndarray | None = None  # (N, H, 3) when recorded
    summary: dict = field(default_factory=dict)

    def state_at(self, k: int) -> str:
        if self.detect_index is None or k < self.detect_index:
            return "waiting"
        if self.converge_index is None or k < self.converge_index:
            return "converging"
        return "nominal"


def detect_throw(acc, beta1: float, samples: int) -> int | None:
    """Index of the first sample at which ‖acc‖ < β1 has held for ``samples`` samples."""
    below = np.linalg.norm(acc, axis=1) < beta1
    if samples <= 1:
        idx = np.flatnonzero(below)
        return int(idx[0]) if len(idx) else None
    run = np.convolve(below.astype(int), np.ones(samples, int), mode="full")[: len(below)]
    idx = np.flatnonzero(run >= samples)
    return int(idx[0]) if len(idx) else None


def recover(
    rec: Recording,
    model: AeroModel,
    params: RecoveryParams | None = None,
    *,
    record_all: bool = False,
    t_release: float | None = None,
    dirs: ArrayLike | None = None,
) -> RecoveryResult:
    """Run the recovery logic over a recording (IMU only). With truth in the recording the
    summary holds the errors at convergence; ``t_release`` (or a simulated throw's metadata)
    gives the time from release to convergence. ``dirs`` (H, 3) replaces the hypotheses' gravity
    directions in the body (default: ``spread_points(n_hypotheses)``)."""
    p = params or RecoveryParams()
    if dirs is not None:
        dirs = np.asarray(dirs, float)
        if dirs.ndim != 2 or dirs.shape[1] != 3 or len(dirs) < 1:
            raise ValueError(f"dirs must have shape (H, 3), got {dirs.shape}")
        p = replace(p, n_hypotheses=len(dirs))
    n = len(rec)
    t = np.ascontiguousarray(rec.t, dtype=np.float64)
    gyr = np.ascontiguousarray(rec.gyr, dtype=np.float64)
    acc = np.ascontiguousarray(rec.acc, dtype=np.float64)
    best = np.full(n, -1, dtype=np.int64)
    s_g = np.full(n, np.nan)
    gdir = np.full((n, 3), np.nan)
    vel = np.full((n, 3), np.nan)
    H = p.n_hypotheses
    prob = np.full((n, H), np.nan) if record_all else np.empty((1, 1))
    gd_all = np.full((n, H, 3), np.nan) if record_all else np.full((n, 1, 3), np.nan)
    events = [("waiting", float(t[0]))]
    prm = p.bank_record(model.mass_kg)
    V, Qr, P, L, Z = initial_bank(p, spread_points(H) if dirs is None else dirs)
    w_prev = gyr[0].copy()
    k_det, kc, detections, first = (
        run_logic(
            (V, Qr, P, L, Z, w_prev),
            (Qr.copy(), P.copy()),
            (t, gyr, acc),
            prm,
            (model.A, model.B, model.C),
            (float(p.beta1), int(p.detect_samples), int(p.rearm_samples), float(p.beta2), float(p.dwell_s)),
            (best, s_g, prob, gd_all, vel),
            record_all,
        )
        if n > 1
        else (-1, -1, 0, -1)
    )
    k_det = int(k_det) if k_det >= 0 else None
    k_conv = None
    if k_det is not None:
        events.append(("thrown", float(t[k_det])))
        events.append(("converging", float(t[k_det])))
        if record_all:
            idx = np.arange(n)[best >= 0]
            gdir[idx] = gd_all[idx, best[idx]]
        else:
            gdir[:] = gd_all[:, 0]
        if kc >= 0:
            k_conv = int(kc)
            events.append(("nominal", float(t[k_conv])))
            i = best[k_conv]
            if k_conv + 1 < n:
                single = (V[i : i + 1].copy(), Qr[i : i + 1].copy(), P[i : i + 1].copy(), np.zeros(1), w_prev)
                _run_single(single, (t, gyr, acc), k_conv + 1, prm, (model.A, model.B, model.C), (gdir, vel))
    res = RecoveryResult(
        t=t,
        events=events,
        detect_index=k_det,
        converge_index=k_conv,
        best=best,
        s_g=s_g,
        gravity_dir=gdir,
        velocity=vel,
        probabilities=prob if record_all else None,
        hypothesis_dirs=gd_all if record_all else None,
    )
    res.summary = _summarize(res, rec, t_release, p)
    res.summary["detections"] = int(detections)
    if first >= 0:
        res.summary["t_first_detect_s"] = float(t[first])
    return res


def true_gravity_dir(q):
    """Gravity direction in the body frame from ``q_nb``: row 2 of R_nb."""
    q = np.asarray(q, float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def angle_deg(a, b):
    """Angle between vectors (degrees), along the last axis."""
    c = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _summarize(res: RecoveryResult, rec, t_release, p) -> dict:
    info = rec.meta.get("scenario_info", {}) if isinstance(rec.meta, dict) else {}
    if t_release is None:
        t_release = info.get("release_time_s")
    out = {
        "events": [{"state": s, "t_s": t} for s, t in res.events],
        "detected": res.detect_index is not None,
        "converged": res.converge_index is not None,
        "release_time_s": t_release,
        "n_hypotheses": p.n_hypotheses,
        "beta1": p.beta1,
        "beta2": p.beta2,
    }
    if res.detect_index is not None:
        out["t_detect_s"] = float(res.t[res.detect_index])
    if res.converge_index is not None:
        k = res.converge_index
        out["t_converged_s"] = float(res.t[k])
        out["t_converge_from_detection_s"] = float(res.t[k] - res.t[res.detect_index])
        if t_release is not None:
            out["t_converge_s"] = float(res.t[k] - t_release)
        out["gravity_dir_body"] = res.gravity_dir[k].tolist()
        out["velocity_body_mps"] = res.velocity[k].tolist()
        if rec.true_q is not None:
            g_true = true_gravity_dir(rec.true_q[k])
            out["gravity_err_deg"] = float(angle_deg(res.gravity_dir[k], g_true))
            if rec.true_vel is not None:
                v_true = quat_rotate(quat_conj(rec.true_q[k]), rec.true_vel[k])
                out["vel_err_mps"] = float(np.linalg.norm(res.velocity[k] - v_true))
    return out
