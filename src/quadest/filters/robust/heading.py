"""Heading (docs/estimators.md, robust, items 3, 5, 8, 9, 10): a separate offset δ about down,
``q_nb = Rz(δ) ⊗ q_EI ⊗ q_Ib``, corrected by the magnetometer (eq R2) with a time constant that
shortens in a sustained spin (eq R7) and while a vertical axis clips; the field's disturbance
detected and rejected; the magnetometer's latency rotated out (eq R5); the vertical bias from
the heading correction's rate; the heading's reported variance (eq R6)."""

from __future__ import annotations

import math

from quadest._jit import njit
from quadest.filters.common import wrap_angle
from quadest.filters.robust.bias import bias_update
from quadest.filters.robust.params import COEF, PARAM, STATE, UNKNOWN_HEADING_VAR
from quadest.rotation.kernels import qmul_s, rotate_s


@njit(cache=True, inline="always")
def latency_corrected(p, mag, w0, w1, w2):
    """Eq R5: a sample ``τ_m`` old rotated forward by the gyro, ``m ← Exp(−ω τ_m) m``."""
    m0, m1, m2 = mag[0], mag[1], mag[2]
    if p[PARAM.mag_latency_s] > 0.0:
        t = p[PARAM.mag_latency_s]
        qw, qx, qy, qz = 1.0, 0.0, 0.0, 0.0
        th = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) * t
        if th > 0.0:
            s = math.sin(0.5 * th) / (th / t)
            qw, qx, qy, qz = math.cos(0.5 * th), -w0 * s, -w1 * s, -w2 * s
        m0, m1, m2 = rotate_s(qw, qx, qy, qz, m0, m1, m2)
    return m0, m1, m2


@njit(cache=True, inline="always")
def heading_time_constant(x, p, h20, h21, h22, spin, nclip):
    """Eq R7: ``τ_ψ / (1 + max(0, |lp(ω_D)| − spin_min) / spin_rate)``, and while an axis clips at
    most ``clip_heading_tau`` over the clipped axes' squared share about down (a spin's vertical
    axis fully, a stick's horizontal one not at all: there it is the tilt that errs, and the
    field's heading with it)."""
    tau = p[PARAM.tau_mag] / (1.0 + max(0.0, spin - p[PARAM.spin_min]) / p[PARAM.spin_rate])
    s0, s1, s2 = h20 * h20 * x[STATE.clipped], h21 * h21 * x[STATE.clipped + 1], h22 * h22 * x[STATE.clipped + 2]
    if nclip:
        share = s0 + s1 + s2
        if share > 0.0:
            tau = min(tau, p[PARAM.clip_heading_tau] / min(1.0, share))
    return tau


@njit(cache=True, inline="always")
def heading_drift_variance(x, p, h20, h21, h22, spin, nclip):
    """Eq R6: the heading's drift rate has the variance of the vertical bias (``h P_b hᵀ``), of
    the scale-factor error times the spin, and of the clipped axes' rates from the field (eq
    R4f, their covariance) seen about down."""
    pbv = (
        h20 * (x[STATE.Pb] * h20 + x[STATE.Pb + 1] * h21 + x[STATE.Pb + 2] * h22)
        + h21 * (x[STATE.Pb + 3] * h20 + x[STATE.Pb + 4] * h21 + x[STATE.Pb + 5] * h22)
        + h22 * (x[STATE.Pb + 6] * h20 + x[STATE.Pb + 7] * h21 + x[STATE.Pb + 8] * h22)
    )
    drift2 = pbv + (p[PARAM.scale_max] * spin) ** 2
    if nclip:
        g0, g1, g2 = h20 * x[STATE.clipped], h21 * x[STATE.clipped + 1], h22 * x[STATE.clipped + 2]
        drift2 += (
            g0 * (x[STATE.Pc] * g0 + x[STATE.Pc + 1] * g1 + x[STATE.Pc + 2] * g2)
            + g1 * (x[STATE.Pc + 6] * g0 + x[STATE.Pc + 7] * g1 + x[STATE.Pc + 8] * g2)
            + g2 * (x[STATE.Pc + 12] * g0 + x[STATE.Pc + 13] * g1 + x[STATE.Pc + 14] * g2)
        )
    return drift2


