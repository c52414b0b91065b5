"""Gyro clipping (docs/estimators.md, robust, item 6): a clipped axis found from a known range or a
confirmed flat top, and its rate with its angular acceleration (eq R4d) from the magnetometer's
rotation in the body (eqs R4-R4c), the clipped axes together (eq R4f), never below the limit."""

from __future__ import annotations

import math

import numpy as np

from quadest._jit import njit
from quadest.filters.robust.params import COEF, PARAM, STATE
from quadest.rotation.kernels import mag_rate_terms


@njit(cache=True, inline="always")
def rate_gain(p, t):
    """Eq R4d: the rate an angular acceleration of 1 adds over ``t`` while it decays with
    ``clip_accel_tau`` (τ): ``∫₀ᵗ e^(−s/τ) ds = τ (1 − e^(−t/τ))``."""
    tau = p[PARAM.clip_accel_tau]
    return -tau * math.expm1(-t / tau)


@njit(cache=True)
def rate_predict(x, p, i, mdt):
    """Eq R4d: axis i's rate ω and angular acceleration α over ``mdt``: ``ω ← ω + g α``,
    ``α ← φ α`` (``φ = e^(−Δt/τ)``, ``g`` :func:`rate_gain`), ``P ← F P Fᵀ + Q`` on the joint
    covariance ``P`` of the three axes (``Pc``, eq R4f): the rate's random walk
    (``clip_rate_q``) and the acceleration's, of intensity ``c² s² / τ`` (``c``
    ``clip_accel_change``, ``s`` the slope at the clip decaying as α does; its terms those of
    an integrated random walk, Δt ≪ τ)."""
    tau = p[PARAM.clip_accel_tau]
    g = rate_gain(p, mdt)
    phi = math.exp(-mdt / tau)
    qa = (p[PARAM.clip_accel_change] * x[STATE.ascale + i]) ** 2 / tau
    x[STATE.ascale + i] *= phi
    x[STATE.rate + i] += g * x[STATE.accel + i]
    x[STATE.accel + i] *= phi
    w, a = STATE.Pc + 7 * i, STATE.Pc + 7 * i + 21  # the diagonal entries of ω_i and α_i
    for k in range(6):  # rows, then columns: F P Fᵀ
        x[STATE.Pc + 6 * i + k] += g * x[STATE.Pc + 6 * (3 + i) + k]
        x[STATE.Pc + 6 * (3 + i) + k] *= phi
    for k in range(6):
        x[STATE.Pc + 6 * k + i] += g * x[STATE.Pc + 6 * k + 3 + i]
        x[STATE.Pc + 6 * k + 3 + i] *= phi
    x[w] += p[PARAM.clip_rate_q] * mdt + qa * mdt**3 / 3.0
    x[w + 3] += 0.5 * qa * mdt * mdt
    x[w + 18] += 0.5 * qa * mdt * mdt
    x[a] += qa * mdt


@njit(cache=True, inline="always")
def rate_from_reading(x, i, wi, rg, mdt):
    """Eq R4d within range: the rate at the interval's end and the angular acceleration from the
    slope between this interval's mean reading ``wi`` and the last one's (each of variance
    ``rg``, their midpoints ``d`` apart): ``α = (wi − w̄) / d``, ``ω = wi + α Δt / 2``."""
    first = x[STATE.wmid + i] == 0.0  # no earlier reading: no slope, α 0 and known so
    d = x[STATE.wmid + i] + 0.5 * mdt
    a = 0.0 if first else 0.5 * mdt / d
    alpha = a * (wi - x[STATE.wmean + i]) * 2.0 / mdt
    x[STATE.rate + i] = wi + 0.5 * mdt * alpha
    x[STATE.accel + i] = alpha
    x[STATE.ascale + i] = alpha
    pwa = 0.0 if first else (1.0 + 2.0 * a) * rg / d
    x[STATE.Pc + 7 * i] = ((1.0 + a) ** 2 + a * a) * rg
    x[STATE.Pc + 7 * i + 3] = pwa
    x[STATE.Pc + 7 * i + 18] = pwa
    x[STATE.Pc + 7 * i + 21] = 0.0 if first else 2.0 * rg / (d * d)
    x[STATE.fresh + i] = 1.0
    x[STATE.wmean + i] = wi
    x[STATE.wmid + i] = 0.5 * mdt


