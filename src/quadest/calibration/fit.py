"""Fitting calibrations from recordings (docs/calibration.md).

Every fit returns a :class:`~quadest.calibration.model.Calibration` with values, 1σ
uncertainties and quality figures, or raises ValueError saying what the data lack.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from quadest.calibration.model import Calibration
from quadest.conventions import GRAVITY
from quadest.models.aero import fit_aero

if TYPE_CHECKING:
    from quadest.data.recording import Recording


# -- static segments ------------------------------------------------------------------------------
def _moving_std(x, w):
    """Standard deviation over a centred window of w samples (per column), by cumulative sums."""
    n = len(x)
    c1 = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x]), axis=0)
    c2 = np.cumsum(np.vstack([np.zeros((1, x.shape[1])), x * x]), axis=0)
    lo = np.clip(np.arange(n) - w // 2, 0, n)
    hi = np.clip(np.arange(n) + w // 2 + 1, 0, n)
    cnt = (hi - lo)[:, None]
    mean = (c1[hi] - c1[lo]) / cnt
    var = (c2[hi] - c2[lo]) / cnt - mean * mean
    return np.sqrt(np.maximum(var, 0.0)), mean


def static_segments(
    rec: Recording,
    *,
    window_s: float = 0.5,
    min_s: float = 2.0,
    gyr_std: float = 0.05,
    acc_std: float = 0.5,
    gyr_mean: float = 0.2,
    trim_s: float = 0.25,
) -> list[tuple[int, int]]:
    """Segments ``(i0, i1)`` (row indices, end exclusive) where the sensor is still: over a
    moving window the gyroscope and accelerometer spread stay below ``gyr_std`` (rad/s) and
    ``acc_std`` (m/s²) per axis and the mean rate below ``gyr_mean``; runs shorter than
    ``min_s`` are dropped and ``trim_s`` is cut from both ends."""
    rate = rec.imu_rate_hz()
    w = max(3, int(window_s * rate))
    sg, mg = _moving_std(rec.gyr, w)
    sa, _ = _moving_std(rec.acc, w)
    still = (sg.max(axis=1) < gyr_std) & (sa.max(axis=1) < acc_std) & (np.linalg.norm(mg, axis=1) < gyr_mean)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    out = []
    trim = int(trim_s * rate)
    for a, b in zip(edges[::2], edges[1::2]):
        a, b = a + trim, b - trim
        if b - a >= min_s * rate:
            out.append((int(a), int(b)))
    return out


def _segments_of(recs, **kw):
    segs = []
    for k, rec in enumerate(recs):
        for a, b in static_segments(rec, **kw):
            segs.append((k, a, b))
    return segs


def _source(recs):
    return {
        "recordings": [
            str(r.meta.get("source", "")) + (f" seed {r.meta['seed']}" if "seed" in r.meta else "") for r in recs
        ]
    }


# -- gyroscope ------------------------------------------------------------------------------------
def calibrate_gyro(recs: Sequence[Recording], **kw) -> Calibration:
    """Bias = mean gyroscope reading over the rest segments found automatically."""
    segs = _segments_of(recs, **kw)
    if not segs:
        raise ValueError(
            "gyro: no rest segment found (the vehicle must lie still for a few seconds; "
            "quadest simulate --scenario rest shows the motion)"
        )
    samples = np.vstack([recs[k].gyr[a:b] for k, a, b in segs])
    bias = samples.mean(axis=0)
    noise = samples.std(axis=0)
    means = np.array([recs[k].gyr[a:b].mean(axis=0) for k, a, b in segs])
    rate = recs[0].imu_rate_hz()
    return Calibration(
        "gyro",
        recs[0].meta.get("units", {}).get("gyr", "rad/s"),
        {"bias": bias.tolist()},
        {"bias": (noise / np.sqrt(len(samples))).tolist()},
        {
            "rest_segments_s": [[float(recs[k].t[a]), float(recs[k].t[b - 1])] for k, a, b in segs],
            "rest_time_s": float(len(samples) / rate),
            "noise_std": noise.tolist(),
            "segment_spread": (means.std(axis=0) if len(means) > 1 else np.zeros(3)).tolist(),
        },
        _source(recs),
    )


# -- accelerometer --------------------------------------------------------------------------------
def calibrate_accel(recs: Sequence[Recording], *, gravity: float = GRAVITY, **kw) -> Calibration:
    """Bias, scale and misalignment (the QUKF paper's eq 4) from static positions.

    Six-position set (each body axis down and up once): the reference of each position is ±g
    along that axis, and ``a_i = M f_i + b`` is solved by least squares for the full M and b
    (18 equations, 12 unknowns). Many-position set (at least 9 positions of unknown attitude):
    ``‖T (a_i − b)‖ = g`` is solved for an upper-triangular T and b (9 unknowns; the rotation
    left free by norms alone is fixed that way). The correction is ``a = T (a' − b)``."""
    from scipy.optimize import least_squares

    segs = _segments_of(recs, **kw)
    if len(segs) < 6:
        raise ValueError(
            f"accel: found {len(segs)} static position(s); a calibration needs six (each axis "
            "down and up) or at least nine of varied attitude, each held still for 2 s or more"
        )
    means = np.array([recs[k].acc[a:b].mean(axis=0) for k, a, b in segs])
    counts = np.array([b - a for _, a, b in segs])
    noise = np.array([recs[k].acc[a:b].std(axis=0) for k, a, b in segs]).mean(axis=0)
    axis = np.argmax(np.abs(means), axis=1)
    signs = np.sign(means[np.arange(len(means)), axis])
    dominance = np.abs(means[np.arange(len(means)), axis]) / np.linalg.norm(means, axis=1)
    six = len(set(zip(axis.tolist(), signs.tolist()))) == 6 and dominance.min() > 0.9
    if six:
        F = np.zeros_like(means)
        F[np.arange(len(means)), axis] = signs * gravity  # reference specific force of each position
        X = np.column_stack([F, np.ones(len(F))])  # a = [M | b] [f; 1]
        sol, *_ = np.linalg.lstsq(X, means, rcond=None)
        M, b = sol[:3].T, sol[3]
        resid = means - X @ sol
        dof = max(1, 3 * len(F) - 12)
        s2 = float(np.sum(resid**2) / dof)
        cov = np.linalg.inv(X.T @ X) * s2
        b_std = np.sqrt(np.full(3, cov[3, 3]))
        m_std = np.sqrt(np.diag(cov)[:3])
        T = np.linalg.inv(M)
        method = "six-position"
    else:
        if len(segs) < 9:
            raise ValueError(
                f"accel: the {len(segs)} static positions are not the six axis-aligned ones; a "
                "many-position calibration needs at least nine of varied attitude"
            )

        def res(p):
            T = np.array([[p[0], p[1], p[2]], [0, p[3], p[4]], [0, 0, p[5]]])
            return np.linalg.norm((means - p[6:9]) @ T.T, axis=1) - gravity

        sol = least_squares(res, np.array([1, 0, 0, 1, 0, 1, 0, 0, 0], float))
        p = sol.x
        T = np.array([[p[0], p[1], p[2]], [0, p[3], p[4]], [0, 0, p[5]]])
        b = p[6:9]
        M = np.linalg.inv(T)
        dof = max(1, len(means) - 9)
        s2 = float(np.sum(sol.fun**2) / dof)
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * s2
        b_std = np.sqrt(np.diag(cov)[6:9])
        m_std = np.sqrt(np.diag(cov)[[0, 3, 5]])
        method = "many-position"
    corrected = (means - b) @ T.T
    return Calibration(
        "accel",
        recs[0].meta.get("units", {}).get("acc", "m/s^2"),
        {"bias": b.tolist(), "matrix": T.tolist(), "sensor_matrix": M.tolist(), "scale": (np.diag(M) - 1.0).tolist()},
        {"bias": b_std.tolist(), "scale": m_std.tolist()},
        {
            "method": method,
            "positions": len(segs),
            "samples_per_position": counts.tolist(),
            "norm_residual_rms_mps2": float(np.sqrt(np.mean((np.linalg.norm(corrected, axis=1) - gravity) ** 2))),
            "noise_std": noise.tolist(),
        },
        _source(recs),
    )


# -- magnetometer ---------------------------------------------------------------------------------
def _ellipsoid_algebraic(m):
    """Algebraic ellipsoid fit ``(m − h)ᵀ A (m − h) = 1``; returns h, A. Exact without noise,
    but biased by it (about 1 % of the field in the centre with 0.5 µT noise)."""
    x, y, z = m[:, 0], m[:, 1], m[:, 2]
    D = np.column_stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z, 2 * x, 2 * y, 2 * z])
    v, *_ = np.linalg.lstsq(D, np.ones(len(m)), rcond=None)
    Q = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    h = -np.linalg.solve(Q, v[6:9])
    k = 1.0 + h @ Q @ h
    return h, Q / k


