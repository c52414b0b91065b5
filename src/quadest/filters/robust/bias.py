"""The gyro bias (docs/estimators.md, robust, item 4): a 3-state Kalman filter whose gain along a
measurement row is capped (eq R3b), the rest detection and the bias measured at rest."""

from __future__ import annotations

from quadest._jit import njit
from quadest.filters.robust.params import PARAM, STATE


@njit(cache=True, inline="always")
def bias_update(x, h0, h1, h2, innov, r, clip, gmax):
    """Scalar Kalman update of the bias with measurement row h, innovation and noise r; the
    gain along h at most ``gmax`` (eq R3b: ``s ≥ h P hᵀ / gmax``)."""
    Pb = STATE.Pb
    ph0 = x[Pb] * h0 + x[Pb + 1] * h1 + x[Pb + 2] * h2
    ph1 = x[Pb + 3] * h0 + x[Pb + 4] * h1 + x[Pb + 5] * h2
    ph2 = x[Pb + 6] * h0 + x[Pb + 7] * h1 + x[Pb + 8] * h2
    hph = h0 * ph0 + h1 * ph1 + h2 * ph2
    s = max(hph + r, hph / gmax)
    if not s > 0.0:
        return
    k0, k1, k2 = ph0 / s, ph1 / s, ph2 / s
    x[STATE.bias] = min(clip, max(-clip, x[STATE.bias] + k0 * innov))
    x[STATE.bias + 1] = min(clip, max(-clip, x[STATE.bias + 1] + k1 * innov))
    x[STATE.bias + 2] = min(clip, max(-clip, x[STATE.bias + 2] + k2 * innov))
    x[Pb] -= k0 * ph0
    x[Pb + 1] -= k0 * ph1
    x[Pb + 2] -= k0 * ph2
    x[Pb + 3] -= k1 * ph0
    x[Pb + 4] -= k1 * ph1
    x[Pb + 5] -= k1 * ph2
    x[Pb + 6] -= k2 * ph0
    x[Pb + 7] -= k2 * ph1
    x[Pb + 8] -= k2 * ph2


@njit(cache=True, inline="always")
def rest_lowpass(x, i, g, a, k):
    """Axis i's gyro and accelerometer low-passes for the rest detection (gain ``k``); returns the
    squared deviations of the readings from them."""
    x[STATE.rest_g + i] += k * (g - x[STATE.rest_g + i])
    x[STATE.rest_a + i] += k * (a - x[STATE.rest_a + i])
    return (g - x[STATE.rest_g + i]) ** 2, (a - x[STATE.rest_a + i]) ** 2


@njit(cache=True, inline="always")
def rest_and_bias(x, p, gyr, acc, nclip, dt):
    """The rest detection (every sample of gyro and accelerometer within ``rest_gyr`` /
    ``rest_acc`` of their low-passes for ``rest_time``; none clipped, the low-passed rate within
    the largest a bias reaches), the bias's random walk, and at rest the low-passed gyro as a
    measurement of the bias. Returns (at rest, the largest squared rate at rest)."""
    k_rest = x[STATE.coef + 4]
    dg0, da0 = rest_lowpass(x, 0, gyr[0], acc[0], k_rest)
    dg1, da1 = rest_lowpass(x, 1, gyr[1], acc[1], k_rest)
    dg2, da2 = rest_lowpass(x, 2, gyr[2], acc[2], k_rest)
    dg = dg0 + dg1 + dg2
    da = da0 + da1 + da2
    # every sample must be within the thresholds (as VQF's): a mean square would take a slow
    # translation for rest
    rg0, rg1, rg2 = x[STATE.rest_g], x[STATE.rest_g + 1], x[STATE.rest_g + 2]
    rest_rate2 = 3.0 * (p[PARAM.bias_clip] + p[PARAM.rest_gyr]) ** 2
    still = (
        dg <= p[PARAM.rest_gyr] * p[PARAM.rest_gyr]
        and da <= p[PARAM.rest_acc] * p[PARAM.rest_acc]
        and nclip == 0
        and rg0 * rg0 + rg1 * rg1 + rg2 * rg2 <= rest_rate2
    )
    x[STATE.rest_t] = x[STATE.rest_t] + dt if still else 0.0
    at_rest = x[STATE.rest_t] >= p[PARAM.rest_time]
    # random walk; the variance capped at the initial one (the vertical axis is weakly
    # observable without a magnetometer)
    qb = p[PARAM.bias_drift] * p[PARAM.bias_drift] * dt
    cap = p[PARAM.bias_init] * p[PARAM.bias_init]
    x[STATE.Pb] = min(x[STATE.Pb] + qb, cap)
    x[STATE.Pb + 4] = min(x[STATE.Pb + 4] + qb, cap)
    x[STATE.Pb + 8] = min(x[STATE.Pb + 8] + qb, cap)
    if at_rest:
        r = p[PARAM.bias_rest_std] * p[PARAM.bias_rest_std]
        bias_update(x, 1.0, 0.0, 0.0, rg0 - x[STATE.bias], r, p[PARAM.bias_clip], 1.0)
        bias_update(x, 0.0, 1.0, 0.0, rg1 - x[STATE.bias + 1], r, p[PARAM.bias_clip], 1.0)
        bias_update(x, 0.0, 0.0, 1.0, rg2 - x[STATE.bias + 2], r, p[PARAM.bias_clip], 1.0)
    return at_rest, rest_rate2
