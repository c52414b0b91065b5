"""Single-sample quaternion kernels compiled with numba: the one vocabulary of quadest's
compiled code (filters, recovery bank, simulator).

Same convention as :mod:`quadest.conventions`; each kernel mirrors a vectorised function of
:mod:`quadest.rotation.quaternion` and is tested against it (tests/unit/test_rotation.py). The
``*_s`` kernels take and return scalars: they allocate nothing, which matters in steps that
run millions of times.
"""

import numpy as np

from quadest._jit import njit

# Floating-point flags for quadest's compiled steps: LLVM may fuse and reorder arithmetic
# (contract, reassoc, arcp); NaN and Inf keep their meaning (no nnan/ninf), which bad-input
# handling needs.
FASTMATH = {"contract", "reassoc", "arcp"}


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


@njit(cache=True, inline="always")
def qmul_s(a0, a1, a2, a3, b0, b1, b2, b3):
    """``a ⊗ b`` (Hamilton), scalars in and out."""
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )


@njit(cache=True, inline="always")
def rotate_s(w, x, y, z, v0, v1, v2):
    """``R(q) v`` for ``q = [w, x, y, z]`` (unit), scalars in and out."""
    return (
        v0 * (1 - 2 * (y * y + z * z)) + v1 * 2 * (x * y - w * z) + v2 * 2 * (x * z + w * y),
        v0 * 2 * (x * y + w * z) + v1 * (1 - 2 * (x * x + z * z)) + v2 * 2 * (y * z - w * x),
        v0 * 2 * (x * z - w * y) + v1 * 2 * (y * z + w * x) + v2 * (1 - 2 * (x * x + y * y)),
    )


@njit(cache=True, inline="always")
def rotate_inv_s(w, x, y, z, v0, v1, v2):
    """``R(q)ᵀ v``: a navigation-frame vector in the body frame, scalars in and out."""
    return (
        v0 * (1 - 2 * (y * y + z * z)) + v1 * 2 * (x * y + w * z) + v2 * 2 * (x * z - w * y),
        v0 * 2 * (x * y - w * z) + v1 * (1 - 2 * (x * x + z * z)) + v2 * 2 * (y * z + w * x),
        v0 * 2 * (x * z + w * y) + v1 * 2 * (y * z - w * x) + v2 * (1 - 2 * (x * x + y * y)),
    )


@njit(cache=True, inline="always")
def qdot_s(w, x, y, z, g0, g1, g2):
    """``½ q ⊗ [0, ω]``: the rate of change of ``q_nb`` for a body rate ω (first-order
    quaternion integration is ``q + Δt · qdot``)."""
    return (
        0.5 * (-x * g0 - y * g1 - z * g2),
        0.5 * (w * g0 + y * g2 - z * g1),
        0.5 * (w * g1 - x * g2 + z * g0),
        0.5 * (w * g2 + x * g1 - y * g0),
    )


@njit(cache=True, inline="always")
def normalize_s(w, x, y, z):
    """The unit quaternion of ``[w, x, y, z]`` (nonzero)."""
    n = np.sqrt(w * w + x * x + y * y + z * z)
    return w / n, x / n, y / n, z / n


@njit(cache=True, inline="always")
def qexp_right(q, a, b, c):
    """``q ← q ⊗ Exp([a, b, c])`` in place, normalised (rotation vector in the body frame)."""
    th = np.sqrt(a * a + b * b + c * c)
    cw = np.cos(0.5 * th)
    k = 0.5 - th * th / 48.0 if th < 1e-6 else np.sin(0.5 * th) / th
    ex, ey, ez = k * a, k * b, k * c
    w, x, y, z = q[0], q[1], q[2], q[3]
    q[0], q[1], q[2], q[3] = normalize_s(
        w * cw - x * ex - y * ey - z * ez,
        w * ex + x * cw + y * ez - z * ey,
        w * ey - x * ez + y * cw + z * ex,
        w * ez + x * ey - y * ex + z * cw,
    )


@njit(cache=True, inline="always")
def rot_matrix(q):
    """``R(q)`` (3x3) of a unit quaternion."""
    rows = rot_entries(q[0], q[1], q[2], q[3])
    R = np.empty((3, 3))
    for i in range(3):
        R[i, 0], R[i, 1], R[i, 2] = rows[i]
    return R


@njit(cache=True, inline="always")
def rot_entries(w, x, y, z):
    """The entries of ``R(q)`` row by row, as tuples (for code that allocates nothing)."""
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


@njit(cache=True, inline="always")
def skew(v):
    """``[v]×`` with ``[v]× u = v × u``."""
    S = np.zeros((3, 3))
    S[0, 1], S[0, 2], S[1, 0], S[1, 2], S[2, 0], S[2, 1] = -v[2], v[1], v[2], -v[0], -v[1], v[0]
    return S


@njit(cache=True, inline="always")
def mag_rate_terms(mi, mj, mk, dj, dk, wj, wk):
    """The rate about body axis i from a vector fixed in the navigation frame and seen turning
    in the body (the magnetic field: robust's eq R4, docs/estimators.md), (i, j, k) cyclic:
    ``ṁ = −ω × m`` gives ``ṁ_j + ω_k m_i = ω_i m_k`` and ``ṁ_k − ω_j m_i = −ω_i m_j``, whose
    least-squares solution is ``ω_i = num / den`` with
    ``num = m_k (ṁ_j + ω_k m_i) − m_j (ṁ_k − ω_j m_i)`` and ``den = m_j² + m_k²`` (a field along the
    axis says nothing of its rate). ``m`` the mid-point of two samples, ``d`` their difference over
    the interval, ``w`` the other axes' mean rates over it."""
    return mk * (dj + wk * mi) - mj * (dk - wj * mi), mj * mj + mk * mk
