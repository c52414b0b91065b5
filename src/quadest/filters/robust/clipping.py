"""Gyro clipping (docs/estimators.md, robust, item 6): a clipped axis found from a known range or a
confirmed flat top, and its rate from the magnetometer's rotation in the body (eqs R4, R4b, R4c),
never below the limit."""

from __future__ import annotations

import math

import numpy as np

from quadest._jit import njit
from quadest.filters.robust.params import PARAM, STATE
from quadest.rotation.kernels import mag_rate_terms


@njit(cache=True, inline="always")
def clip_rate_update(x, p, i, num, den, wi, mdt, kl):
    """Eq R4b: the rate of axis i over the last magnetometer interval. While the axis reads
    within range its mean reading ``wi`` is the rate, and the field's noise (the variance ``V`` of
    ``num − wi den``) is learnt (gain ``kl``). While it is clipped a scalar Kalman filter with a
    random-walk rate (intensity ``q``, ``clip_rate_q``) follows the field's rate:
    ``P ← P + q Δt``, ``K = P / (P + V / den²)``, ``ω ← ω + K (num / den − ω)``,
    ``P ← (1 − K) P``. Its time constant, about ``sqrt(V Δt / (q den²))``, follows from the data:
    a noisy field (the horizontal share of a spin about down) is averaged over a fraction of a
    second, a clean one (a hand-held stick's) followed within a sample or two.

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
        x[STATE.rate + i] = wi
        x[STATE.Pw + i] = 0.0
    else:
        if den <= 0.0:
            return
        pw = x[STATE.Pw + i] + p[PARAM.clip_rate_q] * mdt
        r = x[STATE.Vn + i] / (den * den)
        k = pw / (pw + r) if pw + r > 0.0 else 1.0
        x[STATE.rate + i] += k * (num / den - x[STATE.rate + i])
        x[STATE.Pw + i] = (1.0 - k) * pw


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
def rates_from_field(x, p, m0, m1, m2):
    """A new magnetometer sample ``m`` closes an interval: eq R4 per axis from the field's change
    and the other axes' mean rates, then eqs R4b / R4c (:func:`clip_rate_update`); the interval's
    sums start again."""
    if np.isfinite(x[STATE.mprev]) and x[STATE.mag_dt] > 0.0:
        mdt = x[STATE.mag_dt]
        kl = 1.0 - math.exp(-mdt / p[PARAM.clip_learn_tau])
        c0, c1, c2 = 0.5 * (m0 + x[STATE.mprev]), 0.5 * (m1 + x[STATE.mprev + 1]), 0.5 * (m2 + x[STATE.mprev + 2])
        d0, d1, d2 = (m0 - x[STATE.mprev]) / mdt, (m1 - x[STATE.mprev + 1]) / mdt, (m2 - x[STATE.mprev + 2]) / mdt
        # the interval's mean rates; a clipped axis's from its estimate
        v0 = x[STATE.gsum] / mdt if x[STATE.gclip] == 0.0 else x[STATE.rate]
        v1 = x[STATE.gsum + 1] / mdt if x[STATE.gclip + 1] == 0.0 else x[STATE.rate + 1]
        v2 = x[STATE.gsum + 2] / mdt if x[STATE.gclip + 2] == 0.0 else x[STATE.rate + 2]
        nu, de = mag_rate_terms(c0, c1, c2, d1, d2, v1, v2)
        clip_rate_update(x, p, 0, nu, de, v0, mdt, kl)
        nu, de = mag_rate_terms(c1, c2, c0, d2, d0, v2, v0)
        clip_rate_update(x, p, 1, nu, de, v1, mdt, kl)
        nu, de = mag_rate_terms(c2, c0, c1, d0, d1, v0, v1)
        clip_rate_update(x, p, 2, nu, de, v2, mdt, kl)
    x[STATE.gsum], x[STATE.gsum + 1], x[STATE.gsum + 2] = 0.0, 0.0, 0.0
    x[STATE.gclip], x[STATE.gclip + 1], x[STATE.gclip + 2] = 0.0, 0.0, 0.0
    x[STATE.gflat], x[STATE.gflat + 1], x[STATE.gflat + 2] = 0.0, 0.0, 0.0
    x[STATE.mprev], x[STATE.mprev + 1], x[STATE.mprev + 2] = m0, m1, m2


@njit(cache=True, inline="always")
def hold_axis(x, i, g, dt):
    """A clipped axis's rate: the field's (eq R4b), never below the limit. What the limit adds
    beyond the field's rate is owed and paid back once that rate exceeds the limit, so the bound
    does not rectify the estimate's noise into a drift."""
    if x[STATE.clipped + i] != 0.0:
        a = abs(g)
        sg = 1.0 if g > 0.0 else -1.0
        r = sg * x[STATE.rate + i] + x[STATE.debt + i] / dt
        if r > a:
            x[STATE.hold + i] = sg * r
            x[STATE.debt + i] = 0.0
        else:
            x[STATE.hold + i] = g
            x[STATE.debt + i] = (r - a) * dt


@njit(cache=True, inline="always")
def hold_clipped(x, gyr, dt):
    """Each clipped axis's held rate (:func:`hold_axis`)."""
    hold_axis(x, 0, gyr[0], dt)
    hold_axis(x, 1, gyr[1], dt)
    hold_axis(x, 2, gyr[2], dt)