def _ellipsoid(m):
    """Ellipsoid fit: the algebraic solution refined by least squares on the radial residual
    ``‖L (m − h)‖ − 1`` (L symmetric, ``A = LᵀL``), which noise does not bias."""
    from scipy.optimize import least_squares

    h0, A0 = _ellipsoid_algebraic(m)
    w, V = np.linalg.eigh(A0)
    L0 = V @ np.diag(np.sqrt(np.maximum(w, 1e-30))) @ V.T
    iu = np.triu_indices(3)

    def unpack(p):
        L = np.zeros((3, 3))
        L[iu] = p[3:]
        return p[:3], L + np.triu(L, 1).T

    def res(p):
        h, L = unpack(p)
        return np.linalg.norm((m - h) @ L.T, axis=1) - 1.0

    sol = least_squares(res, np.concatenate([h0, L0[iu]]))
    h, L = unpack(sol.x)
    return h, L.T @ L


MAG_TURN_MIN_DEG = 10.0
"""The field's directions (each sample's, seen from the sensor) must spread this far, RMS about
their mean direction, for an ellipsoid fit: a rest spreads by its noise alone (0.5 µT of a
48 µT field: 0.6°), a calibration dance by tens of degrees (the simulator's figure-eight with
40 % hard iron: 40°; with a hard iron five times the field, 10°)."""


