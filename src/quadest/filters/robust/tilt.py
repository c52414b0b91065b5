"""Tilt (docs/estimators.md, robust, items 1, 2, 7, 10, 11, 12): the strapdown in an
almost-inertial frame, the sample clock the low-passes run at (eq R9), the specific force
low-passed there (a 4th-order share optional, eq R1c; the initial averaging ended by eq R8), the
inclination correction (eq R1) and the bias it measures in motion (eqs R3-R3d), the lever arm,
and the tilt's reported variance (eq R6)."""

from __future__ import annotations

import math

from quadest._jit import njit
from quadest.filters.robust.bias import bias_update
from quadest.filters.robust.params import COEF, PARAM, STATE
from quadest.rotation.kernels import normalize_s, qmul_s, rot_entries, rotate_s

CLOCK_SAMPLES = 1000.0
"""Samples over which the sample clock's interval is averaged (before that many, all of them)."""
CLOCK_RUN_S = 0.05
"""A run of intervals all over 1.5 or all under 1/1.5 clock intervals lasting this long (s; and
:data:`CLOCK_RUN_N` intervals) is a new rate: the clock starts again from the run's mean."""
CLOCK_RUN_N = 20.0


@njit(cache=True, inline="always")
def sample_clock(x, dt):
    """The interval the low-passes run at (item 12, eq R9). An IMU samples on its own clock;
    timestamps a host gave on arrival jitter around it (DIDO: 0.2-9.9 ms around 2.5 ms) or come
    in bursts (a FIFO read at once), and a biquad whose coefficients follow them sample by sample
    is not a low-pass. So: the running mean of all intervals (``1/n``, then exponential over
    :data:`CLOCK_SAMPLES`; a lost sample's long interval is in it, a few per cent at most); a new
    rate, a run of intervals on one side of it (:data:`CLOCK_RUN_S`), starts it again; an
    interval within 1 ppm of the mean is taken as it is (regular recordings run as before)."""
    c = STATE.clock
    n, m, run, rsum = x[c] + 1.0, x[c + 1], x[c + 2], x[c + 3]
    if n == 1.0:
        m = dt
    else:
        side = 1.0 if dt > 1.5 * m else (-1.0 if 1.5 * dt < m else 0.0)
        run, rsum = (run + side, rsum + dt) if side != 0.0 and side * run >= 0.0 else (side, dt * abs(side))
        if abs(run) >= CLOCK_RUN_N and rsum >= CLOCK_RUN_S:
            n, m, run, rsum = abs(run), rsum / abs(run), 0.0, 0.0
        else:
            m += (dt - m) / min(n, CLOCK_SAMPLES)
    x[c], x[c + 1], x[c + 2], x[c + 3] = n, m, run, rsum
    return dt if abs(dt - m) <= 1e-6 * m else m


@njit(cache=True, inline="always")
def step_coefficients(x, p, dt):
    """Cache the Δt-dependent coefficients (recomputed only when Δt changes by over 0.1 %)."""
    if abs(dt - x[STATE.coef_dt]) <= 1e-3 * dt:
        return
    x[STATE.coef_dt] = dt
    fc = math.sqrt(2.0) / (2.0 * math.pi * p[PARAM.tau_acc])  # the cut-off VQF uses for its τ_acc
    K = math.tan(math.pi * min(fc * dt, 0.49))  # bilinear transform, prewarped
    nrm = 1.0 / (1.0 + math.sqrt(2.0) * K + K * K)
    x[STATE.coef] = K * K * nrm  # b0 (b1 = 2 b0, b2 = b0)
    x[STATE.coef + 1] = 2.0 * (K * K - 1.0) * nrm  # a1
    x[STATE.coef + 2] = (1.0 - math.sqrt(2.0) * K + K * K) * nrm  # a2
    x[STATE.coef + 3] = 1.0 - math.exp(-dt / p[PARAM.tau_acc])  # first-order equivalent gain
    x[STATE.coef + 4] = 1.0 - math.exp(-dt / p[PARAM.rest_tau])
    x[STATE.coef + 5] = 1.0 - math.exp(-dt / p[PARAM.mag_lp_tau])
    x[STATE.coef + 6] = 1.0 - math.exp(-dt / p[PARAM.init_tau])


