"""Smooth random signals: sums of sinusoids with analytic derivatives of any order."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from quadest.sim.jets import Jet


@dataclass(frozen=True)
class Sinusoids:
    """``x(t) = Σ_k amp[k] sin(w[k] t + phase[k])`` per dimension; ``amp, phase`` are (K, D)."""

    w: np.ndarray
    amp: np.ndarray
    phase: np.ndarray

    @classmethod
    def random(cls, rng, band_hz, components: int, dims: int, power: float = 2.0):
        """Frequencies uniform in ``band_hz``, random phases, amplitude ∝ w^-power (so that, with
        power 2, every component contributes alike to the acceleration)."""
        lo, hi = band_hz
        if not 0 < lo <= hi:
            raise ValueError(f"frequency band {band_hz} must satisfy 0 < low <= high")
        w = 2 * np.pi * rng.uniform(lo, hi, size=components)
        amp = rng.uniform(0.5, 1.0, size=(components, dims)) * w[:, None] ** -power
        phase = rng.uniform(0, 2 * np.pi, size=(components, dims))
        return cls(w, amp, phase)

    def scaled(self, factor) -> Sinusoids:
        return Sinusoids(self.w, self.amp * np.asarray(factor, float), self.phase)

    def deriv(self, t, k: int = 0):
        """The k-th time derivative at times ``t``, shape (N, D)."""
        t = np.asarray(t, float)
        arg = t[:, None] * self.w[None, :]
        out = np.zeros((len(t), self.amp.shape[1]))
        for d in range(self.amp.shape[1]):
            out[:, d] = np.sin(arg + self.phase[:, d] + k * np.pi / 2) @ (self.amp[:, d] * self.w**k)
        return out

    def jet(self, t, k0: int = 0) -> Jet:
        """Jet of derivatives ``(k0, k0 + 1, k0 + 2)``, shape (N, D)."""
        return Jet(self.deriv(t, k0), self.deriv(t, k0 + 1), self.deriv(t, k0 + 2))

    def peak(self, duration, k: int = 0, dt: float = 0.01, t0: float = 0.0):
        """Largest norm over dimensions of the k-th derivative on a grid over ``[t0, duration]``."""
        t = np.arange(t0, max(duration, t0 + dt) + dt, dt)
        return float(np.linalg.norm(self.deriv(t, k), axis=1).max())

    def rms(self, duration, k: int = 0, dt: float = 0.01):
        t = np.arange(0.0, max(duration, dt) + dt, dt)
        return float(np.sqrt(np.mean(np.sum(self.deriv(t, k) ** 2, axis=1))))


@dataclass(frozen=True)
class RampedSinusoids:
    """An acceleration that starts at ``t0`` from rest, position and velocity zero there.

    ``a(x) = Σ_k A_k sin(w_k x + θ_k) (1 − e^{−x/τ})²`` for ``x = t − t0 >= 0``, written as
    ``Im Σ_j c_j e^{μ_j x}`` with ``(c, μ) ∈ {(A e^{iθ}, iw), (−2A e^{iθ}, iw − 1/τ),
    (A e^{iθ}, iw − 2/τ)}``, so that every derivative and both integrals are exact:
    position ``Im c (e^{μx} − 1 − μx)/μ²``, velocity ``Im c (e^{μx} − 1)/μ``,
    k-th derivative of the acceleration ``Im c μ^k e^{μx}``. The squared ramp makes acceleration
    and jerk continuous at ``t0``. ``θ = ±π/2`` keeps the sinusoids from adding a steady drift.
    """

    c: np.ndarray  # (M, D) complex
    mu: np.ndarray  # (M,) complex
    t0: float

    @classmethod
    def random(cls, rng, band_hz, components, dims, t0, tau, scale_dims=None):
        lo, hi = band_hz
        w = 2 * np.pi * rng.uniform(lo, hi, size=components)
        A = rng.uniform(0.5, 1.0, size=(components, dims))
        if scale_dims is not None:
            A = A * np.asarray(scale_dims, float)
        theta = np.where(rng.random((components, dims)) < 0.5, np.pi / 2, -np.pi / 2)
        base = A * np.exp(1j * theta)
        c = np.concatenate([base, -2 * base, base])
        mu = np.concatenate([1j * w, 1j * w - 1 / tau, 1j * w - 2 / tau])
        return cls(c, mu, float(t0))

    def scaled(self, factor) -> RampedSinusoids:
        return RampedSinusoids(self.c * factor, self.mu, self.t0)

    def deriv(self, t, k: int = 0):
        x = np.maximum(np.asarray(t, float) - self.t0, 0.0)
        e = np.exp(np.outer(x, self.mu))  # (N, M)
        if k == 0:
            F = (e - 1 - np.outer(x, self.mu)) / self.mu**2
        elif k == 1:
            F = (e - 1) / self.mu
        else:
            F = e * self.mu ** (k - 2)
        out = np.imag(F @ self.c)
        out[np.asarray(t) < self.t0] = 0.0
        return out

    def jet(self, t, k0: int = 0) -> Jet:
        return Jet(self.deriv(t, k0), self.deriv(t, k0 + 1), self.deriv(t, k0 + 2))

    def peak(self, duration, k: int = 0, dt: float = 0.01):
        t = np.arange(self.t0, max(duration, self.t0 + dt) + dt, dt)
        return float(np.linalg.norm(self.deriv(t, k), axis=1).max())