@njit(cache=True, inline="always")
def disturbance_gain(x, p, mn, dip, mdt):
    """Item 5: the field's norm and dip, low-passed, against a reference learnt while undisturbed;
    a new field that stays consistent for ``mag_new_time`` (``mag_new_first`` the first time)
    becomes the reference. Returns the factor of the heading's gain: 1 undisturbed, 0 while a
    disturbance is rejected, ``1 / mag_reject_factor`` once rejected for ``mag_max_reject``."""
    if x[STATE.ref] == 0.0:
        x[STATE.ref], x[STATE.ref + 1] = mn, dip
        x[STATE.cur], x[STATE.cur + 1] = mn, dip
        x[STATE.cand], x[STATE.cand + 1] = mn, dip
        x[STATE.undist_t] = p[PARAM.mag_min_undist]
    km = 1.0 - math.exp(-mdt / p[PARAM.mag_lp_tau])
    x[STATE.cur] += km * (mn - x[STATE.cur])
    x[STATE.cur + 1] += km * (dip - x[STATE.cur + 1])
    cn, cd = x[STATE.cur], x[STATE.cur + 1]
    ok = (
        abs(cn - x[STATE.ref]) <= p[PARAM.mag_norm_th] * x[STATE.ref]
        and abs(cd - x[STATE.ref + 1]) <= p[PARAM.mag_dip_th]
    )
    if ok:
        x[STATE.undist_t] += mdt
        if x[STATE.undist_t] >= p[PARAM.mag_min_undist]:
            x[STATE.disturbed] = 0.0
            kr = 1.0 - math.exp(-mdt / p[PARAM.mag_ref_tau])
            x[STATE.ref] += kr * (cn - x[STATE.ref])
            x[STATE.ref + 1] += kr * (cd - x[STATE.ref + 1])
            x[STATE.reject_t] = max(0.0, x[STATE.reject_t] - p[PARAM.mag_reject_factor] * mdt)
            x[STATE.ref_conf] = 1.0 if x[STATE.undist_t] >= p[PARAM.mag_new_first] else x[STATE.ref_conf]
        x[STATE.cand], x[STATE.cand + 1], x[STATE.cand_t] = cn, cd, 0.0
    else:
        x[STATE.undist_t] = 0.0
        x[STATE.disturbed] = 1.0
        x[STATE.reject_t] += mdt
        if (
            abs(cn - x[STATE.cand]) <= p[PARAM.mag_norm_th] * x[STATE.cand]
            and abs(cd - x[STATE.cand + 1]) <= p[PARAM.mag_dip_th]
        ):
            x[STATE.cand_t] += mdt
            kc = 1.0 - math.exp(-mdt / p[PARAM.mag_lp_tau]) if x[STATE.cand_t] < 1.0 else mdt / x[STATE.cand_t]
            x[STATE.cand] += kc * (cn - x[STATE.cand])
            x[STATE.cand + 1] += kc * (cd - x[STATE.cand + 1])
        else:
            x[STATE.cand], x[STATE.cand + 1], x[STATE.cand_t] = cn, cd, 0.0
        need = p[PARAM.mag_new_time] if x[STATE.ref_conf] != 0.0 else p[PARAM.mag_new_first]
        if x[STATE.cand_t] >= need:
            x[STATE.ref], x[STATE.ref + 1] = x[STATE.cand], x[STATE.cand + 1]
            x[STATE.disturbed], x[STATE.reject_t], x[STATE.ref_conf] = 0.0, 0.0, 1.0
            x[STATE.undist_t] = p[PARAM.mag_min_undist]
    gain_div = 1.0
    if x[STATE.disturbed] != 0.0:
        gain_div = 0.0 if x[STATE.reject_t] <= p[PARAM.mag_max_reject] else 1.0 / p[PARAM.mag_reject_factor]
    return gain_div