@njit(cache=True, inline="always")
def clip_rate_update(x, p, i, num, den, wi, mdt, kl, rg):
    """Eqs R4b-R4d, axis i over the last magnetometer interval. While the axis reads within range
    its mean reading ``wi`` (variance ``rg``) measures the rate and, against the one before, the
    angular acceleration (the slope at which it may clip), and the field's noise about the axis
    (the variance ``V`` of ``num − wi den``) is learnt (gain ``kl``); a flat top not yet
    confirmed a clip measures neither. A clipped axis is followed from the field with the other
    clipped axes, jointly (:func:`clipped_rates_from_field`, eq R4f).

    Eq R4c: on a flat top not yet confirmed a clip (``flat``), once ``V`` has been learnt for
    ``clip_learn_tau``, the field's rate in excess of the reading, ``s (num / den − wi)`` (``s``
    the reading's sign) with variance ``V / den²``, is summed with inverse-variance weights;
    once ``Σ excess den²/V / sqrt(Σ den²/V)`` passes
    ``clip_confirm`` standard errors, and the weighted mean excess the top's spread
    (``clip_flat``), the top's level is the axis's limit for that sign."""
    if x[STATE.gclip + i] == 0.0:
        if x[STATE.gflat + i] != 0.0:
            if (
                x[STATE.Vt + i] >= p[PARAM.clip_learn_tau]
                and x[STATE.Vn + i] > 0.0
                and den > 0.0
                and x[STATE.flat + i] != 0.0
            ):
                sg = 1.0 if x[STATE.level + i] > 0.0 else -1.0
                x[STATE.ev_s + i] += sg * (num - wi * den) * den / x[STATE.Vn + i]
                x[STATE.ev_w + i] += den * den / x[STATE.Vn + i]
                # significant, and beyond the flat top's own spread (a quantised reading's
                # rounding errs one way for as long as it holds its value)
                if (
                    x[STATE.ev_s + i] > p[PARAM.clip_confirm] * math.sqrt(x[STATE.ev_w + i])
                    and x[STATE.ev_s + i] > p[PARAM.clip_flat] * abs(x[STATE.level + i]) * x[STATE.ev_w + i]
                ):
                    if sg > 0.0:
                        x[STATE.lim_pos + i] = x[STATE.level + i]
                    else:
                        x[STATE.lim_neg + i] = x[STATE.level + i]
        else:
            # a running mean until clip_learn_tau has passed, then exponential forgetting
            e = num - wi * den
            x[STATE.Vt + i] += mdt
            x[STATE.Vn + i] += max(kl, mdt / x[STATE.Vt + i]) * (e * e - x[STATE.Vn + i])
            rate_from_reading(x, i, wi, rg, mdt)
            return
    x[STATE.wmid + i] += mdt


@njit(cache=True, inline="always")
def field_residual(c0, c1, c2, d0, d1, d2, w0, w1, w2):
    """The field's change ``d`` against ``m × ω`` (``ṁ = −ω × m``; ``c`` the interval's mid-point
    field, ``w`` its mean rates), per component."""
    return d0 - (c1 * w2 - c2 * w1), d1 - (c2 * w0 - c0 * w2), d2 - (c0 * w1 - c1 * w0)


CLIP_FIELD_FLOOR = 1e-3
"""Eq R4f: the least noise of the field's change, as a rate seen through the field (rad/s): a
noise-free field and gyro would leave ``S`` singular where all three axes clip."""