def field_spread_deg(m) -> float:
    """The RMS angle (deg) between each sample's field direction and their mean direction."""
    u = m / (np.linalg.norm(m, axis=1, keepdims=True) + 1e-300)
    mean = u.mean(axis=0)
    mean /= np.linalg.norm(mean) + 1e-300
    return float(np.degrees(np.sqrt(np.mean(np.arccos(np.clip(u @ mean, -1.0, 1.0)) ** 2))))


def _check_field_turned(m) -> None:
    """Refuse samples whose field was not seen turning (:data:`MAG_TURN_MIN_DEG`)."""
    spread = field_spread_deg(m)
    if spread < MAG_TURN_MIN_DEG:
        raise ValueError(
            f"mag: the field's direction spreads {spread:.1f}° (RMS about its mean) over the samples; an "
            f"ellipsoid fit needs the vehicle turned through many orientations (at least {MAG_TURN_MIN_DEG:.0f}°, "
            "e.g. a figure-eight with rolls and pitches: quadest simulate --scenario figure-eight), not a rest"
        )


def calibrate_mag(recs: Sequence[Recording], *, min_samples: int = 100) -> Calibration:
    """Hard iron h and soft iron by ellipsoid fit: ``m = W (m' − h)`` maps the measured
    ellipsoid onto a sphere whose radius is the ellipsoid's mean radius (the field strength,
    in the magnetometer's unit). Refuses data that do not determine the ellipsoid."""
    m = np.vstack([r.mag[np.isfinite(r.mag[:, 0])] for r in recs])
    if len(m) < min_samples:
        raise ValueError(
            f"mag: {len(m)} magnetometer samples; the ellipsoid fit needs at least {min_samples} "
            "taken while the vehicle turns through many orientations"
        )
    _check_field_turned(m)
    d = m - m.mean(axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True) + 1e-300
    ev = np.linalg.eigvalsh(d.T @ d / len(d))
    if ev[0] < 0.03 * ev[-1]:
        raise ValueError(
            "mag: the field was seen turning in one plane only (a rotation about one axis); "
            "turn the vehicle about its other axes too, e.g. a figure-eight with rolls and "
            "pitches (quadest simulate --scenario figure-eight)"
        )
    h, A = _ellipsoid(m)
    w, V = np.linalg.eigh(A)
    if w.min() <= 0:
        raise ValueError("mag: the samples do not lie on an ellipsoid (is the magnetometer disturbed?)")
    radii = 1.0 / np.sqrt(w)
    F = float(np.prod(radii) ** (1.0 / 3.0))
    W = F * (V @ np.diag(np.sqrt(w)) @ V.T)
    # jackknife over five blocks for the uncertainty of h
    blocks = np.array_split(np.arange(len(m)), 5)
    hs = []
    for blk in blocks:
        keep = np.ones(len(m), bool)
        keep[blk] = False
        hs.append(_ellipsoid(m[keep])[0])
    hs = np.array(hs)
    h_std = np.sqrt(4.0 / 5.0 * np.sum((hs - hs.mean(axis=0)) ** 2, axis=0))
    r = np.linalg.norm((m - h) @ W.T, axis=1)
    return Calibration(
        "mag",
        recs[0].meta.get("units", {}).get("mag", "unknown"),
        {"hard_iron": h.tolist(), "soft_iron_correction": W.tolist(), "field_strength": F},
        {"hard_iron": h_std.tolist()},
        {
            "samples": int(len(m)),
            "radius_rms_rel": float(np.sqrt(np.mean((r / F - 1) ** 2))),
            "coverage_eigenvalues": ev.tolist(),
            "axes": radii.tolist(),
        },
        _source(recs),
    )