@njit(cache=True, inline="always")
def heading_from_field(x, p, q_e, m, h2, tau, delta, ph, at_rest, nclip, clip_b):
    """Eq R2 with the magnetometer sample ``m`` and the inclination ``q_e`` (``h2``: the body's
    down axis): ``δ ← δ + k wrap(δ_m − δ)``, ``k = 1 − exp(−Δt_m / τ)`` (at least ``1 / n``
    during the initial averaging), scaled by the disturbance's factor; in steady state the
    correction's rate measures the vertical bias (gain at most ``bias_heading_gain · k``,
    eq R3b). Returns δ, its variance and whether it was updated."""
    ew, ex, ey, ez = q_e
    m0, m1, m2 = m
    h20, h21, h22 = h2
    mdt = x[STATE.mag_dt]
    x[STATE.mag_dt] = 0.0
    me0, me1, me2 = rotate_s(ew, ex, ey, ez, m0, m1, m2)
    mn = math.sqrt(me0 * me0 + me1 * me1 + me2 * me2)
    mh = math.sqrt(me0 * me0 + me1 * me1)
    if not mn > 0.0:
        return delta, ph, 0.0
    dip = math.atan2(me2, mh)
    gain_div = disturbance_gain(x, p, mn, dip, mdt)
    if not (gain_div > 0.0 and mh > 0.0):
        return delta, ph, 0.0
    dm = -math.atan2(me1, me0)  # eq R2
    x[STATE.mag_n] += 1.0
    k = 1.0 - math.exp(-mdt / tau)
    if x[STATE.moved] <= 0.0 or x[STATE.mag_n] == 1.0:
        k = max(k, 1.0 / x[STATE.mag_n])
    k *= gain_div
    e = wrap_angle(dm - delta)
    if x[STATE.mag_n] == 1.0:
        ph = x[STATE.Rm] = 0.25  # first sample: the heading from one noisy field (0.5 rad chosen)
    else:
        x[STATE.Rm] += x[STATE.coef + 5] * (e * e - x[STATE.Rm])
        ph = (1.0 - k) ** 2 * ph + k * k * x[STATE.Rm]
    delta = wrap_angle(delta + k * e)
    # the heading correction's rate measures the vertical drift of a bias error, in steady state
    # only (not during the initial averaging, k = 1/n)
    steady = x[STATE.mag_n] * k > 1.0 or x[STATE.moved] > 0.0
    if p[PARAM.bias_from_heading] != 0.0 and steady and nclip == 0 and not at_rest and x[STATE.disturbed] == 0.0:
        r = p[PARAM.bias_heading_std] * p[PARAM.bias_heading_std] * tau / mdt
        bias_update(x, h20, h21, h22, -(k * e) / mdt, r, clip_b, p[PARAM.bias_heading_gain] * k)
    return delta, ph, 1.0


@njit(cache=True, inline="always")
def heading(x, p, c, m, have_mag, u, at_rest, nclip, clip_b, dt):
    """The heading's time constant and variance, its correction by the field, and the attitude
    ``q_nb = Rz(δ) ⊗ q_EI ⊗ q_Ib`` it completes (into ``x[0:4]``). Returns 1.0 if the field
    corrected the heading."""
    (m0, m1, m2), (u0, u1, u2) = m, u  # the field read, the strapdown's rotation
    iw, ix, iy, iz = x[STATE.qi], x[STATE.qi + 1], x[STATE.qi + 2], x[STATE.qi + 3]
    gw, gx, gy, gz = x[STATE.qg], x[STATE.qg + 1], x[STATE.qg + 2], x[STATE.qg + 3]
    ew, ex, ey, ez = qmul_s(iw, ix, iy, iz, gw, gx, gy, gz)
    h20, h21, h22 = 2 * (ex * ez - ew * ey), 2 * (ey * ez + ew * ex), 1 - 2 * (ex * ex + ey * ey)
    wd = h20 * u0 + h21 * u1 + h22 * u2  # rate about down
    x[STATE.spin] += (1.0 - math.exp(-dt / p[PARAM.spin_tau])) * (wd - x[STATE.spin])
    spin = abs(x[STATE.spin])
    tau = heading_time_constant(x, p, h20, h21, h22, spin, nclip)
    ph = x[STATE.Ph]
    if x[STATE.ref] > 0.0 or have_mag:
        ph += (c[COEF.sg2] + tau * heading_drift_variance(x, p, h20, h21, h22, spin, nclip)) * dt
    delta = x[STATE.delta]
    mupd = 0.0
    if have_mag:
        delta, ph, mupd = heading_from_field(
            x, p, (ew, ex, ey, ez), (m0, m1, m2), (h20, h21, h22), tau, delta, ph, at_rest, nclip, clip_b
        )
    if x[STATE.ref] == 0.0:
        ph = UNKNOWN_HEADING_VAR
    x[STATE.Ph] = min(ph, UNKNOWN_HEADING_VAR)
    x[STATE.delta] = delta
    cz, sz = math.cos(0.5 * delta), math.sin(0.5 * delta)
    x[0], x[1], x[2], x[3] = qmul_s(cz, 0.0, 0.0, sz, ew, ex, ey, ez)
    return mupd