@njit(cache=True, inline="always")
def biquad(x, i, v, b0, a1, a2):
    """One sample of the Butterworth low-pass (transposed direct form II, ``b = b0 [1, 2, 1]``),
    state ``x[i], x[i + 1]``."""
    y = b0 * v + x[i]
    x[i] = 2.0 * b0 * v - a1 * y + x[i + 1]
    x[i + 1] = b0 * v - a2 * y
    return y


@njit(cache=True, inline="always")
def lowpass(x, i, v, b0, a1, a2, share):
    """The force's low-pass (eq R1c): a Butterworth section, and unless ``share`` < 0 that output
    plus ``share`` of what a second section in series changes; state ``x[i]`` to ``x[i + 4]``
    (two per section)."""
    y = biquad(x, i, v, b0, a1, a2)
    if share >= 0.0:
        y += share * (biquad(x, i + 2, y, b0, a1, a2) - y)
    return y


@njit(cache=True, inline="always")
def steady_lowpass(x, i, v, b0, a2):
    """The low-pass's state in steady state at ``v`` (every section)."""
    x[i], x[i + 1] = v - b0 * v, b0 * v - a2 * v
    x[i + 2], x[i + 3] = v - b0 * v, b0 * v - a2 * v


@njit(cache=True, inline="always")
def lever_arm(p, c, acc, w0, w1, w2):
    """Item 7: the specific force at the centre of gravity, ``f − ω × (ω × r)``."""
    f0, f1, f2 = acc[0], acc[1], acc[2]
    if c[COEF.has_lever]:
        r0, r1, r2 = p[PARAM.lever_x], p[PARAM.lever_y], p[PARAM.lever_z]
        c0, c1, c2 = w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0  # ω × r
        f0 -= w1 * c2 - w2 * c1
        f1 -= w2 * c0 - w0 * c2
        f2 -= w0 * c1 - w1 * c0
    return f0, f1, f2


@njit(cache=True, inline="always")
def strapdown(x, w0, w1, w2, dt):
    """Item 1: ``q_Ib ← q_Ib ⊗ Exp((ω − b) Δt)``; returns the rate with the bias removed (a
    clipped axis's rate is the true rate, from the field, or a bound: no bias is removed from it)."""
    u0 = w0 - (x[STATE.bias] if x[STATE.clipped] == 0.0 else 0.0)
    u1 = w1 - (x[STATE.bias + 1] if x[STATE.clipped + 1] == 0.0 else 0.0)
    u2 = w2 - (x[STATE.bias + 2] if x[STATE.clipped + 2] == 0.0 else 0.0)
    th = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2) * dt
    if th > 0.0:
        s = math.sin(0.5 * th) / th * dt
        gw, gx, gy, gz = x[STATE.qg], x[STATE.qg + 1], x[STATE.qg + 2], x[STATE.qg + 3]
        a0_, a1_, a2_, a3_ = qmul_s(gw, gx, gy, gz, math.cos(0.5 * th), u0 * s, u1 * s, u2 * s)
        x[STATE.qg], x[STATE.qg + 1], x[STATE.qg + 2], x[STATE.qg + 3] = normalize_s(a0_, a1_, a2_, a3_)
    return u0, u1, u2


