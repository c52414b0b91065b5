"""The rotor-failure detector's Kalman filter (docs/detection.md): the body rate and each
rotor's effectiveness predicted through the detector's model, corrected by the gyroscope and the
accelerometer one scalar at a time, and the rotors' moment per axis learnt in flight."""

from __future__ import annotations

import numpy as np

from quadest._jit import njit
from quadest.conventions import GRAVITY
from quadest.detect.layout import H_TAU, MAX_ROTORS, MODEL, NS, SCALE_HP, SCALE_LP, SCALE_RANGE, SCALE_RATE, STATE
from quadest.detect.model import air_drag_per_speed, at_centre_of_mass, body_moments, drag_moments, rotor_thrust_yaw
from quadest.detect.params import PARAM


@njit(cache=True, inline="always")
def start_filter(x, p, c, gyr, rotors):
    """The first sample: the rate from the gyroscope, every rotor intact, the speeds read."""
    n = int(c[MODEL.rotors])
    ns = 3 + n
    for i in range(NS * NS):
        x[STATE.P + i] = 0.0
    for j in range(3):
        x[STATE.w + j] = gyr[j]
        x[STATE.P + j * ns + j] = p[PARAM.gyro_noise] ** 2
    for i in range(n):
        x[STATE.eta + i] = 1.0
        x[STATE.P + (3 + i) * ns + 3 + i] = 0.01  # intact within ±10 % at the start
        x[STATE.omega + i] = x[STATE.omega_end + i] = rotors[i]
        x[STATE.h_lp + i] = c[MODEL.ip_s + i] * rotors[i]
        x[STATE.s_lost + i] = 0.0
        x[STATE.s_damaged + i] = 0.0
        x[STATE.speed_low + i] = rotors[i]  # the speed test's floor starts at the reading
        x[STATE.s_speed + i] = 0.0
    x[STATE.lost] = x[STATE.damaged] = -1.0
    x[STATE.contact_t] = -np.inf
    for j in range(3):
        x[STATE.scale + j] = 1.0


@njit(cache=True, inline="always")
def predict(x, p, c, gyr, dt):
    """``ω`` over the interval with the mean squared speed over it (``STATE.omega`` holds
    ``√(½(Ω²_begin + Ω²_end))``); ``P ← F P Fᵀ + Q``."""
    n = int(c[MODEL.rotors])
    B, FP = STATE.B, STATE.FP  # offsets into x
    w0, w1, w2 = gyr[0], gyr[1], gyr[2]  # the measured rate for the gyroscopic and drag terms
    J0, J1, J2 = c[MODEL.inertia], c[MODEL.inertia + 1], c[MODEL.inertia + 2]
    m0, m1, m2 = body_moments(c, w0, w1, w2)
    fx, fy, spread = air_drag_per_speed(x, p, c, n)
    # B[j, i]: the rate change over dt per unit effectiveness of rotor i
    for i in range(n):
        om = x[STATE.omega + i]
        gx, gy = c[MODEL.g + 3 * i], c[MODEL.g + 3 * i + 1]  # gx = −r_y, gy = r_x
        thrust, yaw = rotor_thrust_yaw(c, i, om, w0, w1, w2)
        x[STATE.thrust + i] = thrust
        yaw += spread * om * (gx * fx + gy * fy)
        # the rotor's inertia: its gyroscopic moment −ω × (I_p s_i Ω_i e_z) and the reaction to its
        # acceleration, from its speed low-passed over H_TAU (speed readings with 1 % noise,
        # differentiated per sample, would give noise larger than the yaw moment)
        h = c[MODEL.ip_s + i] * x[STATE.omega_end + i]
        h_before = x[STATE.h_lp + i]
        x[STATE.h_lp + i] = h_before + min(dt / H_TAU, 1.0) * (h - h_before)
        x[B + i] = dt * thrust * gx / J0 - dt * w1 * h / J0
        x[B + MAX_ROTORS + i] = dt * thrust * gy / J1 + dt * w0 * h / J1
        x[B + 2 * MAX_ROTORS + i] = dt * yaw / J2 - (x[STATE.h_lp + i] - h_before) / J2
    a = (1.0 - dt * c[MODEL.damping] / J0, 1.0 - dt * c[MODEL.damping + 1] / J1, 1.0 - dt * c[MODEL.damping + 2] / J2)
    d0, d1 = drag_moments(x, c)
    base = (dt * (m0 / J0 + d0), dt * (m1 / J1 + d1), dt * m2 / J2)
    if p[PARAM.moment_scale_s] > 0.0:
        _learn_moment_scale(x, p, c, gyr, a, base, dt)
    rel = (p[PARAM.model_error], p[PARAM.model_error], p[PARAM.yaw_model_error])
    floor = (p[PARAM.moment_noise] * dt) ** 2
    for j in range(3):
        rotors_part = 0.0
        for i in range(n):
            rotors_part += x[B + j * MAX_ROTORS + i] * x[STATE.eta + i]
        change = (a[j] - 1.0) * x[STATE.w + j] + base[j] + rotors_part
        x[STATE.w + j] += change
        x[STATE.alpha + j] = change / dt
        x[FP + j] = floor + (rel[j] * rotors_part) ** 2  # the model's error grows with the moment
    _propagate_covariance(x, p, n, a, dt)