@njit(cache=True, inline="always")
def field_jacobian(x, b, r, c0, c1, c2, h):
    """Eq R4f's ``H[r, b]``: ``ṁ_r`` against state ``b`` of (ω_x, ω_y, ω_z, α_x, α_y, α_z), on a
    clipped axis ``(m × e_i)_r`` for its rate and ``−Δt/2`` that for its acceleration (the
    interval's mean rate ``ω − α Δt/2``); 0 on an axis read within range."""
    i = b % 3
    if x[STATE.gclip + i] == 0.0:
        return 0.0
    if i == 0:
        v = (0.0, c2, -c1)[r]
    elif i == 1:
        v = (-c2, 0.0, c0)[r]
    else:
        v = (c1, -c0, 0.0)[r]
    return v if b < 3 else -h * v


@njit(cache=True)
def clipped_rates_from_field(x, p, field, mdt, rg):
    """Eq R4f: the axes not read within range over the interval predicted (:func:`rate_predict`)
    and the clipped ones corrected together from the field's change ``d`` (its mid-point ``c``):
    ``ṁ = −ω × m = m × ω``, the interval's mean rate ``ω − α Δt/2`` on a clipped axis and the
    mean reading ``v`` on the others. One Kalman update of (ω, α) on all three axes, of
    covariance ``P`` (``Pc``), with the measurement's noise ``σ² I`` (``sd2``, learnt while no
    axis clips or is a flat top; at least the gyro's mean ``rg |m|²`` and
    :data:`CLIP_FIELD_FLOOR`): where all three clip, the field says nothing of the rate along
    itself, which the prediction keeps, and an error on one axis is not taken as known by the
    others (eq R4, per axis, does). ``P ← P − K (P Hᵀ)ᵀ``, kept symmetric. Written out on the
    state's own entries and its workspace (``work``: ``P Hᵀ``, the gain, ``S``), without
    allocating."""
    (c0, c1, c2), (d0, d1, d2), (v0, v1, v2) = field  # the field's mid-point and change, the mean reading
    P, PH, K, S = STATE.Pc, STATE.work, STATE.work + 18, STATE.work + 36
    for i in range(3):  # an axis's (ω, α) from its reading is uncorrelated with the others'
        if x[STATE.fresh + i] != 0.0:
            for k in range(6):
                if k != i and k != 3 + i:
                    x[P + 6 * i + k] = x[P + 6 * k + i] = x[P + 6 * (3 + i) + k] = x[P + 6 * k + 3 + i] = 0.0
            x[STATE.fresh + i] = 0.0
    nclip = 0
    for i in range(3):
        if x[STATE.gclip + i] != 0.0 or x[STATE.gflat + i] != 0.0:
            rate_predict(x, p, i, mdt)
        nclip += x[STATE.gclip + i] != 0.0
    if nclip == 0:
        return
    h = 0.5 * mdt
    w0 = v0 if x[STATE.gclip] == 0.0 else x[STATE.rate] - h * x[STATE.accel]
    w1 = v1 if x[STATE.gclip + 1] == 0.0 else x[STATE.rate + 1] - h * x[STATE.accel + 1]
    w2 = v2 if x[STATE.gclip + 2] == 0.0 else x[STATE.rate + 2] - h * x[STATE.accel + 2]
    res = field_residual(c0, c1, c2, d0, d1, d2, w0, w1, w2)
    for a in range(6):  # P Hᵀ
        for r in range(3):
            acc = 0.0
            for b in range(6):
                acc += x[P + 6 * a + b] * field_jacobian(x, b, r, c0, c1, c2, h)
            x[PH + 3 * a + r] = acc
    m2 = c0 * c0 + c1 * c1 + c2 * c2
    noise = max(x[STATE.sd2], rg * m2, CLIP_FIELD_FLOOR * CLIP_FIELD_FLOOR * m2)
    for r in range(3):  # S = H P Hᵀ + σ² I
        for q in range(3):
            acc = noise if r == q else 0.0
            for b in range(6):
                acc += field_jacobian(x, b, r, c0, c1, c2, h) * x[PH + 3 * b + q]
            x[S + 3 * r + q] = acc
    s00, s01, s02 = x[S], x[S + 1], x[S + 2]
    s11, s12, s22 = x[S + 4], x[S + 5], x[S + 8]
    i00, i01, i02 = s11 * s22 - s12 * s12, s02 * s12 - s01 * s22, s01 * s12 - s02 * s11
    det = s00 * i00 + s01 * i01 + s02 * i02
    if not det > 0.0:
        return
    i11, i12, i22 = s00 * s22 - s02 * s02, s01 * s02 - s00 * s12, s00 * s11 - s01 * s01
    inv = (i00 / det, i01 / det, i02 / det, i01 / det, i11 / det, i12 / det, i02 / det, i12 / det, i22 / det)
    for a in range(6):  # K = P Hᵀ S⁻¹, the state corrected by K (ṁ − m × ω̄)
        for r in range(3):
            x[K + 3 * a + r] = x[PH + 3 * a] * inv[r] + x[PH + 3 * a + 1] * inv[3 + r] + x[PH + 3 * a + 2] * inv[6 + r]
        dx = x[K + 3 * a] * res[0] + x[K + 3 * a + 1] * res[1] + x[K + 3 * a + 2] * res[2]
        x[(STATE.rate if a < 3 else STATE.accel) + a % 3] += dx
    for a in range(6):  # P ← P − K (P Hᵀ)ᵀ, kept symmetric
        for b in range(a, 6):
            pab = x[P + 6 * a + b] - (
                x[K + 3 * a] * x[PH + 3 * b]
                + x[K + 3 * a + 1] * x[PH + 3 * b + 1]
                + x[K + 3 * a + 2] * x[PH + 3 * b + 2]
            )
            x[P + 6 * a + b] = x[P + 6 * b + a] = pab


