"""The geometric tracking controller on SE(3) of Lee, Leok & McClamroch, "Geometric tracking
control of a quadrotor UAV on SE(3)", IEEE CDC 2010 (the nominal controller), on
quadest's conventions (NED, FRD, ``q_nb``), with rotor-speed allocation for a quadrotor.

With ``e_p = p − p_d``, ``e_v = v − v_d`` and gains per unit mass (as RotorPy's ``SE3Control``):

- desired force (navigation frame): ``F_d = m (−k_p e_p − k_v e_v + a_d − g e_z)`` (eq 12; the
  rotors push against gravity, which is ``+g e_z`` in NED);
- collective thrust ``T = −F_d · (R e_z)``: the projection onto the current thrust axis, which is
  ``−R e_z`` (the rotors push along body −z);
- desired attitude: body z down along ``−F_d/‖F_d‖``; ``y_d = z_d × x_c/‖·‖`` with the heading
  ``x_c = [cos ψ_d, sin ψ_d, 0]``; ``x_d = y_d × z_d`` (eq 13-14);
- attitude error ``e_R = ½ (R_dᵀ R − Rᵀ R_d)^∨`` and rate error ``e_ω = ω`` (a hover or slow
  trajectory: the desired rate is taken as zero, which the paper's feed-forward would refine);
- moment ``M = J (−k_R e_R − k_ω e_ω) + ω × J ω`` (eq 16 with gains per unit inertia, as RotorPy).

Allocation: rotor thrusts ``t = A⁻¹ [T, M_x, M_y, M_z]`` with, for rotor i at ``r_i`` turning
in sense ``s_i``, ``T = Σ t_i``, ``M_x = −Σ r_i,y t_i``, ``M_y = Σ r_i,x t_i``,
``M_z = −Σ s_i (k_m/k_f) t_i`` (the moments of thrusts along −z, and the reaction torques);
then ``Ω_i = √(max(t_i, 0)/k_f)``. ``A⁻¹`` is computed once (:func:`allocation`). When the
rotors cannot give all of it, the yaw moment yields first: ``M_z`` is scaled down (to zero if
need be) until every rotor's thrust lies within ``[0, k_f Ω_max²]``.

In a landing's descent (``limited``) the thrust keeps PX4's limits instead
(:func:`limited_thrust`): never upside down, tilted at most 45°, at least 0.12 of the rotors' most
(at most half the weight).
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from quadest._jit import NO_ALLOCATION, njit
from quadest.models.multirotor import MultirotorParams
from quadest.records import check, check_triples, describe, param
from quadest.rotation.kernels import rot_entries

Gains = namedtuple("Gains", ["k_p", "k_v", "k_R", "k_w", "alloc_inv", "k_f", "t_max"])
"""What the compiled controller reads (built by :meth:`SE3Params.gains`)."""


@dataclass(frozen=True)
class SE3Params:
    k_p: tuple = param(
        (6.5, 6.5, 15.0),
        "1/s²",
        "position gain per unit mass (north, east, down)",
        "RotorPy SE3Control, Hummingbird gains (as quoted in shared/docs/anchors.md)",
    )
    k_v: tuple = param(
        (4.0, 4.0, 9.0),
        "1/s",
        "velocity gain per unit mass",
        "RotorPy SE3Control, Hummingbird gains (as quoted in shared/docs/anchors.md)",
    )
    k_R: float = param(
        544.0,
        "1/s²",
        "attitude gain per unit inertia",
        "RotorPy SE3Control, Hummingbird gains (as quoted in shared/docs/anchors.md)",
        bounds="[0, 1e6]",
    )
    k_w: float = param(
        46.64,
        "1/s",
        "rate gain per unit inertia",
        "RotorPy SE3Control, Hummingbird gains (as quoted in shared/docs/anchors.md)",
        bounds="[0, 1e5]",
    )

    def __post_init__(self):
        check(self, "se3")
        check_triples(self, "se3", "k_p", "k_v")

    def gains(self, vehicle: MultirotorParams) -> Gains:
        return Gains(
            np.asarray(self.k_p, float),
            np.asarray(self.k_v, float),
            float(self.k_R),
            float(self.k_w),
            allocation(vehicle),
            float(vehicle.k_f),
            float(vehicle.k_f * vehicle.omega_max**2),
        )

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)


def allocation(vehicle: MultirotorParams) -> np.ndarray:
    """``A⁻¹`` mapping ``[T, M_x, M_y, M_z]`` to rotor thrusts (module doc); quadrotors only."""
    pos = np.asarray(vehicle.rotor_pos, float)
    if len(pos) != 4:
        raise ValueError(f"the SE(3) allocation needs 4 rotors, the vehicle has {len(pos)}")
    A = np.vstack([np.ones(4), -pos[:, 1], pos[:, 0], -np.asarray(vehicle.spin, float) * vehicle.k_m / vehicle.k_f])
    if abs(np.linalg.det(A)) < 1e-12:
        raise ValueError("the rotor layout cannot produce independent roll, pitch and yaw moments")
    return np.linalg.inv(A)


@njit(cache=True, inline="always")
def attitude_error(R, xd, yd, zd):
    """``e_R = ½ (R_dᵀ R − Rᵀ R_d)^∨`` with ``R_d`` of columns ``xd, yd, zd``."""
    e0 = e1 = e2 = 0.0
    for k in range(3):
        e0 += zd[k] * R[k][1] - R[k][2] * yd[k]
        e1 += xd[k] * R[k][2] - R[k][0] * zd[k]
        e2 += yd[k] * R[k][0] - R[k][1] * xd[k]
    return 0.5 * e0, 0.5 * e1, 0.5 * e2


THRUST_MIN = 0.12
"""The least collective thrust of :func:`limited_thrust`, as a share of the rotors' most (PX4's
MPC_THR_MIN), at most half the weight (:func:`thrust_floor`)."""

TILT_MAX = np.radians(45.0)
"""The largest tilt :func:`limited_thrust` asks for (PX4's MPC_TILTMAX_AIR)."""


@njit(cache=True, **NO_ALLOCATION)
def se3_command(x, p_d, v_d, a_d, yaw_d, gains, vehicle, cmd, limited=False):
    """Rotor speed commands (rad/s) into ``cmd`` for state ``x`` (true or estimated) and the
    reference position, velocity, acceleration (NED) and heading (no allocation: it runs every
    sample of every flight); ``limited``: the thrust's direction and size within an autopilot's
    limits (:func:`limited_thrust`)."""
    R = rot_entries(x[6], x[7], x[8], x[9])
    f = (
        vehicle.mass * (-gains.k_p[0] * (x[0] - p_d[0]) - gains.k_v[0] * (x[3] - v_d[0]) + a_d[0]),
        vehicle.mass * (-gains.k_p[1] * (x[1] - p_d[1]) - gains.k_v[1] * (x[4] - v_d[1]) + a_d[1]),
        vehicle.mass * (-gains.k_p[2] * (x[2] - p_d[2]) - gains.k_v[2] * (x[5] - v_d[2]) + a_d[2])
        - vehicle.mass * vehicle.gravity,
    )
    if limited:
        weight = vehicle.mass * vehicle.gravity
        thrust, zd = limited_thrust(f, weight, thrust_floor(weight, gains.alloc_inv.shape[0] * gains.t_max))
    else:
        thrust = -(f[0] * R[0][2] + f[1] * R[1][2] + f[2] * R[2][2])
        # desired attitude: body z down along −F_d
        nF = np.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
        zd = (-f[0] / nF, -f[1] / nF, -f[2] / nF) if nF > 1e-9 else (0.0, 0.0, 1.0)
    xc0, xc1 = np.cos(yaw_d), np.sin(yaw_d)
    y0, y1, y2 = zd[1] * 0.0 - zd[2] * xc1, zd[2] * xc0 - zd[0] * 0.0, zd[0] * xc1 - zd[1] * xc0
    ny = np.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    if ny < 1e-9:  # thrust axis horizontal along the heading: keep the current body y
        y0, y1, y2, ny = R[0][1], R[1][1], R[2][1], 1.0
    yd = (y0 / ny, y1 / ny, y2 / ny)
    xd = (yd[1] * zd[2] - yd[2] * zd[1], yd[2] * zd[0] - yd[0] * zd[2], yd[0] * zd[1] - yd[1] * zd[0])
    eR0, eR1, eR2 = attitude_error(R, xd, yd, zd)
    w0, w1, w2 = x[10], x[11], x[12]
    J0, J1, J2 = vehicle.inertia[0], vehicle.inertia[1], vehicle.inertia[2]
    M0 = J0 * (-gains.k_R * eR0 - gains.k_w * w0) + (w1 * J2 * w2 - w2 * J1 * w1)
    M1 = J1 * (-gains.k_R * eR1 - gains.k_w * w1) + (w2 * J0 * w0 - w0 * J2 * w2)
    M2 = J2 * (-gains.k_R * eR2 - gains.k_w * w2) + (w0 * J1 * w1 - w1 * J0 * w0)
    mix(thrust, M0, M1, M2, gains, cmd)


@njit(cache=True, inline="always")
def thrust_floor(weight, most):
    """The least collective thrust (N) of :func:`limited_thrust` for a vehicle of ``weight`` whose
    rotors make at most ``most`` (N): :data:`THRUST_MIN` of ``most``, at most half the weight (PX4
    asks for MPC_THR_MIN below the hover's thrust; a vehicle of thrust-to-weight 10 would be set up
    with a lower one, else it could not descend)."""
    return min(THRUST_MIN * most, 0.5 * weight)


@njit(cache=True, inline="always")
def limited_thrust(f, weight, thrust_min):
    """The collective thrust and desired body z axis for the desired force ``f`` (NED) as PX4's
    position controller makes them (PositionControl::_accelerationControl): the axis from the
    horizontal force and the weight, never from a downward demand (so never upside down), tilted
    at most :data:`TILT_MAX`; the thrust the vertical force asks for along it, at least
    ``thrust_min``."""
    z0, z1, z2 = -f[0], -f[1], weight
    lean, most = np.sqrt(z0 * z0 + z1 * z1), weight * np.tan(TILT_MAX)
    if lean > most:
        z0, z1 = z0 * most / lean, z1 * most / lean
    n = np.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
    zd = (z0 / n, z1 / n, z2 / n)
    return max(-f[2] / zd[2], thrust_min), zd


@njit(cache=True)
def mix(thrust, M0, M1, M2, gains, cmd):
    """Rotor speed commands for a collective thrust and body moments (module doc): the exact
    inverse of the quadrotor's map, the yaw moment yielding first when the rotors cannot give
    everything."""
    # yaw yields first: the largest share of M_z (down to none) that keeps every rotor within
    # [0, t_max] given thrust, roll and pitch (as autopilots' mixers do)
    lam = 1.0
    for i in range(4):
        base = gains.alloc_inv[i, 0] * thrust + gains.alloc_inv[i, 1] * M0 + gains.alloc_inv[i, 2] * M1
        yaw = gains.alloc_inv[i, 3] * M2
        if base + lam * yaw < 0.0 and yaw < 0.0:
            lam = max(0.0, min(lam, -base / yaw))
        elif base + lam * yaw > gains.t_max and yaw > 0.0:
            lam = max(0.0, min(lam, (gains.t_max - base) / yaw))
    for i in range(4):
        t = (
            gains.alloc_inv[i, 0] * thrust
            + gains.alloc_inv[i, 1] * M0
            + gains.alloc_inv[i, 2] * M1
            + gains.alloc_inv[i, 3] * M2 * lam
        )
        cmd[i] = np.sqrt(max(t, 0.0) / gains.k_f)