@njit(cache=True, inline="always")
def end_of_averaging(x, p, gyr, fI0, fI1, fI2, y0, y1, y2, n, rest_rate2):
    """Eq R8: the initial averaging assumes no sustained acceleration. For a start that was still,
    the specific force's mean over the last ``init_tau`` leaving the mean so far by more than
    ``init_acc`` and than its noise allows (χ²(3) at 99.9 %: 16.3 times the variance of the
    difference) ends it, and the low-pass starts from the mean as it was before the
    acceleration. Returns the mean to go on from."""
    if n == 1.0 and gyr[0] ** 2 + gyr[1] ** 2 + gyr[2] ** 2 > rest_rate2:
        x[STATE.moved] = -1.0  # started turning: no still reference, the whole averaging
    if x[STATE.moved] == 0.0:
        k_init = x[STATE.coef + 6]
        ks = max(k_init, 1.0 / n)
        x[STATE.ys] += ks * (fI0 - x[STATE.ys])
        x[STATE.ys + 1] += ks * (fI1 - x[STATE.ys + 1])
        x[STATE.ys + 2] += ks * (fI2 - x[STATE.ys + 2])
        if n > 1.0:  # successive differences: var(f_k - f_k-1) = 2 σ²
            e0, e1, e2 = fI0 - x[STATE.fprev], fI1 - x[STATE.fprev + 1], fI2 - x[STATE.fprev + 2]
            x[STATE.fvar] += (0.5 * (e0 * e0 + e1 * e1 + e2 * e2) - x[STATE.fvar]) / (n - 1.0)
        x[STATE.fprev], x[STATE.fprev + 1], x[STATE.fprev + 2] = fI0, fI1, fI2
        # against the mean as it was when the recent force last agreed with it (within half the
        # threshold): a slow onset, which the mean would follow, still shows in full
        dy0, dy1, dy2 = (
            x[STATE.ys] - x[STATE.yok],
            x[STATE.ys + 1] - x[STATE.yok + 1],
            x[STATE.ys + 2] - x[STATE.yok + 2],
        )
        dev2 = dy0 * dy0 + dy1 * dy1 + dy2 * dy2
        thr2 = max(p[PARAM.init_acc] * p[PARAM.init_acc], 16.3 * x[STATE.fvar] * (ks / (2.0 - ks) + 1.0 / n))
        if n == 1.0 or dev2 <= 0.25 * thr2:
            x[STATE.yok], x[STATE.yok + 1], x[STATE.yok + 2] = y0, y1, y2
        elif dev2 > thr2:
            x[STATE.moved] = 1.0  # the low-pass starts from the mean before the acceleration
            y0, y1, y2 = x[STATE.yok], x[STATE.yok + 1], x[STATE.yok + 2]
    return y0, y1, y2


@njit(cache=True, inline="always")
def filtered_force(x, p, gyr, fI0, fI1, fI2, rest_rate2, share, dt):
    """Item 2: the specific force in I low-passed (2nd-order Butterworth); for the first τ_acc a
    running mean (converges at once, no initial transient) until eq R8 ends it. Returns the
    filtered force, the equivalent first-order gain and the averaging's count (−1 once over)."""
    b0, a1, a2, k_acc = x[STATE.coef], x[STATE.coef + 1], x[STATE.coef + 2], x[STATE.coef + 3]
    n = x[STATE.mean_n]
    if n >= 0.0:
        n += 1.0
        y0 = x[STATE.lpy] + (fI0 - x[STATE.lpy]) / n
        y1 = x[STATE.lpy + 1] + (fI1 - x[STATE.lpy + 1]) / n
        y2 = x[STATE.lpy + 2] + (fI2 - x[STATE.lpy + 2]) / n
        kk = max(k_acc, 1.0 / n)
        y0, y1, y2 = end_of_averaging(x, p, gyr, fI0, fI1, fI2, y0, y1, y2, n, rest_rate2)
        if n * dt >= p[PARAM.tau_acc] or x[STATE.moved] > 0.0:
            n = -1.0
            # the low-pass starts in steady state at the mean
            steady_lowpass(x, STATE.lp, y0, b0, a2)
            steady_lowpass(x, STATE.lp + 4, y1, b0, a2)
            steady_lowpass(x, STATE.lp + 8, y2, b0, a2)
        x[STATE.mean_n] = n
    else:
        kk = k_acc
        y0 = lowpass(x, STATE.lp, fI0, b0, a1, a2, share)
        y1 = lowpass(x, STATE.lp + 4, fI1, b0, a1, a2, share)
        y2 = lowpass(x, STATE.lp + 8, fI2, b0, a1, a2, share)
    x[STATE.lpy], x[STATE.lpy + 1], x[STATE.lpy + 2] = y0, y1, y2
    return y0, y1, y2, kk, n