@njit(cache=True, inline="always")
def _propagate_covariance(x, p, n, a, dt):
    """``P ← F P Fᵀ + Q`` with ``F = [[diag(a), B], [0, I]]`` (``B`` and the rate's process
    noise, ``FP``'s first three values, as :func:`predict` left them): rows 0-2 of ``F P``,
    then ``(F P) Fᵀ``, the rate's three rows summed together (three independent sums in flight)."""
    ns = 3 + n
    P, B, FP = STATE.P, STATE.B, STATE.FP
    q0, q1, q2 = x[FP], x[FP + 1], x[FP + 2]
    for col in range(ns):
        s0, s1, s2 = a[0] * x[P + col], a[1] * x[P + ns + col], a[2] * x[P + 2 * ns + col]
        for i in range(n):
            pc = x[P + (3 + i) * ns + col]
            s0 += x[B + i] * pc
            s1 += x[B + MAX_ROTORS + i] * pc
            s2 += x[B + 2 * MAX_ROTORS + i] * pc
        x[FP + col], x[FP + NS + col], x[FP + 2 * NS + col] = s0, s1, s2
    for r in range(ns):  # (F P Fᵀ)[j, r] = (F P)[j, :] · F[r, :]
        if r < 3:
            s0, s1, s2 = a[r] * x[FP + r], a[r] * x[FP + NS + r], a[r] * x[FP + 2 * NS + r]
            for i in range(n):
                br = x[B + r * MAX_ROTORS + i]
                s0 += x[FP + 3 + i] * br
                s1 += x[FP + NS + 3 + i] * br
                s2 += x[FP + 2 * NS + 3 + i] * br
        else:
            s0, s1, s2 = x[FP + r], x[FP + NS + r], x[FP + 2 * NS + r]
        for j, v in ((0, s0), (1, s1), (2, s2)):
            # within the rate's block both (j, r) and (r, j) are computed and differ by rounding:
            # the one from the larger row is kept, as the row-by-row loop before left it
            if r >= 3 or j >= r:
                x[P + j * ns + r] = v
                x[P + r * ns + j] = v
    qe = p[PARAM.eta_walk] ** 2 * dt
    x[P] += q0
    x[P + ns + 1] += q1
    x[P + 2 * ns + 2] += q2
    for i in range(n):
        x[P + (3 + i) * ns + 3 + i] += qe


