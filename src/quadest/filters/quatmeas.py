"""The QUKF paper's measurement: a quaternion from accelerometer and magnetometer (eqs 10-15).

Liang et al. 2023 build the measurement ``Z = q̃`` from roll and pitch of the accelerometer
(eq 11) and the tilt-compensated magnetometer heading (eq 14), through the ZYX conversion eq 15.
Two printed equations do not follow from the paper's own model and are corrected here:

- eq 11 prints ``φ = −arcsin(a_x/g), θ = arctan(a_y/a_z)``: roll and pitch are swapped. From
  eq 10 (``a = g [2(q1q3 − q0q2), 2(q2q3 + q0q1), q0² − q1² − q2² + q3²]``, their accelerometer
  reading +g up at rest) roll is ``atan2(a_y, a_z)`` and pitch ``−arcsin(a_x/g)``. In quadest's
  convention (specific force ``−g Rᵀ e_z``): ``roll = atan2(−f_y, −f_z)``,
  ``pitch = atan2(f_x, √(f_y² + f_z²))``.
- eq 14 prints the numerator ``m_y cos φ − m_z sin φ``; eq 13 two lines above gives
  ``m_x^n sin ψ = m_z sin φ − m_y cos φ``, so the heading is
  ``ψ = atan2(m_z sin φ − m_y cos φ, m_x cos θ + m_y sin φ sin θ + m_z cos φ sin θ)``.

Both are pinned by tests: the measurement quaternion of noise-free samples equals the truth.
"""

import numpy as np

from quadest._jit import njit
from quadest.filters.common import euler_to_q, finite3, mag_heading, norm3, q_to_euler, tilt_from_acc


@njit(cache=True)
def measurement_quaternion(acc, mag, q_pred, use_mag):
    """Eq 15 of roll/pitch from ``acc`` (eq 11, corrected) and heading from ``mag`` (eq 14,
    corrected); without a magnetometer sample the heading is the prediction's. The sign is
    chosen to agree with ``q_pred``. Returns ``(z, ok)``; ``ok`` is False without a usable
    accelerometer sample."""
    z = np.empty(4)
    if not finite3(acc) or norm3(acc) == 0.0:
        return z, False
    roll, pitch = tilt_from_acc(acc)
    if use_mag and finite3(mag) and norm3(mag) > 0.0:
        yaw = mag_heading(mag, roll, pitch)
    else:
        yaw = q_to_euler(q_pred)[2]
    z[:] = euler_to_q(roll, pitch, yaw)
    if z[0] * q_pred[0] + z[1] * q_pred[1] + z[2] * q_pred[2] + z[3] * q_pred[3] < 0.0:
        z[:] = -z
    return z, True
