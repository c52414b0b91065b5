"""The one convention of quadest. Every docstring in the package points here.

Quaternions
    Hamilton algebra (``i*j = k``), scalar first ``q = [w, x, y, z]``, unit norm.
    A quaternion ``q_nb`` rotates a vector from the body frame into the navigation frame:
    ``v_n = q_nb ⊗ [0, v_b] ⊗ q_nb*``, equivalently ``v_n = R_nb @ v_b``.
    The same rotation is ``scipy.spatial.transform.Rotation.from_quat(q, scalar_first=True)``.
Frames
    Navigation frame ``n``: north-east-down (NED). Body frame ``b``: forward-right-down (FRD).
Euler angles
    Yaw-pitch-roll, intrinsic ZYX: ``R_nb = Rz(yaw) @ Ry(pitch) @ Rx(roll)``; radians inside
    the library. Arrays of Euler angles are ordered ``[roll, pitch, yaw]``.
Gravity
    ``GRAVITY = 9.80665`` m/s² along ``+z`` of the navigation frame. An accelerometer measures
    specific force ``f_b = R_nb.T @ (a_n - g_n)``, so a level vehicle at rest reads ``[0, 0, -g]``.
Units
    SI everywhere: s, m, m/s, m/s², rad, rad/s, kg, N. A quantity in another unit carries the
    unit in its name (``rate_hz``, ``range_dps``, ``field_ut``). Magnetometer data may be in any
    unit (µT in simulations); its unit is stated in a recording's metadata.
"""

import numpy as np

GRAVITY = 9.80665
"""Standard gravity in m/s²."""

GRAVITY_N = np.array([0.0, 0.0, GRAVITY])
"""Gravity vector in the navigation frame (NED), m/s²."""

# Frame changes as matrices acting on vectors.
ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""``v_ned = ENU_TO_NED @ v_enu`` (its own inverse)."""

FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])
"""``v_frd = FLU_TO_FRD @ v_flu`` (its own inverse)."""