@njit(cache=True, inline="always")
def fourth_order_share(x, p, u0, u1, u2):
    """Eq R1c: the 4th-order low-pass's share, ``1 / (1 + (lp‖ω‖ / lp_rate)²)``, ``lp`` first order
    over τ_acc (a rotation's scale-factor drift lags by the filter's delay, and the 4th order's is
    twice the 2nd's); −1 with ``lp_rate`` 0 (the 2nd order alone)."""
    if p[PARAM.lp_rate] <= 0.0:
        return -1.0
    wn = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    x[STATE.wlp] += x[STATE.coef + 3] * (wn - x[STATE.wlp])
    r = x[STATE.wlp] / p[PARAM.lp_rate]
    return 1.0 / (1.0 + r * r)


@njit(cache=True, inline="always")
def correct_inclination(x, y0, y1, y2):
    """Eq R1: ``q_EI ← q_c ⊗ q_EI``, the shortest rotation taking the filtered down direction
    onto ``e_z``. Returns ``q_c``'s (w, x, y) and whether there was a direction to correct to."""
    iw, ix, iy, iz = x[STATE.qi], x[STATE.qi + 1], x[STATE.qi + 2], x[STATE.qi + 3]
    v0, v1, v2 = rotate_s(iw, ix, iy, iz, -y0, -y1, -y2)  # down, as estimated, in E
    vn = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if not vn > 0.0:
        return 1.0, 0.0, 0.0, False
    v0, v1, v2 = v0 / vn, v1 / vn, v2 / vn
    cw = math.sqrt(max(0.0, 0.5 * (1.0 + v2)))
    if cw > 1e-6:
        cx, cy = 0.5 * v1 / cw, -0.5 * v0 / cw
    else:
        cx, cy = 1.0, 0.0
    a0_, a1_, a2_, a3_ = qmul_s(cw, cx, cy, 0.0, iw, ix, iy, iz)
    x[STATE.qi], x[STATE.qi + 1], x[STATE.qi + 2], x[STATE.qi + 3] = normalize_s(a0_, a1_, a2_, a3_)
    return cw, cx, cy, True


@njit(cache=True, inline="always")
def lowpass_or_hold(x, i, v, hold, share):
    """The force's low-pass (state from ``x[i]``, eq R1c) of ``v``; with ``hold`` (the force still
    averaged) its state set steady at ``v``, and ``v`` returned."""
    b0, a1, a2 = x[STATE.coef], x[STATE.coef + 1], x[STATE.coef + 2]
    if hold:
        steady_lowpass(x, i, v, b0, a2)
        return v
    return lowpass(x, i, v, b0, a1, a2, share)


@njit(cache=True, inline="always")
def filtered_rows(x, ew, ex, ey, ez, hold, share):
    """Eq R3d: the rows of ``R(q_Eb)`` (north, east, down) into ``hrow``, and ``R(q_Eb) b``
    (north, east), low-passed as the force is; returns the latter."""
    rows = rot_entries(ew, ex, ey, ez)
    b0_, b1_, b2_ = x[STATE.bias], x[STATE.bias + 1], x[STATE.bias + 2]
    for r in range(3):
        for j in range(3):
            k = 3 * r + j
            x[STATE.hrow + k] = lowpass_or_hold(x, STATE.hlp + 4 * k, rows[r][j], hold, share)
    hb_n = rows[0][0] * b0_ + rows[0][1] * b1_ + rows[0][2] * b2_
    hb_e = rows[1][0] * b0_ + rows[1][1] * b1_ + rows[1][2] * b2_
    return (
        lowpass_or_hold(x, STATE.hblp, hb_n, hold, share),
        lowpass_or_hold(x, STATE.hblp + 4, hb_e, hold, share),
    )


