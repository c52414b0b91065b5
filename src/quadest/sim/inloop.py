"""The sensors sampled one sample at a time, in compiled code, for a closed loop (issue #13:
the estimator in the loop reads them as the vehicle flies).

The model is the one of :mod:`quadest.sim.sensors` with the draws of
:func:`quadest.sim.simulator.draw_processes`, so that the readings of a closed-loop flight
equal, to rounding, what :func:`~quadest.sim.simulator.sample_sensors` makes of the same flight
afterwards (``tests/test_flight.py`` checks it; :func:`quadest.sim.flown.flown_recording`
checks it on every flown recording). Per IMU sample ``k``::

    gyr = clip(DLPF(M_g ω + b_g[k] + δω[k] + n_g[k]))
    acc = clip(DLPF(M_a f_imu + b_a[k] + vib[k] + n_a[k])),  f_imu = Rᵀ(a − g) + ω̇ × r + ω × (ω × r)
    vib, δω: each rotor's blade-pass tone and a damaged propeller's imbalance, from the rotor
             speeds (quadest.sim.sensors.rotor_vibration_step, the function the batch model calls)
    mag = clip(S Rᵀ B_n(p) + b_hard + k_motor · current + n_m)   on magnetometer rows, R, p and
          current as they were latency_s before
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from quadest._jit import njit
from quadest.models.multirotor import MultirotorParams
from quadest.rotation.kernels import rotate_inv_s
from quadest.sim import sensors as S
from quadest.sim.params import SimConfig
from quadest.sim.sensors import (
    distortion_at,
    distortion_sources,
    lowpass_step,
    rotor_vibration_model,
    rotor_vibration_step,
)

SensorModel = namedtuple(
    "SensorModel",
    [
        "gyr_matrix",
        "gyr_bias",
        "gyr_noise",
        "gyr_range",
        "acc_matrix",
        "acc_bias",
        "acc_noise",
        "acc_range",
        "lever",
        "gravity",
        "rv",
        "vib_acc",
        "vib_gyr",
        "has_mag",
        "mag_index",
        "mag_soft",
        "mag_hard",
        "mag_motor",
        "mag_noise",
        "mag_range",
        "field_n",
        "dist_src",
        "dist_mom",
        "has_dist",
        "mag_hist",
        "gyr_alpha",
        "acc_alpha",
        "lp",
    ],
)
"""What the compiled sampler reads: the configuration's constants and one run's draws."""


def sensor_model(cfg: SimConfig, processes, has_mag, vehicle: MultirotorParams) -> SensorModel:
    """Pack a configuration, the flown ``vehicle`` (its rotors vibrate) and the draws of one
    run (``draw_processes`` with the vehicle's rotors) for the sampler."""
    has_mag = np.asarray(has_mag, bool)
    index = np.cumsum(has_mag) - 1  # row k's magnetometer noise is mag_noise[index[k]]
    mag_noise = processes.mag_noise if len(processes.mag_noise) else np.zeros((1, 3))
    sources = distortion_sources(cfg.environment)
    src, mom = sources if sources is not None else (np.zeros((0, 3)), np.zeros((0, 3)))
    return SensorModel(
        np.ascontiguousarray(processes.gyro_errors["matrix"]),
        np.ascontiguousarray(processes.gyr_bias),
        np.ascontiguousarray(processes.gyr_noise),
        float(cfg.gyro.range),
        np.ascontiguousarray(processes.acc_errors["matrix"]),
        np.ascontiguousarray(processes.acc_bias),
        np.ascontiguousarray(processes.acc_noise),
        float(cfg.acc.range),
        np.asarray(cfg.acc.lever_arm, float),
        float(cfg.environment.gravity),
        rotor_vibration_model(vehicle, cfg.acc.vibration_amp, processes.vib_offsets, cfg.acc.lever_arm),
        np.zeros(3),
        np.zeros(3),
        has_mag,
        index.astype(np.int64),
        np.ascontiguousarray(cfg.mag.soft_iron, dtype=float),
        np.asarray(cfg.mag.hard_iron, float),
        np.asarray(cfg.mag.motor_coef, float),
        np.ascontiguousarray(mag_noise),
        float(cfg.mag.range),
        S.earth_field(cfg.environment),
        src,
        mom,
        sources is not None,
        np.zeros((int(round(cfg.mag.latency_s * cfg.imu.rate_hz)) + 1, 8)),
        S.dlpf_alpha(cfg.gyro.dlpf_hz, cfg.imu.rate_hz),
        S.dlpf_alpha(cfg.acc.dlpf_hz, cfg.imu.rate_hz),
        np.zeros(6),
    )


@njit(cache=True)
def _clip(v, limit):
    return min(max(v, -limit), limit)


@njit(cache=True, inline="always")
def sample_imu(m, k, t, q, acc_n, w, wdot, speeds, imbalance, vib_state, gyr, acc):
    """IMU sample ``k`` at time ``t`` from the true attitude ``q``, acceleration ``acc_n``
    (navigation frame), rate ``w`` and angular acceleration ``wdot`` (body), and the rotors'
    ``speeds`` and ``imbalance``; into ``gyr`` and ``acc``. ``vib_state`` carries the rotor
    angles (start with :func:`quadest.sim.sensors.vibration_state`)."""
    rotor_vibration_step(m.rv, t, speeds, imbalance, vib_state, m.vib_acc, m.vib_gyr)
    for i in range(3):
        u = (
            (m.gyr_matrix[i, 0] * w[0] + m.gyr_matrix[i, 1] * w[1] + m.gyr_matrix[i, 2] * w[2] + m.gyr_bias[k, i])
            + m.vib_gyr[i]
        ) + m.gyr_noise[k, i]
        if m.gyr_alpha < 1.0:  # the DLPF, settled at the first sample
            m.lp[i] = lowpass_step(m.lp[i], u, m.gyr_alpha) if k > 0 else u
            u = m.lp[i]
        gyr[i] = _clip(u, m.gyr_range)
    f0, f1, f2 = rotate_inv_s(q[0], q[1], q[2], q[3], acc_n[0], acc_n[1], acc_n[2] - m.gravity)
    r0, r1, r2 = m.lever[0], m.lever[1], m.lever[2]
    # ω̇ × r + ω × (ω × r)
    c0, c1, c2 = w[1] * r2 - w[2] * r1, w[2] * r0 - w[0] * r2, w[0] * r1 - w[1] * r0
    f0 += (wdot[1] * r2 - wdot[2] * r1) + (w[1] * c2 - w[2] * c1)
    f1 += (wdot[2] * r0 - wdot[0] * r2) + (w[2] * c0 - w[0] * c2)
    f2 += (wdot[0] * r1 - wdot[1] * r0) + (w[0] * c1 - w[1] * c0)
    for i in range(3):
        a = m.acc_matrix[i, 0] * f0 + m.acc_matrix[i, 1] * f1 + m.acc_matrix[i, 2] * f2 + m.acc_bias[k, i]
        u = (a + m.vib_acc[i]) + m.acc_noise[k, i]
        if m.acc_alpha < 1.0:
            m.lp[3 + i] = lowpass_step(m.lp[3 + i], u, m.acc_alpha) if k > 0 else u
            u = m.lp[3 + i]
        acc[i] = _clip(u, m.acc_range)


@njit(cache=True, inline="always")
def sample_mag(m, k, q, pos, current, mag):
    """Magnetometer sample on IMU row ``k`` into ``mag`` (NaN where no sample arrives), from the
    attitude, position and motor current of ``latency`` samples before (``m.mag_hist`` keeps
    them; call it every sample)."""
    h = m.mag_hist
    d = h.shape[0] - 1
    if k == 0:
        for r in range(d + 1):
            _keep(h, r, q, pos, current)
    _keep(h, k % (d + 1), q, pos, current)
    if not m.has_mag[k]:
        mag[0], mag[1], mag[2] = np.nan, np.nan, np.nan
        return
    j = max(k - d, 0) % (d + 1)
    current = h[j, 4]
    f0, f1, f2 = m.field_n[0], m.field_n[1], m.field_n[2]
    if m.has_dist:
        d0, d1, d2 = distortion_at(h[j, 5], h[j, 6], h[j, 7], m.dist_src, m.dist_mom)
        f0, f1, f2 = d0 + f0, d1 + f1, d2 + f2
    b0, b1, b2 = rotate_inv_s(h[j, 0], h[j, 1], h[j, 2], h[j, 3], f0, f1, f2)
    j = m.mag_index[k]
    for i in range(3):
        v = m.mag_soft[i, 0] * b0 + m.mag_soft[i, 1] * b1 + m.mag_soft[i, 2] * b2 + m.mag_hard[i]
        mag[i] = _clip(v + current * m.mag_motor[i] + m.mag_noise[j, i], m.mag_range)


@njit(cache=True, inline="always")
def _keep(h, r, q, pos, current):
    h[r, 0], h[r, 1], h[r, 2], h[r, 3], h[r, 4] = q[0], q[1], q[2], q[3], current
    h[r, 5], h[r, 6], h[r, 7] = pos[0], pos[1], pos[2]


@njit(cache=True)
def motor_current(load, active, thrust_to_weight):
    """As :func:`quadest.sim.truth.motor_current`, one sample."""
    return (active / 4.0) * (max(load, 0.0) / thrust_to_weight) ** 1.5
