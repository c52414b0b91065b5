"""The rotor-failure detector's sequential tests (docs/detection.md): the CUSUM sums on each
rotor's deficit that answer 'lost' and 'damaged' (Page 1954), and the fast test, a generalised
likelihood ratio of a loss at the start of each of the last few samples' windows."""

from __future__ import annotations

import numpy as np

from quadest._jit import njit
from quadest.detect.filter import holding
from quadest.detect.layout import GLR_MAX, GLR_ROW, MAX_ROTORS, MODEL, ROW, STATE
from quadest.detect.model import body_moments, drag_moments
from quadest.detect.params import PARAM


@njit(cache=True, inline="always")
def cusum_test(x, p, c, dt):
    """The two CUSUM tests on each rotor's deficit; the first alarm of each is kept."""
    n = int(c[MODEL.rotors])
    total = 0.0
    for i in range(n):
        total += x[STATE.eta + i]
    var_total = 0.0
    var_min = np.inf
    for i in range(n):
        var_total += x[STATE.P + (3 + i) * (3 + n) + 3 + i]
        var_min = min(var_min, x[STATE.P + (3 + i) * (3 + n) + 3 + i])
    sd_max = p[PARAM.deficit_sd_ratio] * np.sqrt(var_min)
    touching = holding(x, p)
    for i in range(n):
        if touching:  # forces the rotor model has not, or a thrust cut: no evidence either way
            x[STATE.s_lost + i] = 0.0
            x[STATE.s_damaged + i] = 0.0
            continue
        others = _others(x, i, n) if p[PARAM.weighted_others] != 0.0 else (total - x[STATE.eta + i]) / (n - 1)
        var_i = x[STATE.P + (3 + i) * (3 + n) + 3 + i]
        scale = max(others, 0.5) if p[PARAM.relative_deficit] != 0.0 else 1.0
        d = (others - x[STATE.eta + i]) / scale if np.sqrt(var_i) < sd_max else 0.0  # too uncertain: no evidence
        k = p[PARAM.deficit_sigmas]
        if k > 0.0 and d * d * scale * scale < k * k * _deficit_variance(x, i, n):  # within its noise
            d = 0.0
        left = x[STATE.eta + i] / others if others > 0.0 else 0.0
        sl = max(0.0, x[STATE.s_lost + i] + dt * (d - p[PARAM.lost_drift]))
        sd = max(0.0, x[STATE.s_damaged + i] + dt * (d - p[PARAM.damaged_drift]))
        x[STATE.s_lost + i], x[STATE.s_damaged + i] = sl, sd
        if x[STATE.lost] < 0.0 and sl > p[PARAM.lost_threshold]:
            x[STATE.lost], x[STATE.lost_t], x[STATE.lost_eta] = i, x[STATE.time], left
        if x[STATE.damaged] < 0.0 and sd > p[PARAM.damaged_threshold]:
            x[STATE.damaged], x[STATE.damaged_t], x[STATE.damaged_eta] = i, x[STATE.time], left


@njit(cache=True, inline="always")
def _others(x, i, n):
    """The other rotors' effectiveness, each weighted by how well it is known (``1/P_jj``): a
    rotor turning slowly, whose effectiveness wanders, does not set the reference."""
    num = 0.0
    den = 0.0
    for j in range(n):
        if j != i:
            w = 1.0 / x[STATE.P + (3 + j) * (3 + n) + 3 + j]
            num += w * x[STATE.eta + j]
            den += w
    return num / den


@njit(cache=True, inline="always")
def _deficit_variance(x, i, n):
    """The variance of rotor ``i``'s deficit ``d_i = aᵀη``, ``a_j = 1/(n−1)`` for the others and
    −1 for itself: ``aᵀ P a`` (the effectivenesses are correlated: their differences are known
    far better than each one)."""
    ns = 3 + n
    total = 0.0
    for j in range(n):
        aj = -1.0 if j == i else 1.0 / (n - 1)
        for k in range(n):
            ak = -1.0 if k == i else 1.0 / (n - 1)
            total += aj * ak * x[STATE.P + (3 + j) * ns + 3 + k]
    return total


