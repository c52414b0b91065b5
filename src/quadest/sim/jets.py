"""Second-order jets: a value with its exact first and second time derivatives.

The flight scenarios are built by differential flatness: attitude follows from the path's
acceleration, jerk and snap through normalisations and cross products. Carrying ``(x, ẋ, ẍ)``
through those operations with the product and chain rules gives the body rate and the angular
acceleration exactly (``[ω]× = Rᵀ Ṙ``, ``[ω̇]× = Rᵀ R̈ − [ω]×²``), without numerical
differentiation, so the simulated gyroscope and accelerometer agree with the true attitude to
rounding error. All arrays carry a leading sample axis ``N``.
"""

import numpy as np


class Jet:
    """``(v, d1, d2)``: value and exact first and second time derivatives, same shapes."""

    __slots__ = ("v", "d1", "d2")

    def __init__(self, v, d1, d2):
        self.v, self.d1, self.d2 = np.asarray(v, float), np.asarray(d1, float), np.asarray(d2, float)

    @classmethod
    def const(cls, v):
        v = np.asarray(v, float)
        return cls(v, np.zeros_like(v), np.zeros_like(v))

    def __add__(self, o):
        o = o if isinstance(o, Jet) else Jet.const(o)
        return Jet(self.v + o.v, self.d1 + o.d1, self.d2 + o.d2)

    __radd__ = __add__

    def __neg__(self):
        return Jet(-self.v, -self.d1, -self.d2)

    def __sub__(self, o):
        return self + (-o if isinstance(o, Jet) else -np.asarray(o, float))

    def __rsub__(self, o):
        return (-self) + o

    def __mul__(self, c):
        """Multiplication by a constant (a number or an array broadcasting like ``v``)."""
        if isinstance(c, Jet):
            return scale(c, self) if c.v.ndim < self.v.ndim else scale(self, c)
        return Jet(self.v * c, self.d1 * c, self.d2 * c)

    __rmul__ = __mul__


def bilinear(op, a: Jet, b: Jet) -> Jet:
    """Product rule for any bilinear ``op``: (ab)' = a'b + ab', (ab)'' = a''b + 2a'b' + ab''."""
    return Jet(op(a.v, b.v), op(a.d1, b.v) + op(a.v, b.d1), op(a.d2, b.v) + 2.0 * op(a.d1, b.d1) + op(a.v, b.d2))


def scale(s: Jet, x: Jet) -> Jet:
    """Scalar jet ``s`` (N,) times jet ``x`` (N, ...)."""
    extra = (None,) * (x.v.ndim - s.v.ndim)
    return bilinear(lambda a, b: a[(...,) + extra] * b, s, x)


def cross(a: Jet, b: Jet) -> Jet:
    return bilinear(np.cross, a, b)


def dot(a: Jet, b: Jet) -> Jet:
    return bilinear(lambda x, y: np.sum(x * y, axis=-1), a, b)


def matvec(A: Jet, x: Jet) -> Jet:
    return bilinear(lambda M, v: np.einsum("nij,nj->ni", M, v), A, x)


def matmul(A: Jet, B: Jet) -> Jet:
    return bilinear(lambda M, K: M @ K, A, B)


def transpose(A: Jet) -> Jet:
    return Jet(np.swapaxes(A.v, -1, -2), np.swapaxes(A.d1, -1, -2), np.swapaxes(A.d2, -1, -2))


def chain(x: Jet, f, f1, f2) -> Jet:
    """Chain rule for a scalar function with derivatives ``f1``, ``f2`` (elementwise)."""
    return Jet(f(x.v), f1(x.v) * x.d1, f2(x.v) * x.d1**2 + f1(x.v) * x.d2)


def sin(x: Jet) -> Jet:
    return chain(x, np.sin, np.cos, lambda v: -np.sin(v))


def cos(x: Jet) -> Jet:
    return chain(x, np.cos, lambda v: -np.sin(v), lambda v: -np.cos(v))


def norm(u: Jet) -> Jet:
    """Euclidean norm over the last axis."""
    return chain(dot(u, u), np.sqrt, lambda w: 0.5 / np.sqrt(w), lambda w: -0.25 * w**-1.5)


def normalize(u: Jet) -> Jet:
    """``u / |u|`` over the last axis."""
    inv = chain(dot(u, u), lambda w: w**-0.5, lambda w: -0.5 * w**-1.5, lambda w: 0.75 * w**-2.5)
    return scale(inv, u)


def columns(x: Jet, y: Jet, z: Jet) -> Jet:
    """The matrix jet whose columns are the vector jets ``x, y, z``."""
    return Jet(
        *(np.stack([a, b, c], axis=-1) for a, b, c in zip((x.v, x.d1, x.d2), (y.v, y.d1, y.d2), (z.v, z.d1, z.d2)))
    )


def rot_z(angle: Jet) -> Jet:
    """Rotation matrix jet about z by a scalar angle jet."""
    c, s = cos(angle), sin(angle)
    zero, one = Jet.const(np.zeros_like(angle.v)), Jet.const(np.ones_like(angle.v))
    return columns(_stack3(c, s, zero), _stack3(-s, c, zero), _stack3(zero, zero, one))


def rot_axis(axis, angle: Jet) -> Jet:
    """Rotation matrix jet about a constant unit ``axis`` by a scalar angle jet (Rodrigues)."""
    k = np.asarray(axis, float)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    c, s = cos(angle), sin(angle)
    one_minus_c = 1.0 - c
    n = angle.v.shape
    eye = Jet.const(np.broadcast_to(np.eye(3), n + (3, 3)))
    return (
        eye
        + scale(s, Jet.const(np.broadcast_to(K, n + (3, 3))))
        + scale(one_minus_c, Jet.const(np.broadcast_to(K @ K, n + (3, 3))))
    )


def _stack3(a: Jet, b: Jet, c: Jet) -> Jet:
    return Jet(*(np.stack(t, axis=-1) for t in zip((a.v, a.d1, a.d2), (b.v, b.d1, b.d2), (c.v, c.d1, c.d2))))


def vee(W):
    """Vector of the skew part of ``W`` (..., 3, 3): ``vee(skew(w)) == w``."""
    return 0.5 * np.stack(
        [W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], axis=-1
    )


def body_rates(R: Jet):
    """Body angular rate ``ω`` and acceleration ``ω̇`` (N, 3) of a rotation-matrix jet ``R_nb``.

    ``Ṙ = R [ω]×`` gives ``[ω]× = Rᵀ Ṙ``; differentiating once more,
    ``R̈ = R [ω]×² + R [ω̇]×`` gives ``[ω̇]× = Rᵀ R̈ − [ω]×²``.
    """
    Rt = np.swapaxes(R.v, -1, -2)
    W = Rt @ R.d1
    w = vee(W)
    Wx = np.zeros_like(W)
    Wx[..., 0, 1], Wx[..., 0, 2], Wx[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    Wx[..., 1, 0], Wx[..., 2, 0], Wx[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    wdot = vee(Rt @ R.d2 - Wx @ Wx)
    return w, wdot
