"""The fault-tolerant controller's allocation (docs/vehicle.md, *The fault-tolerant
controller*): the collective thrust and the two moments it asks of the rotors left, met exactly
where the rotors' range allows, else by a weighted least-squares fit within each rotor's
thrust range."""

from __future__ import annotations

import numpy as np

from quadest._jit import njit


@njit(cache=True)
def allocate(ftc, thrust, M0, M1, cmd):
    """Rotor speeds (rad/s) into ``cmd`` for the collective thrust and the roll and pitch moments
    (body) asked of the three rotors left: the bounded least squares (``thrust_weight`` > 0) or
    the former allocation (module doc)."""
    if ftc.alloc_weight[0] > 0.0:
        _bounded_allocation(ftc, thrust, M0, M1, cmd)
        return
    thrust, scale = _fit_to_rotors(ftc, thrust, M0, M1)
    M0 *= scale
    M1 *= scale
    for i in range(cmd.shape[0]):
        cmd[i] = 0.0
    for a in range(3):
        t = ftc.alloc_inv[a, 0] * thrust + ftc.alloc_inv[a, 1] * M0 + ftc.alloc_inv[a, 2] * M1
        cmd[ftc.active[a]] = np.sqrt(min(max(t, 0.0), ftc.t_max) / ftc.k_f)


