"""The controller that takes over a recovered vehicle (after a throw or a tumble): from any
attitude a reduced-attitude controller (angle and axis, as the recovery paper's ref [19])
brings the thrust axis up, since SE(3)'s attitude error vanishes towards 180°; once the thrust
axis is within ``upright_rad`` of where the velocity and altitude loop wants it, SE(3) holds
zero velocity and the held height (the paper's velocity and altitude loop). It also says
whether the attitude control error is below ``β3`` (section V-B: the nominal estimator's
accelerometer update waits for it)."""

from __future__ import annotations

import numpy as np

from quadest._jit import njit
from quadest.control.se3 import mix, se3_command
from quadest.rotation.kernels import rot_matrix

UPRIGHT_RATE_GAIN = 8.0  # 1/s: rate commanded per radian of tilt error (chosen: turns 180° in well under 0.5 s)
UPRIGHT_RATE_MAX = 20.0  # rad/s (chosen: within the gyroscope's range and the motors' authority)
UPRIGHT_THRUST_MIN = 0.2  # of the weight: kept for the moments while the thrust axis points away (chosen)


@njit(cache=True)
def recovery_command(xh, p_d, v_d, a_d, yaw_d, gains, vehicle, beta3, upright_rad, cmd):
    """Rotor speed commands into ``cmd`` for the estimated state ``xh`` holding the height
    ``p_d[2]`` and zero velocity (no horizontal position: the velocity loop); returns whether
    the attitude control error (desired against estimated thrust axis) is below ``beta3``."""
    R = rot_matrix(xh[6:10])
    f0 = -gains.k_v[0] * xh[3]
    f1 = -gains.k_v[1] * xh[4]
    f2 = -gains.k_p[2] * (xh[2] - p_d[2]) - gains.k_v[2] * xh[5] - vehicle.gravity
    nf = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    cosang = -(f0 * R[0, 2] + f1 * R[1, 2] + f2 * R[2, 2]) / max(nf, 1e-9)
    if cosang > np.cos(upright_rad):
        se3_command(xh, p_d, v_d, a_d, yaw_d, gains, vehicle, cmd)
    else:
        upright(xh, R, -f0 / nf, -f1 / nf, -f2 / nf, nf, cosang, gains, vehicle, cmd)
    return cosang > np.cos(beta3)


@njit(cache=True)
def upright(xh, R, zd0, zd1, zd2, f_norm, cosang, gains, vehicle, cmd):
    """Bring the thrust axis up from any attitude: reduced-attitude control by angle and axis.
    The desired body z (down) axis ``z_d`` (navigation frame, opposite the desired thrust), in
    the body ``z_b = Rᵀ z_d``; the rate ``ω_d = min(k α, ω_max) (e_z × z_b)/‖e_z × z_b‖``
    (``ż_b = z_b × ω`` then turns ``z_b`` towards ``e_z``) with the tilt error ``α`` (any
    horizontal axis when upside down), no yaw rate; the moment ``J k_ω (ω_d − ω) + ω × J ω``;
    thrust the desired force along the thrust axis, at least a fifth of the weight."""
    zb0 = R[0, 0] * zd0 + R[1, 0] * zd1 + R[2, 0] * zd2
    zb1 = R[0, 1] * zd0 + R[1, 1] * zd1 + R[2, 1] * zd2
    alpha = np.arccos(min(1.0, max(-1.0, cosang)))
    a0, a1 = -zb1, zb0  # e_z × z_b (its z part is 0)
    na = np.sqrt(a0 * a0 + a1 * a1)
    if na < 1e-6:
        a0, a1, na = 1.0, 0.0, 1.0
    rate = min(UPRIGHT_RATE_GAIN * alpha, UPRIGHT_RATE_MAX)
    wd0, wd1 = rate * a0 / na, rate * a1 / na
    w0, w1, w2 = xh[10], xh[11], xh[12]
    J0, J1, J2 = vehicle.inertia[0], vehicle.inertia[1], vehicle.inertia[2]
    M0 = J0 * gains.k_w * (wd0 - w0) + (w1 * J2 * w2 - w2 * J1 * w1)
    M1 = J1 * gains.k_w * (wd1 - w1) + (w2 * J0 * w0 - w0 * J2 * w2)
    M2 = J2 * gains.k_w * (0.0 - w2) + (w0 * J1 * w1 - w1 * J0 * w0)
    thrust = max(vehicle.mass * f_norm * cosang, UPRIGHT_THRUST_MIN * vehicle.mass * vehicle.gravity)
    mix(thrust, M0, M1, M2, gains, cmd)