@njit(cache=True, inline="always")
def detect_clip(x, p, i, g):
    """Item 6: whether axis i's reading ``g`` is clipped. With a known range, a reading within
    ``clip_flat`` of it. Otherwise a flat top is a candidate: beyond ``clip_min_rate``, within
    ``clip_flat`` of the previous reading and of the extreme of its sign, an extreme that has
    stood ``clip_plateau`` samples (a ramp sets a new one at every sample); it continues while
    the readings stay within ``clip_flat`` of its first (a clipped axis cannot read more, a
    ramp soon does). The signs are tracked apart: calibrated readings clip at +416.6 and
    −421.6 °/s on RepoIMU's TStick trial 5, each wandering by a few tenths of a percent with the
    other axes' calibration terms. A candidate is a clip once its limit is confirmed, by a
    reading repeated exactly ``clip_repeat`` times (a quantised reading repeats at a smooth peak
    for a few samples; a clipped raw value for as long as the clip) or by the field (eq R4c, in
    the magnetometer step): a steady spin at its fastest is a flat top too, and is not a clip.
    A confirmed limit is the sensor's: later readings within ``clip_flat`` of it are clipped at
    once, and a reading beyond it erases it."""
    a = abs(g)
    tol = p[PARAM.clip_flat] * a
    if p[PARAM.gyro_range] > 0.0:
        return a >= p[PARAM.gyro_range] - tol
    if a < p[PARAM.clip_min_rate]:
        x[STATE.flat + i] = 0.0
        return False
    x[STATE.peak_n + i] += 1.0
    x[STATE.trough_n + i] += 1.0
    if g > x[STATE.peak + i]:
        x[STATE.peak + i] = g
        x[STATE.peak_n + i] = 0.0
    if g < x[STATE.trough + i]:
        x[STATE.trough + i] = g
        x[STATE.trough_n + i] = 0.0
    lim = x[STATE.lim_pos + i] if g > 0.0 else x[STATE.lim_neg + i]
    if lim != 0.0 and a > abs(lim) + tol:  # read beyond: it was no limit
        if g > 0.0:
            x[STATE.lim_pos + i] = 0.0
        else:
            x[STATE.lim_neg + i] = 0.0
        lim = 0.0
    if lim != 0.0 and abs(a - abs(lim)) <= tol:
        x[STATE.flat + i] = 0.0
        return True
    if x[STATE.flat + i] != 0.0 and g * x[STATE.level + i] > 0.0:
        cand = abs(a - abs(x[STATE.level + i])) <= tol
    else:
        if g > 0.0:
            cand = g >= x[STATE.peak + i] - tol and x[STATE.peak_n + i] >= p[PARAM.clip_plateau]
        else:
            cand = g <= x[STATE.trough + i] + tol and x[STATE.trough_n + i] >= p[PARAM.clip_plateau]
        cand = cand and abs(g - x[STATE.gprev + i]) <= tol
        x[STATE.level + i] = g
        x[STATE.rep + i] = 0.0
        x[STATE.ev_s + i] = 0.0
        x[STATE.ev_w + i] = 0.0
    if not cand:
        x[STATE.flat + i] = 0.0
        return False
    x[STATE.flat + i] = 1.0
    x[STATE.gflat + i] = 1.0
    x[STATE.rep + i] = x[STATE.rep + i] + 1.0 if g == x[STATE.gprev + i] else 0.0
    if x[STATE.rep + i] >= p[PARAM.clip_repeat]:  # repeated exactly for long: the limit
        if g > 0.0:
            x[STATE.lim_pos + i] = g
        else:
            x[STATE.lim_neg + i] = g
        x[STATE.flat + i] = 0.0
        return True
    return False