@njit(cache=True, inline="always")
def motion_bias(x, p, q_c, q_eb, lp_hb, rate2, clip_b, dt):
    """Eq R3: the correction's rate ``q_c`` measures the horizontal drift of a bias error, while
    the scale-factor error at the rate (``rate2`` its square) is below the bias it resolves (eq
    R3c). Rows: ``R(q_Eb)``'s of the moment, or (``bias_rows_lp``, eq R3d) low-passed as the
    force, the innovation then ``−y + lp(H b) − lp(H) b`` (``lp_hb``)."""
    if p[PARAM.scale_max] ** 2 * rate2 > p[PARAM.bias_motion_std] ** 2:
        return
    cw, cx, cy = q_c
    sn = math.sqrt(cx * cx + cy * cy)
    ang = 2.0 * math.atan2(sn, cw)
    sc = ang / sn / dt if sn > 1e-12 else 2.0 / dt
    in_n, in_e = -cx * sc, -cy * sc  # minus the E-frame rate of the correction, north and east
    r = p[PARAM.bias_motion_std] * p[PARAM.bias_motion_std] * p[PARAM.tau_acc] / dt
    gmax = p[PARAM.bias_gain] * dt / p[PARAM.tau_acc]
    if p[PARAM.bias_rows_lp] != 0.0:
        H = STATE.hrow
        h00, h01, h02 = x[H], x[H + 1], x[H + 2]
        h10, h11, h12 = x[H + 3], x[H + 4], x[H + 5]
        b0_, b1_, b2_ = x[STATE.bias], x[STATE.bias + 1], x[STATE.bias + 2]
        in_n += lp_hb[0] - (h00 * b0_ + h01 * b1_ + h02 * b2_)
        in_e += lp_hb[1] - (h10 * b0_ + h11 * b1_ + h12 * b2_)
    else:
        rows = rot_entries(q_eb[0], q_eb[1], q_eb[2], q_eb[3])
        h00, h01, h02 = rows[0]
        h10, h11, h12 = rows[1]
    bias_update(x, h00, h01, h02, in_n, r, clip_b, gmax)
    bias_update(x, h10, h11, h12, in_e, r, clip_b, gmax)


@njit(cache=True, inline="always")
def tilt(x, p, c, gyr, f, fn, u, at_rest, nclip, rest_rate2, clip_b, dt):
    """Items 2, 4 and 10: the inclination from the low-passed specific force ``f`` (its norm
    ``fn``), the bias in motion, and the tilt's variance (eq R6: ``P_θ ← (1 − k)² (P_θ + (σ_g² +
    τ_acc tr(P_b)/3) Δt) + k² R_a (1 + 2 τ_c / Δt)``, ``R_a`` the low-passed squared angle between
    the raw specific force and the vertical); ``u`` the strapdown's rate."""
    f0, f1, f2 = f
    u0, u1, u2 = u
    gw, gx, gy, gz = x[STATE.qg], x[STATE.qg + 1], x[STATE.qg + 2], x[STATE.qg + 3]
    iw, ix, iy, iz = x[STATE.qi], x[STATE.qi + 1], x[STATE.qi + 2], x[STATE.qi + 3]
    ew, ex, ey, ez = qmul_s(iw, ix, iy, iz, gw, gx, gy, gz)  # q_Eb
    pt = x[STATE.Pt]
    sb2 = (x[STATE.Pb] + x[STATE.Pb + 4] + x[STATE.Pb + 8]) / 3.0
    pt += (c[COEF.sg2] + p[PARAM.tau_acc] * sb2) * dt
    if fn > 0.0:
        fI0, fI1, fI2 = rotate_s(gw, gx, gy, gz, f0, f1, f2)
        share = fourth_order_share(x, p, u0, u1, u2)
        y0, y1, y2, kk, n = filtered_force(x, p, gyr, fI0, fI1, fI2, rest_rate2, share, dt)
        lp_hb = filtered_rows(x, ew, ex, ey, ez, n >= 0.0, share)
        cw, cx, cy, corrected = correct_inclination(x, y0, y1, y2)
        if corrected and not at_rest and nclip == 0 and n < 0.0:
            rate2 = u0 * u0 + u1 * u1 + u2 * u2
            motion_bias(x, p, (cw, cx, cy), (ew, ex, ey, ez), lp_hb, rate2, clip_b, dt)
        # accelerometer direction noise (adaptive)
        fe2 = rotate_s(ew, ex, ey, ez, f0, f1, f2)[2]
        cosang = min(1.0, max(-1.0, -fe2 / fn))
        ang2 = math.acos(cosang) ** 2
        k_rest = x[STATE.coef + 4]
        x[STATE.Ra] += k_rest * (ang2 - x[STATE.Ra]) if x[STATE.Ra] > 0.0 else ang2
        pt = (1.0 - kk) ** 2 * pt + kk * kk * x[STATE.Ra] * (1.0 + 2.0 * p[PARAM.acc_corr_s] / dt)
    x[STATE.Pt] = pt
