"""Madgwick's gradient-descent orientation filter, MARG and IMU forms.

S. O. H. Madgwick, A. J. L. Harrison, R. Vaidyanathan, "Estimation of IMU and MARG orientation
using a gradient descent algorithm", ICORR 2011 (AFCKF ref [11]).

The paper's earth frame has z up (gravity reference ``[0, 0, 1]``, met by the up-pointing
specific force) and x towards magnetic north: north-west-up. The gradient step is taken in that
frame, on ``q' = q_F ⊗ q_nb`` with ``q_F = [0, 1, 0, 0]`` (NED -> NWU, a half turn about x), and
the result is mapped back to NED. This matters: the objective is written in the unit-quaternion
form of the rotation and its 4-D gradient is normalised including its radial part, so an NED
rewrite that is equal on the unit sphere takes slightly different steps (0.25° apart after 20 s).
ahrs's implementation of the paper gives the same attitude in NWU (tested to 1e-9 rad).
"""

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.filters.base import Estimator, Params, coefficient_offsets, params_record
from quadest.filters.common import (
    BASE,
    admit,
    admitted_mag,
    finite3,
    gravity_objective,
    norm3,
    prepare,
    publish,
    run_and_stream,
)
from quadest.records import param
from quadest.rotation.kernels import normalize_s, qdot_s, rotate_s


@dataclass(frozen=True)
class MadgwickParams(Params):
    use_mag: bool = param(
        True,
        "-",
        "use the magnetometer (MARG form) when samples are present",
        "quadest: 9-axis when samples are present",
    )
    beta_marg: float = param(
        0.041,
        "-",
        "gradient-descent gain β in the MARG form",
        "Madgwick 2010 report / reference implementation",
        bounds="[0, 10]",
    )
    beta_imu: float = param(
        0.033,
        "-",
        "gradient-descent gain β in the IMU (6-axis) form",
        "Madgwick 2010 report / reference implementation",
        bounds="[0, 10]",
    )


PARAM = Record = params_record(MadgwickParams)
Coefficients = namedtuple("Coefficients", ["beta"])
COEF = coefficient_offsets(Coefficients)


def coefficients(params: MadgwickParams) -> Coefficients:
    """β of the form in use (MARG with the magnetometer, IMU without)."""
    return Coefficients(float(params.beta_marg if params.use_mag else params.beta_imu))


@njit(cache=True)
def madgwick_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    use_mag = p[PARAM.use_mag] != 0.0
    diag[0] = 0.0
    if not prepare(x, acc, mag, use_mag):
        return
    beta = c[COEF.beta]
    # the paper's z-up frame: q' = q_F ⊗ q_nb = [−x, w, −z, y]
    qw, qx, qy, qz = -x[1], x[0], -x[3], x[2]
    # eq 12: q̇_ω = ½ q ⊗ [0, ω]
    d0 = d1 = d2 = d3 = 0.0
    if finite3(gyr):
        d0, d1, d2, d3 = qdot_s(qw, qx, qy, qz, gyr[0], gyr[1], gyr[2])
    an = norm3(acc) if finite3(acc) else 0.0
    if an > 0.0:
        # up-pointing specific force; J_gᵀ f_g (eqs 25-26)
        f0, f1, f2, J0, J1, J2 = gravity_objective(qw, qx, qy, qz, acc[0] / an, acc[1] / an, acc[2] / an)
        s0 = J0[0] * f0 + J1[0] * f1 + J2[0] * f2
        s1 = J0[1] * f0 + J1[1] * f1 + J2[1] * f2
        s2 = J0[2] * f0 + J1[2] * f1 + J2[2] * f2
        s3 = J0[3] * f0 + J1[3] * f1 + J2[3] * f2
        mn = norm3(mag) if (use_mag and finite3(mag)) else 0.0
        if mn > 0.0:
            mx, my, mz = mag[0] / mn, mag[1] / mn, mag[2] / mn
            # eq 45: h = q ⊗ m ⊗ q*, eq 46: b = [√(hx² + hy²), 0, hz]
            hx, hy, hz = rotate_s(qw, qx, qy, qz, mx, my, mz)
            bx = np.sqrt(hx * hx + hy * hy)
            bz = hz
            f3 = 2.0 * bx * (0.5 - qy * qy - qz * qz) + 2.0 * bz * (qx * qz - qw * qy) - mx
            f4 = 2.0 * bx * (qx * qy - qw * qz) + 2.0 * bz * (qw * qx + qy * qz) - my
            f5 = 2.0 * bx * (qw * qy + qx * qz) + 2.0 * bz * (0.5 - qx * qx - qy * qy) - mz
            # J_bᵀ f_b (eq 32)
            s0 += -2.0 * bz * qy * f3 + (-2.0 * bx * qz + 2.0 * bz * qx) * f4 + 2.0 * bx * qy * f5
            s1 += 2.0 * bz * qz * f3 + (2.0 * bx * qy + 2.0 * bz * qw) * f4 + (2.0 * bx * qz - 4.0 * bz * qx) * f5
            s2 += (
                (-4.0 * bx * qy - 2.0 * bz * qw) * f3
                + (2.0 * bx * qx + 2.0 * bz * qz) * f4
                + (2.0 * bx * qw - 4.0 * bz * qy) * f5
            )
            s3 += (-4.0 * bx * qz + 2.0 * bz * qx) * f3 + (-2.0 * bx * qw + 2.0 * bz * qy) * f4 + 2.0 * bx * qx * f5
            diag[0] = 2.0
        else:
            diag[0] = 1.0
        sn = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
        if sn > 0.0:
            # eq 33: q̇ = q̇_ω − β ∇f/|∇f|
            d0 -= beta * s0 / sn
            d1 -= beta * s1 / sn
            d2 -= beta * s2 / sn
            d3 -= beta * s3 / sn
    # eq 13: q_t = q_{t−1} + q̇ Δt, normalised; back to NED: q_nb = q_F* ⊗ q' = [q'x, −q'w, q'z, −q'y]
    q0, q1, q2, q3 = normalize_s(qw + d0 * dt, qx + d1 * dt, qy + d2 * dt, qz + d3 * dt)
    x[0], x[1], x[2], x[3] = q1, -q0, q3, -q2
    publish(x)


madgwick_run, madgwick_stream = run_and_stream(madgwick_step)


class Madgwick(Estimator):
    """Madgwick's filter. Diagnostic ``correction``: 0 none, 1 accelerometer, 2 accelerometer
    and magnetometer."""

    name = "madgwick"
    Params = MadgwickParams
    Record = Record
    coefficients = staticmethod(coefficients)
    state_size = BASE
    diag_names = ("correction",)
    step = staticmethod(madgwick_step)
    batch = staticmethod(madgwick_run)
    stream = staticmethod(madgwick_stream)
