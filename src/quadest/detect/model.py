"""The rotor-failure detector's model of the vehicle (docs/detection.md): its coefficients
packed from a vehicle's parameters (the detector's own, never the simulated truth's), the
motors, each rotor's thrust and moment, the body's damping and drag, the accelerometer's lever
arm and the air's drag read from it."""

from __future__ import annotations

import numpy as np

from quadest._jit import njit
from quadest.detect.layout import F_TAU, MAX_ROTORS, MODEL, STATE
from quadest.detect.params import PARAM
from quadest.records import pack


def model_coefficients(vehicle, imu_position=(0.0, 0.0, 0.0), drag_moment=((0.0, 0.0), (0.0, 0.0))) -> np.ndarray:
    """The detector's model of a vehicle (a :class:`~quadest.models.multirotor.MultirotorParams`:
    the detector's own, never the simulated truth's), of where its accelerometer sits
    (``imu_position``, m from the centre of mass, body axes) and of the drag's moments
    (``drag_moment``: roll's and pitch's angular acceleration per specific force along x and y,
    rad/s² per m/s², as ``quadest identify`` fits them; :func:`drag_moments`) packed for the
    compiled step."""
    pos, spin = np.asarray(vehicle.rotor_pos, float), np.asarray(vehicle.spin, float)
    n = len(pos)
    if not 2 <= n <= MAX_ROTORS:
        raise ValueError(f"detector: {n} rotors; it handles 2 to {MAX_ROTORS}")
    g = np.zeros((MAX_ROTORS, 3))
    g[:n] = np.column_stack([-pos[:, 1], pos[:, 0], -spin * vehicle.k_m / vehicle.k_f])
    values = [n, vehicle.mass_kg, *vehicle.inertia, vehicle.k_f, vehicle.k_z, vehicle.k_h, vehicle.motor_tau_s]
    values += [vehicle.omega_min]
    values += [vehicle.omega_max, vehicle.omega_dot_max, *vehicle.damping, *vehicle.rot_drag, *g.ravel()]
    ip_s = np.zeros(MAX_ROTORS)
    ip_s[:n] = vehicle.rotor_inertia * spin
    imu = np.asarray(imu_position, float)
    if imu.shape != (3,) or not np.isfinite(imu).all():
        raise ValueError(f"detector: imu_position must be three finite values (m), got {imu_position!r}")
    drag = np.asarray(drag_moment, float)
    if drag.shape != (2, 2) or not np.isfinite(drag).all():
        raise ValueError(f"detector: drag_moment must be 2 rows (roll, pitch) of 2 finite values, got {drag_moment!r}")
    return pack(values + list(ip_s) + list(vehicle.body_drag[:2]) + list(imu) + list(drag.ravel()))


@njit(cache=True, inline="always")
def drag_moments(x, c):
    """The angular acceleration about x and y of the drag acting off the centre of mass (the
    rotors' drag at their hubs, the body's at its centre of pressure), linear in the low-passed
    specific force along x and y (``STATE.f_lp``; rad/s²)."""
    fx, fy = x[STATE.f_lp], x[STATE.f_lp + 1]
    d = MODEL.drag_moment
    return c[d] * fx + c[d + 1] * fy, c[d + 2] * fx + c[d + 3] * fy


@njit(cache=True, inline="always")
def motor_step(omega, cmd, c, dt):
    """The detector's motor model: first order with its time constant, speed and rate limits."""
    target = min(max(cmd, c[MODEL.omega_min]), c[MODEL.omega_max])
    rate = (target - omega) / c[MODEL.tau]
    lim = c[MODEL.omega_dot_max]
    return omega + dt * min(max(rate, -lim), lim)


@njit(cache=True, inline="always")
def _thrust(c, om, w0, w1, gx, gy):
    """An intact rotor's thrust at speed ``om`` on a body turning at ``(w0, w1)``: ``k_f Ω² + k_z Ω
    u_z`` with the hub's axial speed from the rotation, ``u_z = ω_x r_y − ω_y r_x`` (the
    vehicle's own velocity is not known here: it moves every rotor alike)."""
    return c[MODEL.k_f] * om * om + c[MODEL.k_z] * om * (-w0 * gx - w1 * gy)


@njit(cache=True, inline="always")
def body_moments(c, w0, w1, w2):
    """The moments on the body turning at ``ω`` other than the rotors': the gyroscopic
    ``−ω × J ω`` and the quadratic drag ``−C_r |ω| ω`` (the linear damping ``D ω`` is applied by
    the caller)."""
    J0, J1, J2 = c[MODEL.inertia], c[MODEL.inertia + 1], c[MODEL.inertia + 2]
    m0 = -(w1 * J2 * w2 - w2 * J1 * w1) - c[MODEL.rot_drag] * abs(w0) * w0
    m1 = -(w2 * J0 * w0 - w0 * J2 * w2) - c[MODEL.rot_drag + 1] * abs(w1) * w1
    m2 = -(w0 * J1 * w1 - w1 * J0 * w0) - c[MODEL.rot_drag + 2] * abs(w2) * w2
    return m0, m1, m2