@njit(cache=True, inline="always")
def clip_axis(x, p, i, g, dt):
    """Axis i's reading ``g`` clipped or not (:func:`detect_clip`; 1 or 0), the reading
    integrated over the magnetometer interval."""
    clipped = detect_clip(x, p, i, g)
    x[STATE.gprev + i] = g
    x[STATE.gsum + i] += g * dt
    if clipped:
        x[STATE.clipped + i] = 1.0
        x[STATE.gclip + i] = 1.0
        return 1
    x[STATE.clipped + i] = 0.0
    x[STATE.debt + i] = 0.0
    return 0


# The phases below write their axes out rather than loop over them: a loop inside an inlined
# function that takes arrays keeps numba's reference counts on them in the hot path (robust's
# step was 25 % slower with the loops).
@njit(cache=True, inline="always")
def detect_clipping(x, p, gyr, dt):
    """Each axis clipped or not; returns how many are."""
    n0 = clip_axis(x, p, 0, gyr[0], dt)
    n1 = clip_axis(x, p, 1, gyr[1], dt)
    n2 = clip_axis(x, p, 2, gyr[2], dt)
    return n0 + n1 + n2


@njit(cache=True, inline="always")
def held_rates(x, gyr, nclip):
    """The body rate used: a clipped axis's held rate, the reading on the others."""
    w0, w1, w2 = gyr[0], gyr[1], gyr[2]
    if nclip:
        if x[STATE.clipped] != 0.0:
            w0 = x[STATE.hold]
        if x[STATE.clipped + 1] != 0.0:
            w1 = x[STATE.hold + 1]
        if x[STATE.clipped + 2] != 0.0:
            w2 = x[STATE.hold + 2]
    return w0, w1, w2


