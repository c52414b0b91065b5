"""Small dense linear algebra in explicit loops, for the compiled filter steps.

numba sends ``@`` and ``np.linalg.inv`` on 2-D arrays to BLAS/LAPACK, whose call overhead
(~0.3-1 µs) dominates for 3x3 to 9x9 matrices; these loops compile to a few hundred
instructions. Each function is tested against numpy.
"""

import numpy as np

from quadest._jit import njit
from quadest.rotation.kernels import FASTMATH


@njit(cache=True, fastmath=FASTMATH)
def mm(A, B):
    """``A @ B``."""
    n, k = A.shape
    m = B.shape[1]
    C = np.zeros((n, m))
    for i in range(n):
        for r in range(k):
            a = A[i, r]
            if a != 0.0:
                for j in range(m):
                    C[i, j] += a * B[r, j]
    return C


@njit(cache=True, fastmath=FASTMATH)
def mm_t(A, B):
    """``A @ B.T``."""
    n, k = A.shape
    m = B.shape[0]
    C = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for r in range(k):
                s += A[i, r] * B[j, r]
            C[i, j] = s
    return C


@njit(cache=True, fastmath=FASTMATH)
def mv(A, v):
    """``A @ v``."""
    n, k = A.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for r in range(k):
            s += A[i, r] * v[r]
        out[i] = s
    return out


@njit(cache=True, fastmath=FASTMATH)
def inv_spd(A):
    """Inverse of a symmetric positive definite matrix by Gauss-Jordan elimination (no pivoting
    is needed for SPD matrices)."""
    n = A.shape[0]
    M = A.copy()
    inv = np.eye(n)
    for c in range(n):
        d = M[c, c]
        for j in range(n):
            M[c, j] /= d
            inv[c, j] /= d
        for r in range(n):
            if r != c:
                f = M[r, c]
                if f != 0.0:
                    for j in range(n):
                        M[r, j] -= f * M[c, j]
                        inv[r, j] -= f * inv[c, j]
    return inv


@njit(cache=True, fastmath=FASTMATH)
def inv_spd_into(M, out):
    """Inverse of a symmetric positive definite matrix into ``out`` by Gauss-Jordan, without
    allocating (``M`` is destroyed)."""
    n = M.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = 1.0 if i == j else 0.0
    for c in range(n):
        d = M[c, c]
        for j in range(n):
            M[c, j] /= d
            out[c, j] /= d
        for r in range(n):
            if r != c:
                f = M[r, c]
                for j in range(n):
                    M[r, j] -= f * M[c, j]
                    out[r, j] -= f * out[c, j]