@njit(cache=True, inline="always")
def rotor_thrust_yaw(c, i, om, w0, w1, w2):
    """Intact rotor ``i`` at speed ``om`` on a body turning at ``ω``: its thrust (:func:`_thrust`;
    its roll and pitch moments are ``thrust · (g_x, g_y)``) and its yaw moment, the reaction
    torque and the rotor drag of the hub's in-plane speed ``ω_z × r_i``."""
    gx, gy, gz = c[MODEL.g + 3 * i], c[MODEL.g + 3 * i + 1], c[MODEL.g + 3 * i + 2]
    thrust = _thrust(c, om, w0, w1, gx, gy)
    yaw = c[MODEL.k_f] * om * om * gz - c[MODEL.k_h] * om * w2 * (gx * gx + gy * gy)  # reaction, rotor drag
    return thrust, yaw


@njit(cache=True, inline="always")
def air_drag_per_speed(x, p, c, n):
    """The rotors' drag as the vehicle moves through the air (docs/detection.md): rotor ``i``'s
    yaw moment is ``−k_h η_i Ω_i (r_x u_y − r_y u_x)`` with ``u`` the body's velocity in the
    air, and the accelerometer reads the rotors' drag with the body's, ``m f_xy = −(k_h Σ_j η_j
    Ω_j + c |u|) u_xy``. So the moment is ``s m Ω_i (g_x f_x + g_y f_y) / Σ_j η_j Ω_j`` with ``s``
    the rotors' share of the drag at that speed. Returns ``f_x, f_y`` and ``s m / Σ_j η_j Ω_j``
    (zero when off, or without rotor drag in the model)."""
    if p[PARAM.air_drag] == 0.0:
        return 0.0, 0.0, 0.0
    total = 0.0
    for j in range(n):
        total += max(x[STATE.eta + j], 0.0) * x[STATE.omega + j]
    fx, fy = x[STATE.f_lp], x[STATE.f_lp + 1]
    rotors = c[MODEL.k_h] * total  # the rotors' drag per unit speed
    if rotors <= 0.0:
        return 0.0, 0.0, 0.0
    body = 0.5 * (c[MODEL.body_drag] + c[MODEL.body_drag + 1])
    force = c[MODEL.mass] * np.sqrt(fx * fx + fy * fy)
    speed = force / rotors if body <= 0.0 else (np.sqrt(rotors * rotors + 4.0 * body * force) - rotors) / (2.0 * body)
    share = rotors / (rotors + body * speed)
    return fx, fy, share * c[MODEL.mass] / total


@njit(cache=True, inline="always")
def at_centre_of_mass(x, p, c, acc):
    """The accelerometer's reading less what its place ``r`` off the centre of mass adds,
    ``α × r + ω × (ω × r)``, with the model's rate and angular acceleration over the interval
    (a gyroscope's difference would carry its rotors' tone, tens of rad/s² at a sample's
    spacing). Kept in ``STATE.acc_cg``: every later use reads it."""
    out = STATE.acc_cg
    if p[PARAM.lever_arm] == 0.0:
        for j in range(3):
            x[out + j] = acc[j]
        return x[out : out + 3]
    w0, w1, w2 = x[STATE.w], x[STATE.w + 1], x[STATE.w + 2]
    a0, a1, a2 = x[STATE.alpha], x[STATE.alpha + 1], x[STATE.alpha + 2]
    r0, r1, r2 = c[MODEL.imu], c[MODEL.imu + 1], c[MODEL.imu + 2]
    v0, v1, v2 = w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0  # ω × r
    x[out] = acc[0] - (a1 * r2 - a2 * r1) - (w1 * v2 - w2 * v1)
    x[out + 1] = acc[1] - (a2 * r0 - a0 * r2) - (w2 * v0 - w0 * v2)
    x[out + 2] = acc[2] - (a0 * r1 - a1 * r0) - (w0 * v1 - w1 * v0)
    return x[out : out + 3]


@njit(cache=True, inline="always")
def air_lowpass(x, c, acc, w2, dt):
    """The accelerometer's x and y without the rotors' drag from the body's yaw rate ``w2`` (the
    hubs' in-plane speed ``ω_z (g_x, g_y)``: ``m f_rot = −k_h ω_z Σ_j η_j Ω_j (g_x, g_y)_j``),
    low-passed over ``F_TAU``: the drag of the body's motion through the air. A missing reading
    keeps the last."""
    if not (np.isfinite(acc[0]) and np.isfinite(acc[1])):
        return
    rx = ry = 0.0
    for j in range(int(c[MODEL.rotors])):
        k = c[MODEL.k_h] * w2 * max(x[STATE.eta + j], 0.0) * x[STATE.omega + j] / c[MODEL.mass]
        rx += k * c[MODEL.g + 3 * j]
        ry += k * c[MODEL.g + 3 * j + 1]
    a = min(dt / F_TAU, 1.0)
    x[STATE.f_lp] += a * (acc[0] + rx - x[STATE.f_lp])
    x[STATE.f_lp + 1] += a * (acc[1] + ry - x[STATE.f_lp + 1])