@njit(cache=True, inline="always")
def _learn_moment_scale(x, p, c, gyr, a, base, dt):
    """The rotors' moment per axis against the model's (docs/detection.md, The moment learnt in
    flight): the measured rate change less the model's without the rotors against the rotors'
    modelled change at their common effectiveness, both band-passed, by least squares with a
    fading memory and a prior at 1; the rows of ``B`` (unscaled on entry) scaled by it."""
    n = int(c[MODEL.rotors])
    common = 0.0
    for i in range(n):
        common += x[STATE.eta + i]
    common = min(max(common / n, 0.5), 1.5)
    fast, slow = min(dt / SCALE_LP, 1.0), min(dt / SCALE_HP, 1.0)
    keep = 1.0 - min(dt / p[PARAM.moment_scale_s], 1.0)
    prior = (p[PARAM.moment_scale_prior] * dt) ** 2 * p[PARAM.moment_scale_s] / dt
    step = SCALE_RATE * dt  # the most it moves in a sample: a model's error is steady, a loss is sudden
    valid = x[STATE.samples] >= 2.0  # the last reading is there
    learn = valid and x[STATE.lost] < 0.0 and not holding(x, p)
    for i in range(n):  # a deficit past the 'lost' drift: maybe a loss, whose moments are not the model's
        learn = learn and x[STATE.s_lost + i] == 0.0
    Y, U, S = STATE.scale_y, STATE.scale_u, STATE.scale_sums
    for j in range(3):
        if valid:
            before = x[STATE.gyr_prev + 3 + j]
            y = gyr[j] - before - (a[j] - 1.0) * before - base[j]
            u = 0.0
            for i in range(n):
                u += x[STATE.B + j * MAX_ROTORS + i]
            x[Y + j] += fast * (y - x[Y + j])
            x[Y + 3 + j] += slow * (x[Y + j] - x[Y + 3 + j])
            x[U + j] += fast * (common * u - x[U + j])
            x[U + 3 + j] += slow * (x[U + j] - x[U + 3 + j])
        if learn:
            yb, ub = x[Y + j] - x[Y + 3 + j], x[U + j] - x[U + 3 + j]
            x[S + j] = keep * x[S + j] + yb * ub
            x[S + 3 + j] = keep * x[S + 3 + j] + ub * ub
            slope = (x[S + j] + prior) / (x[S + 3 + j] + prior)
            paced = min(max(slope, x[STATE.scale + j] - step), x[STATE.scale + j] + step)
            x[STATE.scale + j] = min(max(paced, 1.0 - SCALE_RANGE), 1.0 + SCALE_RANGE)
            if abs(paced - 1.0) >= SCALE_RANGE:  # at the clamp: reported (Detection.moment_scale_clamped)
                x[STATE.scale_clamped + j] = 1.0
        scale = x[STATE.scale + j]
        for i in range(n):
            x[STATE.B + j * MAX_ROTORS + i] *= scale


@njit(cache=True, inline="always")
def holding(x, p):
    """The tests hold: on the ground, within ``contact_hold_s`` of a contact or ``cut_hold_s``
    of a thrust cut."""
    if x[STATE.landed] != 0.0 or x[STATE.time] - x[STATE.contact_t] <= p[PARAM.contact_hold_s]:
        return True
    return x[STATE.time] - x[STATE.cut_t] <= p[PARAM.cut_hold_s]


@njit(cache=True, inline="always")
def update_thrust(x, ns, z, r):
    """Scalar Kalman update with the measurement row ``x[STATE.h:]`` (``ns`` values, zero on the
    rate: the accelerometer's z reads the effectiveness only), value ``z``, variance ``r``. The
    state's rate and effectiveness are contiguous (``STATE.w``)."""
    P, h, ph, w = STATE.P, STATE.h, STATE.ph, STATE.w
    for a in range(ns):
        v = 0.0
        for b in range(3, ns):
            v += x[P + a * ns + b] * x[h + b]
        x[ph + a] = v
    s = r
    pred = 0.0
    for a in range(3, ns):
        s += x[h + a] * x[ph + a]
        pred += x[h + a] * x[w + a]
    _apply_gain(x, ns, (z - pred) / s, s)


@njit(cache=True, inline="always")
def update_rate(x, ns, j, z, r):
    """Scalar Kalman update with the gyroscope's axis ``j``, value ``z``, variance ``r``: the
    row is the unit vector, so ``P h`` is ``P``'s column ``j``."""
    P, ph = STATE.P, STATE.ph
    for a in range(ns):
        x[ph + a] = x[P + a * ns + j]
    s = x[P + j * ns + j] + r
    _apply_gain(x, ns, (z - x[STATE.w + j]) / s, s)


