"""Points spread evenly on the unit sphere: the hypotheses of the bank of EKFs.

The recovery paper (section IV.B) uses numerical solutions of the spherical-codes problem
(its ref [17], Sloane's tables): N points whose smallest pairwise angle is as large as possible.
quadest computes them by a deterministic optimisation, so any N is available without tables:

1. start from the Fibonacci lattice (deterministic, already nearly uniform);
2. minimise the Riesz s-energy ``Σ 1/|p_i − p_j|^s`` by projected gradient steps with s rising
   from 2 to 512: as s grows the minimiser approaches the max-min (spherical code) solution.

For N = 4, 6, 12 this reaches the tetrahedron, octahedron and icosahedron within 0.003°
(tested to 0.01°); for N = 40 a smallest angle of 33.07° (the Fejes Tóth bound is 34.6°).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike


def _fibonacci(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def min_angle(points: ArrayLike) -> float:
    """Smallest angle (rad) between any two of the points (unit vectors)."""
    p = np.asarray(points, float)
    c = np.clip(p @ p.T, -1.0, 1.0)
    np.fill_diagonal(c, -1.0)
    return float(np.arccos(c.max()))


def _normalize(p):
    return p / np.linalg.norm(p, axis=1, keepdims=True)


# (exponent s, iterations, step decay per iteration)
SCHEDULE = ((2.0, 300, 0.997), (8.0, 300, 0.997), (32.0, 300, 0.997), (128.0, 600, 0.997), (512.0, 4000, 0.998))


def _riesz(p, s, iters, decay, step0=0.05):
    """Projected gradient descent on the Riesz s-energy. Forces are scaled by the current
    smallest distance, ``(r_min/r)^(s+2)``, so large s neither overflows nor underflows; the
    largest step is a fixed fraction of the mean spacing and decays geometrically."""
    n = len(p)
    eye = np.eye(n, dtype=bool)
    step = step0 * np.sqrt(4 * np.pi / n)
    for _ in range(iters):
        d = p[:, None, :] - p[None, :, :]
        r = np.sqrt(np.sum(d * d, axis=-1))
        r[eye] = np.inf
        w = (r.min() / r) ** (s + 2)
        f = np.einsum("ij,ijk->ik", w, d)
        f -= np.sum(f * p, axis=1, keepdims=True) * p  # tangential part
        fmax = np.linalg.norm(f, axis=1).max()
        if fmax == 0.0:
            break
        p = _normalize(p + step * f / fmax)
        step *= decay
    return p


@lru_cache(maxsize=32)
def _spread(n: int) -> tuple:
    p = _fibonacci(n)
    if n > 2:
        for s, iters, decay in SCHEDULE:
            p = _riesz(p, s, iters, decay)
    elif n == 2:
        p = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    return tuple(map(tuple, p))


def spread_points(n: int) -> np.ndarray:
    """``n`` unit vectors spread evenly on the sphere (deterministic; cached), shape (n, 3)."""
    if int(n) != n or n < 1:
        raise ValueError(f"the number of hypotheses must be a positive whole number, got {n}")
    return np.array(_spread(int(n)))
