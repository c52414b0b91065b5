"""Conversions between quadest's frames (NED / FRD) and the other common ones (ENU / FLU).

Both frame changes are proper rotations by 180°:
ENU -> NED about the axis ``(1, 1, 0)/√2``, FLU -> FRD about the body x axis. A quaternion
``q_nb`` given for an ENU navigation frame and an FLU body frame becomes quadest's ``q_nb`` by
``q_T ⊗ q ⊗ q_F`` with ``q_T = [0, 1/√2, 1/√2, 0]`` and ``q_F = [0, 1, 0, 0]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from quadest.conventions import ENU_TO_NED, FLU_TO_FRD
from quadest.rotation.quaternion import quat_mul

_S = np.sqrt(0.5)
_Q_ENU_TO_NED = np.array([0.0, _S, _S, 0.0])
_Q_FLU_TO_FRD = np.array([0.0, 1.0, 0.0, 0.0])


def vec_enu_to_ned(v: ArrayLike) -> np.ndarray:
    """Navigation-frame vector(s) from east-north-up to north-east-down."""
    return np.asarray(v, dtype=float) @ ENU_TO_NED.T


vec_ned_to_enu = vec_enu_to_ned  # the change is its own inverse


def vec_flu_to_frd(v: ArrayLike) -> np.ndarray:
    """Body-frame vector(s) from forward-left-up to forward-right-down."""
    return np.asarray(v, dtype=float) @ FLU_TO_FRD.T


vec_frd_to_flu = vec_flu_to_frd


def quat_enu_flu_to_ned_frd(q: ArrayLike) -> np.ndarray:
    """``q_nb`` of an ENU navigation frame and FLU body frame -> quadest's NED/FRD ``q_nb``."""
    return quat_mul(quat_mul(_Q_ENU_TO_NED, np.asarray(q, dtype=float)), _Q_FLU_TO_FRD)


def quat_ned_frd_to_enu_flu(q: ArrayLike) -> np.ndarray:
    """quadest's NED/FRD ``q_nb`` -> ``q_nb`` of an ENU navigation frame and FLU body frame."""
    return quat_mul(quat_mul(_Q_ENU_TO_NED, np.asarray(q, dtype=float)), _Q_FLU_TO_FRD)


def to_scalar_last(q: ArrayLike) -> np.ndarray:
    """``[w, x, y, z]`` -> ``[x, y, z, w]`` (scipy's default, ROS messages)."""
    return np.roll(np.asarray(q, dtype=float), -1, axis=-1)


def from_scalar_last(q: ArrayLike) -> np.ndarray:
    """``[x, y, z, w]`` -> quadest's ``[w, x, y, z]``."""
    return np.roll(np.asarray(q, dtype=float), 1, axis=-1)
