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

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import njit
from quadest.data.files import write_json
from quadest.data.tagged import read_tagged_json
from quadest.rotation import quat_conj, quat_rotate

if TYPE_CHECKING:
    from quadest.data.recording import Recording

FORMAT_TAG = "quadest aero model v1"


def psi(w: ArrayLike) -> np.ndarray:
    """Rate features ψ(ω) of eq 10, ``(..., 3) -> (..., 10)``."""
    w = np.asarray(w, float)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    return np.stack([x, y, z, x * x, y * y, z * z, x * y, y * z, z * x, np.ones_like(x)], axis=-1)


def features(v: ArrayLike, w: ArrayLike) -> np.ndarray:
    """Feature vector φ(v, ω) = ``[v, ‖v‖ v, ψ(ω)]`` of eq 12, ``(..., 16)``."""
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
    """Parameter matrices of eq 9 (body frame FRD): A (3, 3) N s/m, B (3, 3) N s²/m², C (3, 10),
    and the vehicle mass (kg) that turns the force into the accelerometer's specific force (eq 7)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    mass_kg: float = 0.5
    info: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        for name, shape in (("A", (3, 3)), ("B", (3, 3)), ("C", (3, 10))):
            try:
                a = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"aero model {name}: not a numeric matrix") from None
            if a.shape != shape:
                raise ValueError(f"aero model {name}: expected shape {shape}, got {a.shape}")
            if not np.isfinite(a).all():
                raise ValueError(f"aero model {name}: non-finite value")
            object.__setattr__(self, name, a)
        if (
            isinstance(self.mass_kg, bool)
            or not isinstance(self.mass_kg, (int, float))
            or not (math.isfinite(self.mass_kg) and self.mass_kg > 0)
        ):
            raise ValueError(f"aero model: mass must be a positive number of kg, got {self.mass_kg!r}")
        if not isinstance(self.info, dict):
            raise ValueError("aero model: info must be a mapping")

    def specific_force(self, v: ArrayLike, w: ArrayLike) -> np.ndarray:
        """Eq 7 without noise: ``f_c / m`` (m/s², body frame)."""
        return self.force(v, w) / self.mass_kg

    def scaled(self, factors: ArrayLike) -> AeroModel:
        """A copy with every entry of Λ = [A B C] multiplied by ``factors`` (3, 16)."""
        L = self.Lambda * np.asarray(factors, float)
        return AeroModel(L[:, :3], L[:, 3:6], L[:, 6:], self.mass_kg, dict(self.info))

    def to_dict(self) -> dict:
        return {
            "format": FORMAT_TAG,
            "frame": "body FRD (quadest conventions)",
            "mass_kg": self.mass_kg,
            "A": self.A.tolist(),
            "B": self.B.tolist(),
            "C": self.C.tolist(),
            "info": self.info,
        }

    def save(self, path: str | Path) -> Path:
        """Write the JSON file, atomically (nothing half-written is left on a failure)."""
        return write_json(path, self.to_dict())

    @classmethod
    def load(cls, path: str | Path) -> AeroModel:
        d = read_tagged_json(path, FORMAT_TAG, "aero model")
        try:
            return cls(d["A"], d["B"], d["C"], d["mass_kg"], d.get("info", {}))
        except KeyError as exc:
            raise ValueError(f"{path}: aero model lacks {exc}") from None
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None

    @property
    def Lambda(self):
        """Combined parameter matrix Λ = [A B C] of eq 13, (3, 16)."""
        return np.hstack([self.A, self.B, self.C])

    def force(self, v: ArrayLike, w: ArrayLike) -> np.ndarray:
        """Eq 13: ``f_c = Λ φ(v, ω)`` (N, body frame), vectorised."""
        return features(v, w) @ self.Lambda.T

    @classmethod
    def from_z_up(cls, A: ArrayLike, B: ArrayLike, C: ArrayLike) -> AeroModel:
        """Convert matrices given in a body frame with z along the thrust axis (the paper's)."""
        P = np.diag([1.0, -1.0, -1.0])
        # ψ of the paper's rate (P ω) in terms of ψ of ours: odd terms in y or z flip sign
        Q = np.diag([1, -1, -1, 1, 1, 1, -1, 1, -1, 1]).astype(float)
        return cls(P @ np.asarray(A) @ P, P @ np.asarray(B) @ P, P @ np.asarray(C) @ Q)


def free_flight_mask(rec: Recording) -> np.ndarray:
    """Samples where the model applies: after the release of a simulated throw (its metadata),
    otherwise every sample."""
    info = rec.meta.get("scenario_info", {}) if isinstance(rec.meta, dict) else {}
    if "release_time_s" in info:
        return rec.t >= info["release_time_s"]
    return np.ones(len(rec), bool)


def fit_aero(recordings: Iterable[Recording], mass_kg: float, masks: Sequence[ArrayLike] | None = None) -> AeroModel:
    """Eq 14: the least-squares Λ* of ``m z_acc ≈ Λ φ(v, ω)`` over the samples of recordings that
    carry true velocity and attitude (``true_vel``, ``true_q``). The body velocity is the true
    navigation-frame velocity rotated into the body; ω is the gyroscope sample (as in the paper).
    ``masks`` selects samples per recording (default: :func:`free_flight_mask`).

    The fit's RMS residual (m/s², per axis) and sample count are in ``model.info``."""
    rows, targets, names = [], [], []
    for k, rec in enumerate(recordings):
        if rec.true_vel is None or rec.true_q is None:
            raise ValueError(f"recording {k}: fitting needs true_vel and true_q")
        mask = free_flight_mask(rec) if masks is None else np.asarray(masks[k], bool)
        ok = mask & np.isfinite(rec.true_vel).all(axis=1) & np.isfinite(rec.true_q).all(axis=1)
        vb = quat_rotate(quat_conj(rec.true_q[ok]), rec.true_vel[ok])
        rows.append(features(vb, rec.gyr[ok]))
        targets.append(mass_kg * rec.acc[ok])
        names.append(str(rec.meta.get("source", k)) + (f" seed {rec.meta['seed']}" if "seed" in rec.meta else ""))
    Phi, Y = np.vstack(rows), np.vstack(targets)
    if len(Phi) < 16 * 3:
        raise ValueError(f"fitting needs at least 48 samples, got {len(Phi)}")
    Lam_T, *_ = np.linalg.lstsq(Phi, Y, rcond=None)  # Φ Λᵀ ≈ m z
    L = Lam_T.T
    resid = (Y - Phi @ Lam_T) / mass_kg
    info = {
        "samples": int(len(Phi)),
        "recordings": names,
        "residual_rms_mps2": np.sqrt(np.mean(resid**2, axis=0)).tolist(),
        "condition_number": float(np.linalg.cond(Phi)),
    }
    return AeroModel(L[:, :3], L[:, 3:6], L[:, 6:], mass_kg, info)