@njit(cache=True, inline="always")
def glr_store(x, p, c, gyr, acc, dt):
    """This sample into the fast test's ring: what :func:`predict` made of it, per rotor, and η."""
    n = int(c[MODEL.rotors])
    row = STATE.glr + int(x[STATE.glr_head]) * GLR_ROW
    J = (c[MODEL.inertia], c[MODEL.inertia + 1], c[MODEL.inertia + 2])
    m = body_moments(c, gyr[0], gyr[1], gyr[2])
    d0, d1 = drag_moments(x, c)
    drag = (d0, d1, 0.0)
    for j in range(3):
        x[row + ROW.gyr + j] = gyr[j]
        x[row + ROW.base + j] = dt * ((m[j] - c[MODEL.damping + j] * gyr[j]) / J[j] + drag[j])
        for i in range(n):
            x[row + ROW.b + j * MAX_ROTORS + i] = x[STATE.B + j * MAX_ROTORS + i]
    for i in range(n):
        x[row + ROW.thrust + i] = x[STATE.thrust + i] / c[MODEL.mass]
        x[row + ROW.eta + i] = x[STATE.eta + i]
    x[row + ROW.acc_z] = acc[2] if np.isfinite(acc[2]) else np.nan
    x[STATE.glr_head] = (x[STATE.glr_head] + 1.0) % GLR_MAX
    x[STATE.glr_n] = min(x[STATE.glr_n] + 1.0, GLR_MAX)


@njit(cache=True, inline="always")
def glr_test(x, p, c, dt):
    """The fast test: for each window of the last 3 to ``glr_window_s`` of samples (each a time
    the loss may have begun), the gyroscope's change and the accelerometer's z against the model
    with every rotor at its effectiveness before the window; for each rotor the least-squares
    share ``μ`` of its contribution gone and twice the log-likelihood ratio ``(sᵀΣ⁻¹r)² / sᵀΣ⁻¹s``
    of that against none (Willsky & Jones 1976), the largest over windows and rotors."""
    n = int(c[MODEL.rotors])
    w_max = min(int(round(p[PARAM.glr_window_s] / dt)), GLR_MAX - 1, int(x[STATE.glr_n]) - 1)
    if w_max < 3 or x[STATE.lost] >= 0.0:
        return
    if holding(x, p):
        return
    head = int(x[STATE.glr_head])  # the slot of the next sample: the last is head − 1, wrapped
    last = STATE.glr + _ring(head - 1) * GLR_ROW
    R, S = STATE.glr_r, STATE.glr_sig  # sums over the window: see below
    for j in range(4):
        x[R + j] = 0.0  # the rate change without the rotors (3), the accelerometer's z (1)
    for k in range(4 * MAX_ROTORS):  # per unit η of each rotor: its rate change (3), its thrust per mass
        x[S + k] = 0.0  # (as the ring's rows: ``S + j·MAX_ROTORS + i``)
    count = 0
    rel = (p[PARAM.model_error], p[PARAM.model_error], p[PARAM.yaw_model_error])
    g2 = p[PARAM.gyro_noise] ** 2
    g = (2.0 * max(g2, x[STATE.gyr_var]), 2.0 * max(g2, x[STATE.gyr_var + 1]), 2.0 * max(g2, x[STATE.gyr_var + 2]))
    best, who, share = 0.0, -1, 0.0
    for w in range(1, w_max + 1):  # the window of the last w samples
        row = STATE.glr + _ring(head - w) * GLR_ROW
        first = STATE.glr + _ring(head - w - 1) * GLR_ROW  # the sample before it
        eta0 = first + ROW.eta
        for j in range(3):
            x[R + j] += x[row + ROW.base + j]
        for k in range(3 * MAX_ROTORS):  # every slot, the absent rotors' zeros too: a fixed-length loop
            x[S + k] += x[row + ROW.b + k]  # the compiler vectorises (docs/detection.md, the fast test's cost)
        a = x[row + ROW.acc_z]
        if np.isfinite(a):
            count += 1
            x[R + 3] += a
            for k in range(3 * MAX_ROTORS, 4 * MAX_ROTORS):
                x[S + k] += x[row + ROW.b + k]  # ROW.thrust
        if w < 3:
            continue
        stat, rotor, runner_up, mu = _glr_rotors(x, p, n, w, dt, count, last, first, eta0, rel, g)
        if stat > best and mu > p[PARAM.glr_min_loss] and stat > p[PARAM.glr_margin] * runner_up:
            best, who, share = stat, rotor, mu
    if who >= 0 and best > p[PARAM.glr_threshold]:
        x[STATE.lost], x[STATE.lost_t] = who, x[STATE.time]
        x[STATE.lost_eta] = max(0.0, 1.0 - share)