@njit(cache=True, inline="always")
def _apply_gain(x, ns, innovation_per_s, s):
    """The state moved by ``P h`` times the innovation over its variance ``s``, and ``P ← P −
    (P h)(P h)ᵀ / s`` on and above the diagonal, mirrored (``P`` is exactly symmetric on entry and
    stays so)."""
    P, ph, w = STATE.P, STATE.ph, STATE.w
    for a in range(ns):
        x[w + a] += x[ph + a] * innovation_per_s
    for a in range(ns):
        pa = x[ph + a]
        for b in range(a, ns):
            v = x[P + a * ns + b] - pa * x[ph + b] / s
            x[P + a * ns + b] = v
            x[P + b * ns + a] = v


@njit(cache=True, inline="always")
def correct(x, p, c, gyr, acc):
    """The gyroscope's three rates and the accelerometer's z, moved to the centre of mass."""
    n = int(c[MODEL.rotors])
    ns = 3 + n
    h = STATE.h
    acc = at_centre_of_mass(x, p, c, acc)
    rg = p[PARAM.gyro_noise] ** 2
    for j in range(3):
        update_rate(x, ns, j, gyr[j], max(rg, x[STATE.gyr_var + j]))
    if np.isfinite(acc[2]):
        intact = 0.0
        for i in range(n):
            x[h + 3 + i] = -x[STATE.thrust + i] / c[MODEL.mass]
            intact -= x[h + 3 + i]
        margin = p[PARAM.contact_margin]
        if margin > 0.0 and -acc[2] > 1.3 * intact + margin:  # the ground pushes: the rotors cannot
            x[STATE.contact_t] = x[STATE.time]
            x[STATE.landed] = 1.0
        elif intact > 0.9 * GRAVITY:  # the rotors carry the weight again (lifted off)
            x[STATE.landed] = 0.0
        update_thrust(x, ns, acc[2], p[PARAM.acc_noise] ** 2)


@njit(cache=True, inline="always")
def gyro_noise_estimate(x, p, gyr, dt):
    """The gyroscope's noise variance per axis from its second difference, ``(g_k − 2 g_{k−1} +
    g_{k−2})² / 6`` (white noise's; the motion's share is its jerk times dt², negligible at IMU
    rates), averaged over ``noise_window_s`` (a running mean over the first window)."""
    x[STATE.samples] += 1.0
    k = x[STATE.samples]
    if p[PARAM.noise_window_s] > 0.0 and k >= 3.0:
        a = max(dt / p[PARAM.noise_window_s], 1.0 / (k - 2.0))
        for j in range(3):
            d2 = gyr[j] - 2.0 * x[STATE.gyr_prev + j] + x[STATE.gyr_prev + 3 + j]
            x[STATE.gyr_var + j] += a * (d2 * d2 / 6.0 - x[STATE.gyr_var + j])
    for j in range(3):
        x[STATE.gyr_prev + 3 + j] = x[STATE.gyr_prev + j]
        x[STATE.gyr_prev + j] = gyr[j]


@njit(cache=True, inline="always")
def note_commands(x, p, c, cmd):
    """The speeds commanded over the interval that ends at the next step (rad/s), kept for the
    speed test: a thrust cut, ``cut_rotors`` or more at the lowest speed, holds the tests (the
    rotors are then far from the regime the model holds in: near idle, decelerating, in the inflow
    of the vehicle's own motion)."""
    n = int(c[MODEL.rotors])
    for i in range(n):
        x[STATE.cmd + i] = cmd[i]
    x[STATE.cmd_known] = 1.0
    need = p[PARAM.cut_rotors]
    if need <= 0.0:
        return
    at_min = 0
    for i in range(n):
        if cmd[i] <= c[MODEL.omega_min]:
            at_min += 1
    if at_min >= need:
        x[STATE.cut_t] = x[STATE.time]
