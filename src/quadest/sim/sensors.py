"""Sensor models: gyroscope, accelerometer and magnetometer, each with its own errors.

Inertial sensors (per axis, through an optional first-order anti-alias low-pass (``dlpf_hz``),
clipped to ``±range``)::

    gyr = M_g ω + b_g + b_rw(t) + n
    acc = M_a f_imu + b_a + b_rw(t) + vibration + n,   f_imu = Rᵀ(a − g) + ω̇ × r + ω × (ω × r)

with ``M = (I + diag(scale)) (I + misalignment)``, a constant bias, a bias random walk, white
noise, and for the accelerometer the IMU's lever arm ``r`` from the centre of mass and a rotor
vibration tone whose frequency follows the rotor speed and whose amplitude grows with rotor load.
Magnetometer (µT)::

    mag = S Rᵀ B_n + b_hard + k_motor · current + n

with the earth field ``B_n = F [cos I cos D, cos I sin D, sin I]`` (NED), a soft-iron matrix
``S``, a hard-iron offset and a disturbance proportional to the motor current (which grows
with thrust, and at equal thrust when a rotor is lost).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from quadest.rotation import quat_conj, quat_rotate
from quadest.sim.params import Accelerometer, Environment, Gyroscope, Magnetometer


def earth_field(env: Environment) -> np.ndarray:
    """Earth magnetic field in NED, µT."""
    inc, dec = np.radians(env.inclination_deg), np.radians(env.declination_deg)
    return env.field_ut * np.array([np.cos(inc) * np.cos(dec), np.cos(inc) * np.sin(dec), np.sin(inc)])


def draw_errors(model, rng) -> dict:
    """Per-run realisation of constant bias, scale factors and misalignment."""
    bias = np.array(model.bias, float) if model.bias is not None else rng.normal(0.0, model.bias_std, 3)
    scale = np.array(model.scale, float) if model.scale is not None else rng.normal(0.0, model.scale_std, 3)
    if model.misalignment is not None:
        mis = np.array(model.misalignment, float)
    else:
        mis = rng.normal(0.0, model.misalignment_std, (3, 3))
        np.fill_diagonal(mis, 0.0)
    M = (np.eye(3) + np.diag(scale)) @ (np.eye(3) + mis)
    return {"bias": bias, "scale": scale, "misalignment": mis, "matrix": M}


def random_walk(t, std, rng):
    """Bias random walk of intensity ``std`` (unit/√s) sampled at ``t``, starting at 0."""
    if std == 0.0:
        return np.zeros((len(t), 3))
    dt = np.diff(t, prepend=t[0])
    return np.cumsum(rng.normal(size=(len(t), 3)) * (std * np.sqrt(dt))[:, None], axis=0)


def inertial_processes(t, model: Gyroscope | Accelerometer, errors, rng):
    """What an inertial sensor adds that does not depend on the motion, drawn at the instants
    ``t``: the bias at each sample (constant part plus random walk) and the white noise."""
    bias = errors["bias"] + random_walk(t, model.bias_rw_std, rng)
    noise = rng.normal(0.0, model.noise_std, (len(t), 3)) if model.noise_std > 0 else np.zeros((len(t), 3))
    return bias, noise


def dlpf_alpha(cutoff_hz: float, rate_hz: float) -> float:
    """The smoothing factor of a first-order low-pass at ``cutoff_hz`` sampled at ``rate_hz``:
    ``α = 1 − exp(−2π f_c / f_s)`` (1: no filter)."""
    return 1.0 if cutoff_hz <= 0 else float(1.0 - np.exp(-2.0 * np.pi * cutoff_hz / rate_hz))


@njit(cache=True)
def lowpass_step(y, u, alpha):
    """One sample of the first-order low-pass: ``y ← α u + (1 − α) y`` (the sensor's DLPF; the
    batch model and the closed loop call this same function)."""
    return alpha * u + (1.0 - alpha) * y


@njit(cache=True)
def _lowpass(u, alpha):
    out = np.empty_like(u)
    for j in range(u.shape[1]):
        y = u[0, j]
        for k in range(u.shape[0]):
            y = lowpass_step(y, u[k, j], alpha) if k > 0 else u[0, j]
            out[k, j] = y
    return out


def apply_inertial(true, matrix, bias, noise, limit, extra=None, alpha: float = 1.0):
    """``clip(DLPF(M true + bias + extra + noise), ±limit)`` over rows, the low-pass starting
    settled at the first sample (the order of the sums is the one :mod:`quadest.sim.inloop`
    keeps sample by sample)."""
    out = true @ matrix.T + bias
    if extra is not None:
        out = out + extra
    out = out + noise
    if alpha < 1.0 and len(out):
        out = _lowpass(np.ascontiguousarray(out), alpha)
    return np.clip(out, -limit, limit)


def inertial(true, t, model: Gyroscope | Accelerometer, errors, rng, extra=None):
    """Apply scale/misalignment, bias, random walk, extra terms, noise and saturation.
    Returns the readings and the bias at each sample (constant part plus random walk)."""
    bias, noise = inertial_processes(t, model, errors, rng)
    rate = 1.0 / np.median(np.diff(t)) if len(t) > 1 else 1.0
    return apply_inertial(true, errors["matrix"], bias, noise, model.range, extra, dlpf_alpha(model.dlpf_hz, rate)), bias


def specific_force_at_imu(q, acc_n, w, wdot, lever, gravity):
    """``f_imu = Rᵀ(a − g) + ω̇ × r + ω × (ω × r)``, body frame, m/s²."""
    f = quat_rotate(quat_conj(q), acc_n - np.array([0.0, 0.0, gravity]))
    r = np.broadcast_to(np.asarray(lever, float), w.shape)
    return f + np.cross(wdot, r) + np.cross(w, np.cross(w, r))


def vibration_offsets(amp, rng) -> np.ndarray:
    """The tone's phase offset per axis (drawn only when there is a tone)."""
    return rng.uniform(0, 2 * np.pi, 3) if np.asarray(amp, float).any() else np.zeros(3)