# -- centrifugal constants and aerodynamics ------------------------------------------------------------
def fit_centrifugal(gyr, acc, *, min_rate: float = 5.0, gyro_range: float = np.inf):
    """Least-squares ``ω1, ω2`` of eq 13 from a spinning segment: ``a_xy ≈ ω_z² [ω1, ω2] + c``
    over samples with ``|ω_z| > min_rate`` and the gyroscope below its range. Returns
    ``(omega1, omega2, rms_residual)``; raises ValueError without enough spinning samples."""
    gyr, acc = np.asarray(gyr, float), np.asarray(acc, float)
    spinning = (np.abs(gyr[:, 2]) > min_rate) & np.isfinite(acc).all(axis=1)
    ok = spinning & (np.abs(gyr).max(axis=1) < gyro_range)
    if ok.sum() < 50:
        clipped = f" ({int(spinning.sum() - ok.sum())} more with the gyroscope at its range)" if spinning.any() else ""
        raise ValueError(
            f"fit_centrifugal: {int(ok.sum())} samples spin faster than {min_rate} rad/s with the gyroscope "
            f"below its range{clipped}; need a spinning segment of at least 50 samples"
        )
    A = np.column_stack([gyr[ok, 2] ** 2, np.ones(ok.sum())])
    out = []
    res = []
    for j in (0, 1):
        coef, *_ = np.linalg.lstsq(A, acc[ok, j], rcond=None)
        out.append(coef[0])
        res.append(acc[ok, j] - A @ coef)
    return out[0], out[1], float(np.sqrt(np.mean(np.square(res))))


def calibrate_centrifugal(recs: Sequence[Recording], *, min_rate: float = 5.0) -> Calibration:
    """The AFCKF's ω1, ω2 (eq 13) from spinning segments, gyroscope below its range."""
    gyr = np.vstack([r.gyr for r in recs])
    acc = np.vstack([r.acc for r in recs])
    rng = np.inf
    cfg = recs[0].meta.get("config", {})
    if cfg:
        rng = float(cfg["gyro"]["range"]) if cfg["gyro"]["range"] != "inf" else np.inf
    ok = np.abs(gyr).max(axis=1) < rng * (1 - 1e-9)
    o1, o2, res = fit_centrifugal(gyr[ok], acc[ok], min_rate=min_rate)
    spin = np.abs(gyr[ok, 2]) > min_rate
    w2 = gyr[ok][spin, 2] ** 2
    se = res / np.sqrt(np.sum((w2 - w2.mean()) ** 2))
    return Calibration(
        "centrifugal",
        recs[0].meta.get("units", {}).get("acc", "m/s^2"),
        {"omega1": o1, "omega2": o2},
        {"omega1": se, "omega2": se},
        {
            "samples": int(spin.sum()),
            "residual_rms_mps2": res,
            "rate_range_rad_s": [float(np.sqrt(w2.min())), float(np.sqrt(w2.max()))],
        },
        _source(recs),
    )


def calibrate_aero(recs, mass_kg: float | None = None) -> Calibration:
    """The recovery paper's aerodynamic model (eq 14): the same fit as ``quadest fit-aero``."""
    if mass_kg is None:
        mass_kg = recs[0].meta.get("config", {}).get("vehicle", {}).get("mass_kg")
        if mass_kg is None:
            raise ValueError("aero: give the vehicle mass (--mass KG)")
    model = fit_aero(recs, mass_kg)
    return Calibration(
        "aero",
        recs[0].meta.get("units", {}).get("acc", "m/s^2"),
        {"A": model.A.tolist(), "B": model.B.tolist(), "C": model.C.tolist(), "mass_kg": model.mass_kg},
        {},
        model.info,
        _source(recs),
    )


def calibrate(kind: str, recs: Sequence[Recording], **kw) -> Calibration:
    fn = {
        "gyro": calibrate_gyro,
        "accel": calibrate_accel,
        "mag": calibrate_mag,
        "centrifugal": calibrate_centrifugal,
        "aero": calibrate_aero,
    }.get(kind)
    if fn is None:
        raise ValueError(f"unknown calibration kind {kind!r}; kinds: gyro, accel, mag, centrifugal, aero")
    return fn(recs, **kw)
