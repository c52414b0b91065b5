"""Single-sample quaternion kernels compiled with numba, for use inside compiled filters.

Same convention as :mod:`quadest.conventions`; each kernel mirrors a vectorised function of
:mod:`quadest.rotation.quaternion` and is tested against it.
"""
import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def qmul(p, q):
    """Hamilton product ``p ⊗ q`` of two ``(4,)`` arrays."""
    out = np.empty(4)
    out[0] = p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3]
    out[1] = p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2]
    out[2] = p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1]
    out[3] = p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]
    return out


@njit(cache=True, inline="always")
def qnormalize(q):
    """Unit quaternion (in place); a zero quaternion becomes identity."""
    n = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if n > 0.0:
        for i in range(4):
            q[i] /= n
    else:
        q[0], q[1], q[2], q[3] = 1.0, 0.0, 0.0, 0.0
    return q


@njit(cache=True, inline="always")
def qrotate(q, v):
    """``R(q) @ v`` for a unit quaternion ``q`` and a ``(3,)`` vector."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    out = np.empty(3)
    out[0] = v[0] + w * tx + (y * tz - z * ty)
    out[1] = v[1] + w * ty + (z * tx - x * tz)
    out[2] = v[2] + w * tz + (x * ty - y * tx)
    return out


@njit(cache=True, inline="always")
def qrotate_inv(q, v):
    """``R(q).T @ v``: a navigation-frame vector expressed in the body frame."""
    qc = np.empty(4)
    qc[0], qc[1], qc[2], qc[3] = q[0], -q[1], -q[2], -q[3]
    return qrotate(qc, v)


@njit(cache=True, inline="always")
def qexp(rv):
    """Quaternion of a rotation vector ``rv`` (rad)."""
    th = np.sqrt(rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2])
    out = np.empty(4)
    out[0] = np.cos(0.5 * th)
    k = 0.5 - th * th / 48.0 if th < 1e-6 else np.sin(0.5 * th) / th
    out[1], out[2], out[3] = k * rv[0], k * rv[1], k * rv[2]
    return out
