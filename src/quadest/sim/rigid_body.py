"""Rigid-body free flight of a thrown quadcopter with idle propellers (compiled RK4).

State ``x = [p_n (3), v_n (3), q_nb (4), ω_b (3)]``. Dynamics (recovery paper eqs 3-6 on
quadest's conventions, with Euler's equation written with the inertia as it should be):

    ṗ = v,   v̇ = R(q) f_c(Rᵀ v, ω)/m + g,   q̇ = ½ q ⊗ [0, ω],
    J ω̇ = −ω × (J ω) − D ω

with the aerodynamic force ``f_c`` of eq 9 (:mod:`quadest.models.aero`) and a body-rate
damping torque ``−D ω``. The quaternion is renormalised after every step.
"""

import numpy as np

from quadest._jit import njit
from quadest.models.aero import aero_force
from quadest.rotation.kernels import qmul, qrotate, qrotate_inv


@njit(cache=True)
def _deriv(x, m, Jd, Dd, A, B, C, g):
    dx = np.empty(13)
    q = x[6:10]
    w = x[10:13]
    vb = qrotate_inv(q, x[3:6])
    an = qrotate(q, aero_force(vb, w, A, B, C)) / m
    dx[0:3] = x[3:6]
    dx[3:6] = an + g
    wq = np.zeros(4)
    wq[1:] = w
    dx[6:10] = 0.5 * qmul(q, wq)
    Jw = Jd * w
    dx[10] = (-(w[1] * Jw[2] - w[2] * Jw[1]) - Dd[0] * w[0]) / Jd[0]
    dx[11] = (-(w[2] * Jw[0] - w[0] * Jw[2]) - Dd[1] * w[1]) / Jd[1]
    dx[12] = (-(w[0] * Jw[1] - w[1] * Jw[0]) - Dd[2] * w[2]) / Jd[2]
    return dx


@njit(cache=True)
def integrate(x0, t0, times, max_step, m, Jd, Dd, A, B, C, g):
    """Integrate from state ``x0`` at ``t0`` to each of ``times`` (increasing, ``>= t0``).

    Returns the states (N, 13) and their derivatives (N, 13) at ``times``.
    """
    n = len(times)
    X = np.empty((n, 13))
    dX = np.empty((n, 13))
    x = x0.copy()
    t = t0
    for k in range(n):
        span = times[k] - t
        steps = int(np.ceil(span / max_step - 1e-9)) if span > 0 else 0
        if steps > 0:
            h = span / steps
            for _ in range(steps):
                k1 = _deriv(x, m, Jd, Dd, A, B, C, g)
                k2 = _deriv(x + 0.5 * h * k1, m, Jd, Dd, A, B, C, g)
                k3 = _deriv(x + 0.5 * h * k2, m, Jd, Dd, A, B, C, g)
                k4 = _deriv(x + h * k3, m, Jd, Dd, A, B, C, g)
                x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                nq = np.sqrt(np.sum(x[6:10] ** 2))
                x[6:10] /= nq
        t = times[k]
        X[k] = x
        dX[k] = _deriv(x, m, Jd, Dd, A, B, C, g)
    return X, dX
