"""Rotation math on quadest's convention (see :mod:`quadest.conventions`).

Vectorised numpy functions take quaternions of shape ``(4,)`` or ``(N, 4)`` and vectors of
shape ``(3,)`` or ``(N, 3)``. Compiled single-sample kernels for use inside numba code live in
:mod:`quadest.rotation.kernels`.
"""

from quadest.rotation.frames import (
    from_scalar_last,
    quat_enu_flu_to_ned_frd,
    quat_ned_frd_to_enu_flu,
    to_scalar_last,
    vec_enu_to_ned,
    vec_flu_to_frd,
    vec_frd_to_flu,
    vec_ned_to_enu,
)
from quadest.rotation.quaternion import (
    angle_between,
    euler_to_quat,
    matrix_to_quat,
    quat_conj,
    quat_continuous,
    quat_from_rotvec,
    quat_mul,
    quat_normalize,
    quat_rotate,
    quat_to_euler,
    quat_to_matrix,
    quat_to_rotvec,
    skew,
)

__all__ = [
    "angle_between",
    "euler_to_quat",
    "matrix_to_quat",
    "quat_conj",
    "quat_continuous",
    "quat_from_rotvec",
    "quat_mul",
    "quat_normalize",
    "quat_rotate",
    "quat_to_euler",
    "quat_to_matrix",
    "quat_to_rotvec",
    "skew",
    "from_scalar_last",
    "quat_enu_flu_to_ned_frd",
    "quat_ned_frd_to_enu_flu",
    "to_scalar_last",
    "vec_enu_to_ned",
    "vec_flu_to_frd",
    "vec_frd_to_flu",
    "vec_ned_to_enu",
]