@njit(cache=True, inline="always")
def rates_from_field(x, p, c, m0, m1, m2):
    """A new magnetometer sample ``m`` closes an interval: eqs R4b / R4c per axis
    (:func:`clip_rate_update`) from the field's change and the other axes' mean rates (eq R4),
    the field's noise learnt while every axis reads within range, and the clipped axes'
    rates from the field together (eq R4f); the interval's sums start again."""
    if np.isfinite(x[STATE.mprev]) and x[STATE.mag_dt] > 0.0:
        mdt = x[STATE.mag_dt]
        kl = 1.0 - math.exp(-mdt / p[PARAM.clip_learn_tau])
        c0, c1, c2 = 0.5 * (m0 + x[STATE.mprev]), 0.5 * (m1 + x[STATE.mprev + 1]), 0.5 * (m2 + x[STATE.mprev + 2])
        d0, d1, d2 = (m0 - x[STATE.mprev]) / mdt, (m1 - x[STATE.mprev + 1]) / mdt, (m2 - x[STATE.mprev + 2]) / mdt
        rg = c[COEF.sg2] / mdt  # the variance of the gyro's mean over the interval
        # the interval's mean rates; a clipped axis's from its estimate (eq R4d)
        gm = 0.5 * rate_gain(p, mdt)
        v0 = x[STATE.gsum] / mdt if x[STATE.gclip] == 0.0 else x[STATE.rate] + gm * x[STATE.accel]
        v1 = x[STATE.gsum + 1] / mdt if x[STATE.gclip + 1] == 0.0 else x[STATE.rate + 1] + gm * x[STATE.accel + 1]
        v2 = x[STATE.gsum + 2] / mdt if x[STATE.gclip + 2] == 0.0 else x[STATE.rate + 2] + gm * x[STATE.accel + 2]
        nu, de = mag_rate_terms(c0, c1, c2, d1, d2, v1, v2)
        clip_rate_update(x, p, 0, nu, de, v0, mdt, kl, rg)
        nu, de = mag_rate_terms(c1, c2, c0, d2, d0, v2, v0)
        clip_rate_update(x, p, 1, nu, de, v1, mdt, kl, rg)
        nu, de = mag_rate_terms(c2, c0, c1, d0, d1, v0, v1)
        clip_rate_update(x, p, 2, nu, de, v2, mdt, kl, rg)
        g0, g1, g2 = (
            x[STATE.gclip] + x[STATE.gflat],
            x[STATE.gclip + 1] + x[STATE.gflat + 1],
            x[STATE.gclip + 2] + x[STATE.gflat + 2],
        )
        if g0 + g1 + g2 != 0.0:
            clipped_rates_from_field(x, p, ((c0, c1, c2), (d0, d1, d2), (v0, v1, v2)), mdt, rg)
        else:  # eq R4f's noise: the field's change against every axis's reading, per component
            r0, r1, r2 = field_residual(c0, c1, c2, d0, d1, d2, v0, v1, v2)
            x[STATE.sdt] += mdt
            x[STATE.sd2] += max(kl, mdt / x[STATE.sdt]) * ((r0 * r0 + r1 * r1 + r2 * r2) / 3.0 - x[STATE.sd2])
    x[STATE.gsum], x[STATE.gsum + 1], x[STATE.gsum + 2] = 0.0, 0.0, 0.0
    x[STATE.gclip], x[STATE.gclip + 1], x[STATE.gclip + 2] = 0.0, 0.0, 0.0
    x[STATE.gflat], x[STATE.gflat + 1], x[STATE.gflat + 2] = 0.0, 0.0, 0.0
    x[STATE.mprev], x[STATE.mprev + 1], x[STATE.mprev + 2] = m0, m1, m2


@njit(cache=True, inline="always")
def hold_axis(x, i, g, dt, ga):
    """A clipped axis's rate: the field's (eq R4f) carried on by its angular acceleration since
    the last magnetometer sample (``ga``, :func:`rate_gain`; eq R4d), never below the limit.
    What the limit adds beyond the field's rate is owed and paid back once that rate exceeds the
    limit, so the bound does not rectify the estimate's noise into a drift."""
    if x[STATE.clipped + i] != 0.0:
        a = abs(g)
        sg = 1.0 if g > 0.0 else -1.0
        r = sg * (x[STATE.rate + i] + ga * x[STATE.accel + i]) + x[STATE.debt + i] / dt
        if r > a:
            x[STATE.hold + i] = sg * r
            x[STATE.debt + i] = 0.0
        else:
            x[STATE.hold + i] = g
            x[STATE.debt + i] = (r - a) * dt


@njit(cache=True, inline="always")
def hold_clipped(x, p, gyr, dt, since):
    """Each clipped axis's held rate (:func:`hold_axis`), ``since`` the last magnetometer sample."""
    ga = rate_gain(p, since)
    hold_axis(x, 0, gyr[0], dt, ga)
    hold_axis(x, 1, gyr[1], dt, ga)
    hold_axis(x, 2, gyr[2], dt, ga)