@njit(cache=True, inline="always")
def _ring(k):
    """The ring's slot of sample index ``k`` (``k`` ≥ −GLR_MAX)."""
    return k + GLR_MAX if k < 0 else k


@njit(cache=True, inline="always")
def _glr_rotors(x, p, n, w, dt, count, last, first, eta0, rel, g):
    """One window of the fast test (:func:`glr_test`'s sums; ``g`` twice the gyroscope's noise
    variance per axis): the largest ratio over the rotors, its rotor, the next rotor's ratio and
    the share ``μ`` of the best. A window whose residual ``rᵀΣ⁻¹r``, which bounds every rotor's
    ratio (Cauchy-Schwarz), stays below the threshold cannot fire: it returns no rotor, and the
    decision is the same."""
    R, S = STATE.glr_r, STATE.glr_sig
    # the rotors' rate change and thrust over the window at the effectiveness before it
    p0 = p1 = p2 = pred = 0.0
    for i in range(n):
        e = x[eta0 + i]
        p0 += x[S + i] * e
        p1 += x[S + MAX_ROTORS + i] * e
        p2 += x[S + 2 * MAX_ROTORS + i] * e
        pred += x[S + 3 * MAX_ROTORS + i] * e
    best, second, who, mu = 0.0, 0.0, -1, 0.0
    r0 = x[last + ROW.gyr] - x[first + ROW.gyr] - x[R] - p0
    r1 = x[last + ROW.gyr + 1] - x[first + ROW.gyr + 1] - x[R + 1] - p1
    r2 = x[last + ROW.gyr + 2] - x[first + ROW.gyr + 2] - x[R + 2] - p2
    m2 = (p[PARAM.moment_noise] * w * dt) ** 2
    i0 = 1.0 / (g[0] + m2 + (rel[0] * p0) ** 2)  # one over each residual's variance
    i1 = 1.0 / (g[1] + m2 + (rel[1] * p1) ** 2)
    i2 = 1.0 / (g[2] + m2 + (rel[2] * p2) ** 2)
    r3 = i3 = 0.0
    if count > 0:
        r3 = (x[R + 3] + pred) / count
        i3 = count / p[PARAM.acc_noise] ** 2
    bound = r0 * r0 * i0 + r1 * r1 * i1 + r2 * r2 * i2 + r3 * r3 * i3
    if bound < 0.99 * p[PARAM.glr_threshold]:
        return 0.0, -1, 0.0, 0.0
    per = 1.0 / max(count, 1)
    for i in range(n):
        e = x[eta0 + i]
        s0, s1, s2 = -x[S + i] * e, -x[S + MAX_ROTORS + i] * e, -x[S + 2 * MAX_ROTORS + i] * e
        s3 = x[S + 3 * MAX_ROTORS + i] * e * per
        a0, a1, a2, a3 = s0 * i0, s1 * i1, s2 * i2, s3 * i3
        num = a0 * r0 + a1 * r1 + a2 * r2 + a3 * r3
        den = a0 * s0 + a1 * s1 + a2 * s2 + a3 * s3
        if den <= 0.0 or num <= 0.0:
            continue
        llr = num * num / den
        if llr > best:
            best, second, who, mu = llr, best, i, num / den
        elif llr > second:
            second = llr
    return best, who, second, mu
