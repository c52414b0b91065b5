"""The recovery paper's aerodynamic force model, eqs 9-13, in quadest's body frame (FRD).

``f_c(v, ω) = A v + B |v| v + C ψ(ω)`` (eq 9) is the combined aerodynamic and constant idle
thrust force in newtons, body frame, with ``v`` the body-frame velocity relative to still air and
``ψ(ω) = (ωx, ωy, ωz, ωx², ωy², ωz², ωxωy, ωyωz, ωzωx, 1)`` (eq 10). The paper's body frame has
z along the thrust axis (up); quadest's is FRD, so a parameter set taken from the paper is
converted with ``P = diag(1, -1, -1)``: ``A_frd = P A P``, ``B_frd = P B P`` and ``C_frd = P C
Q(P)`` where ``Q`` maps ``ψ`` of the FRD rate to ``ψ`` of the paper's rate (see
:func:`AeroModel.from_z_up`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit


def psi(w):
    """Rate features ψ(ω) of eq 10, ``(..., 3) -> (..., 10)``."""
    w = np.asarray(w, float)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    return np.stack([x, y, z, x * x, y * y, z * z, x * y, y * z, z * x, np.ones_like(x)], axis=-1)


def features(v, w):
    """Feature vector φ(v, ω) = [v, |v| v, ψ(ω)] of eq 12, ``(..., 16)``."""
    v = np.asarray(v, float)
    return np.concatenate([v, np.linalg.norm(v, axis=-1, keepdims=True) * v, psi(w)], axis=-1)


@njit(cache=True)
def aero_force(vb, w, A, B, C):
    """Eq 9 for one sample: force (N) in the body frame."""
    sp = np.sqrt(vb[0] ** 2 + vb[1] ** 2 + vb[2] ** 2)
    ps = np.empty(10)
    ps[0], ps[1], ps[2] = w[0], w[1], w[2]
    ps[3], ps[4], ps[5] = w[0] * w[0], w[1] * w[1], w[2] * w[2]
    ps[6], ps[7], ps[8], ps[9] = w[0] * w[1], w[1] * w[2], w[2] * w[0], 1.0
    f = np.zeros(3)
    for i in range(3):
        s = 0.0
        for j in range(3):
            s += A[i, j] * vb[j] + B[i, j] * sp * vb[j]
        for j in range(10):
            s += C[i, j] * ps[j]
        f[i] = s
    return f


@dataclass(frozen=True)
class AeroModel:
    """Parameter matrices of eq 9 (body frame FRD): A (3, 3) N s/m, B (3, 3) N s²/m², C (3, 10)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray

    def __post_init__(self):
        for name, shape in (("A", (3, 3)), ("B", (3, 3)), ("C", (3, 10))):
            a = np.array(getattr(self, name), dtype=float)
            if a.shape != shape:
                raise ValueError(f"aero model {name}: expected shape {shape}, got {a.shape}")
            object.__setattr__(self, name, a)

    @property
    def Lambda(self):
        """Combined parameter matrix Λ = [A B C] of eq 13, (3, 16)."""
        return np.hstack([self.A, self.B, self.C])

    def force(self, v, w):
        """Eq 13: ``f_c = Λ φ(v, ω)`` (N, body frame), vectorised."""
        return features(v, w) @ self.Lambda.T

    @classmethod
    def from_z_up(cls, A, B, C):
        """Convert matrices given in a body frame with z along the thrust axis (the paper's)."""
        P = np.diag([1.0, -1.0, -1.0])
        # ψ of the paper's rate (P ω) in terms of ψ of ours: odd terms in y or z flip sign
        Q = np.diag([1, -1, -1, 1, 1, 1, -1, 1, -1, 1]).astype(float)
        return cls(P @ np.asarray(A) @ P, P @ np.asarray(B) @ P, P @ np.asarray(C) @ Q)