def vibration(t, rotor_load, rotor_hz_hover, amp, rng=None, offsets=None):
    """Rotor tone: frequency ``f_hover √load``, amplitude ``amp · load`` per axis; the phase
    offsets drawn from ``rng`` or given."""
    amp = np.asarray(amp, float)
    if not amp.any():
        return np.zeros((len(t), 3))
    freq = rotor_hz_hover * np.sqrt(np.maximum(rotor_load, 0.0))
    phase = 2 * np.pi * np.concatenate([[0.0], np.cumsum(0.5 * (freq[1:] + freq[:-1]) * np.diff(t))])
    offs = vibration_offsets(amp, rng) if offsets is None else offsets
    return np.sin(phase[:, None] + offs) * amp * rotor_load[:, None]


def mag_noise(n: int, model: Magnetometer, rng) -> np.ndarray:
    """White noise of ``n`` magnetometer samples."""
    return rng.normal(0.0, model.noise_std, (n, 3)) if model.noise_std > 0 else np.zeros((n, 3))


def magnetometer(q, current, env: Environment, model: Magnetometer, rng=None, noise=None):
    """``clip(S Rᵀ B_n + b_hard + k_motor current + noise)``; the noise drawn from ``rng`` or given."""
    B_b = quat_rotate(quat_conj(q), earth_field(env))
    m = B_b @ np.array(model.soft_iron, float).T + np.array(model.hard_iron, float)
    m = m + np.outer(current, np.array(model.motor_coef, float))
    m = m + (mag_noise(len(q), model, rng) if noise is None else noise)
    return np.clip(m, -model.range, model.range)


def mag_rows(k, imu_rate, mag_rate):
    """Rows (by nominal IMU index ``k``) at which a new magnetometer sample arrives: the first
    IMU row at or after each magnetometer tick."""
    if mag_rate <= 0:
        return np.zeros(len(k), bool)
    tick = np.floor(k * (mag_rate / imu_rate) + 1e-9)
    return np.concatenate([[True], tick[1:] > tick[:-1]])