@njit(cache=True, inline="always")
def _bounded_allocation(ftc, thrust, M0, M1, cmd):
    """Rotor speeds into ``cmd`` from the three thrusts within ``[0, t_max]`` nearest
    ``[thrust, M0, M1]`` in the weighted least squares (``alloc_weight``). Each of the 27 active
    sets (every rotor free, at 0 or at ``t_max``) is solved and the best one within the bounds
    kept: the problem is convex, so that is its optimum. A moment that would need the rotor
    opposite the lost one to pull is met as nearly as the others can, not turned around."""
    A, w = ftc.alloc, ftc.alloc_weight
    u0, u1, u2 = thrust, M0, M1
    tol = 1e-9 * ftc.t_max
    best0, best1, best2 = _solve3(ftc.alloc_inv, u0, u1, u2)  # met exactly within the bounds: the optimum
    if min(best0, best1, best2) >= -tol and max(best0, best1, best2) <= ftc.t_max + tol:
        _set_speeds(ftc, best0, best1, best2, cmd)
        return
    best = np.inf
    for code in range(27):
        m0, m1, m2 = code % 3, (code // 3) % 3, code // 9  # 0 free, 1 at zero, 2 at t_max
        t0 = 0.0 if m0 == 1 else ftc.t_max
        t1 = 0.0 if m1 == 1 else ftc.t_max
        t2 = 0.0 if m2 == 1 else ftc.t_max
        if m0 == 0 and m1 == 0 and m2 == 0:
            t0, t1, t2 = _solve3(ftc.alloc_inv, u0, u1, u2)
        elif (m0 == 0) + (m1 == 0) + (m2 == 0) == 2:
            f, g = (0, 1) if m2 != 0 else ((0, 2) if m1 != 0 else (1, 2))
            x, y = _least_squares2(A, w, u0, u1, u2, f, g, t0, t1, t2)
            t0, t1, t2 = _put(t0, t1, t2, f, x)
            t0, t1, t2 = _put(t0, t1, t2, g, y)
        elif (m0 == 0) + (m1 == 0) + (m2 == 0) == 1:
            f = 0 if m0 == 0 else (1 if m1 == 0 else 2)
            t0, t1, t2 = _put(t0, t1, t2, f, _least_squares1(A, w, u0, u1, u2, f, t0, t1, t2))
        if min(t0, t1, t2) < -tol or max(t0, t1, t2) > ftc.t_max + tol:
            continue
        cost = 0.0
        for i in range(3):
            r = A[i, 0] * t0 + A[i, 1] * t1 + A[i, 2] * t2 - (u0 if i == 0 else (u1 if i == 1 else u2))
            cost += (w[i] * r) ** 2
        if cost < best:
            best0, best1, best2, best = t0, t1, t2, cost
    _set_speeds(ftc, best0, best1, best2, cmd)


@njit(cache=True, inline="always")
def _set_speeds(ftc, t0, t1, t2, cmd):
    """The three rotors' speeds for their thrusts, clipped to what they can give; the lost one 0."""
    for i in range(cmd.shape[0]):
        cmd[i] = 0.0
    for a, t in ((0, t0), (1, t1), (2, t2)):
        cmd[ftc.active[a]] = np.sqrt(min(max(t, 0.0), ftc.t_max) / ftc.k_f)


@njit(cache=True, inline="always")
def _solve3(inv, u0, u1, u2):
    """``A⁻¹ u``: the three thrusts that give ``u`` exactly."""
    return (
        inv[0, 0] * u0 + inv[0, 1] * u1 + inv[0, 2] * u2,
        inv[1, 0] * u0 + inv[1, 1] * u1 + inv[1, 2] * u2,
        inv[2, 0] * u0 + inv[2, 1] * u1 + inv[2, 2] * u2,
    )


@njit(cache=True, inline="always")
def _put(t0, t1, t2, j, v):
    """``(t0, t1, t2)`` with entry ``j`` set to ``v``."""
    return (v if j == 0 else t0), (v if j == 1 else t1), (v if j == 2 else t2)


@njit(cache=True, inline="always")
def _residual(A, u0, u1, u2, t0, t1, t2, free_a, free_b, i):
    """Row ``i`` of ``u − A t`` with the free entries' thrusts left out."""
    r = u0 if i == 0 else (u1 if i == 1 else u2)
    for j, t in ((0, t0), (1, t1), (2, t2)):
        if j != free_a and j != free_b:
            r -= A[i, j] * t
    return r


@njit(cache=True, inline="always")
def _least_squares2(A, w, u0, u1, u2, f, g, t0, t1, t2):
    """The weighted least squares of thrusts ``f`` and ``g``, the third held (normal equations)."""
    a11, a12, a22, b1, b2 = 0.0, 0.0, 0.0, 0.0, 0.0
    for i in range(3):
        r = _residual(A, u0, u1, u2, t0, t1, t2, f, g, i)
        p, q, ww = A[i, f], A[i, g], w[i] * w[i]
        a11 += ww * p * p
        a12 += ww * p * q
        a22 += ww * q * q
        b1 += ww * p * r
        b2 += ww * q * r
    det = a11 * a22 - a12 * a12
    if abs(det) < 1e-300:
        return -1.0, -1.0  # singular: no solution (refused by the bounds)
    return (a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det


@njit(cache=True, inline="always")
def _least_squares1(A, w, u0, u1, u2, f, t0, t1, t2):
    """The weighted least squares of thrust ``f``, the other two held."""
    num, den = 0.0, 0.0
    for i in range(3):
        r = _residual(A, u0, u1, u2, t0, t1, t2, f, -1, i)
        num += w[i] * w[i] * A[i, f] * r
        den += w[i] * w[i] * A[i, f] * A[i, f]
    return num / den


@njit(cache=True, inline="always")
def _thrust_range(ftc, thrust, M0, M1):
    """The collective thrusts in ``[0, thrust]`` for which every rotor that shares the thrust
    stays within ``[0, t_max]`` with the moments ``M0``, ``M1``: ``(lo, hi)``, empty if lo > hi."""
    lo, hi = 0.0, thrust
    for a in range(3):
        c = ftc.alloc_inv[a, 0]  # rotor a's share of the thrust (0 for the one opposite the lost one)
        m = ftc.alloc_inv[a, 1] * M0 + ftc.alloc_inv[a, 2] * M1
        if c > 1e-9:
            hi = min(hi, (ftc.t_max - m) / c)
            lo = max(lo, -m / c)
        elif c < -1e-9:
            hi = min(hi, -m / c)
            lo = max(lo, (ftc.t_max - m) / c)
    return lo, hi


@njit(cache=True, inline="always")
def _fit_to_rotors(ftc, thrust, M0, M1):
    """What the rotors can give, the roll and pitch moments first: the largest collective
    thrust up to ``thrust`` with every rotor that shares it within ``[0, t_max]``; where none
    fits, the moments scaled down (their direction kept, bisection) until one does. Returns the
    thrust and the moments' scale. (Clipping each rotor alone would give up the moments' ratio.)"""
    lo, hi = _thrust_range(ftc, thrust, M0, M1)
    if lo <= hi:
        return hi, 1.0
    s_ok, s_bad = 0.0, 1.0
    for _ in range(12):
        s = 0.5 * (s_ok + s_bad)
        lo, hi = _thrust_range(ftc, thrust, s * M0, s * M1)
        if lo <= hi:
            s_ok = s
        else:
            s_bad = s
    lo, hi = _thrust_range(ftc, thrust, s_ok * M0, s_ok * M1)
    return max(hi, 0.0), s_ok
