"""Sensor models: gyroscope, accelerometer and magnetometer, each with its own errors.

Inertial sensors (per axis, through an optional first-order anti-alias low-pass (``dlpf_hz``),
clipped to ``±range``)::

    gyr = M_g ω + b_g + b_rw(t) + n
    acc = M_a f_imu + b_a + b_rw(t) + vibration + n,   f_imu = Rᵀ(a − g) + ω̇ × r + ω × (ω × r)

with ``M = (I + diag(scale)) (I + misalignment)``, a constant bias, a bias random walk, white
noise, and for the accelerometer the IMU's lever arm ``r`` from the centre of mass and a rotor
vibration tone whose frequency follows the rotor speed and whose amplitude grows with rotor load.
A flown vehicle's vibration comes from each rotor's own speed (:func:`rotor_vibration_step`:
a blade-pass tone per rotor, and a damaged propeller's once-per-revolution imbalance as the
rigid body's response to its rotating force, in the gyroscope too).
Magnetometer (µT)::

    mag = S Rᵀ B_n(p) + b_hard + k_motor · current + n

with the earth field ``B_n = F [cos I cos D, cos I sin D, sin I]`` (NED), indoors distorted by
magnetised steel below the flight (:func:`distortion_sources`: a field that varies with the
position ``p``), a soft-iron matrix
``S``, a hard-iron offset and a disturbance proportional to the motor current (which grows
with thrust, and at equal thrust when a rotor is lost); on magnetometer rows, with ``R``, ``p``
and the current as they were ``latency_s`` before.

The model is one compiled function per sensor, called one sample at a time
(:func:`sample_imu`, :func:`sample_mag` on a :class:`SensorModel` from :func:`sensor_model`): a
closed loop calls them as the vehicle flies, and a whole trajectory is sampled by the compiled
loop :func:`sample_all` over the same functions, so the two are the same by construction.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from quadest._jit import njit
from quadest.models.multirotor import MultirotorParams
from quadest.rotation.kernels import rotate_inv_s
from quadest.sim.params import Accelerometer, Environment, Gyroscope, Magnetometer, SimConfig


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


RotorVibration = namedtuple(
    "RotorVibration",
    ["pos", "spin", "inv_inertia", "mass", "omega_hover", "blades", "bp_amp", "bp_gyr", "has_bp", "offsets", "lever"],
)
"""What :func:`rotor_vibration_step` reads: the vehicle's rotors, the blade-pass amplitude per
rotor and axis, one run's phases and the IMU's lever arm (built by :func:`rotor_vibration_model`)."""


def rotor_vibration_model(vehicle: MultirotorParams, amp, offsets, lever, gyro_amp=(0.0, 0.0, 0.0)) -> RotorVibration:
    """The flown vehicle's vibration: ``amp`` the total blade-pass amplitude per axis at hover
    (the configuration's ``acc.vibration_amp``, shared by the rotors so that N incoherent tones
    carry the power of one: ``amp/√N`` each), ``gyro_amp`` the gyroscope's (``gyro.vibration_amp``,
    rad/s, shared alike), ``offsets`` one run's phases (rotors × 4: the blade-pass phase per axis,
    then the rotor's angle at the start)."""
    amp = np.asarray(amp, float)
    gyro_amp = np.asarray(gyro_amp, float)
    offsets = np.ascontiguousarray(offsets, dtype=float)
    if offsets.shape != (vehicle.rotors, 4):
        raise ValueError(f"rotor vibration: offsets must be {vehicle.rotors} rows of 4, got shape {offsets.shape}")
    return RotorVibration(
        np.ascontiguousarray(vehicle.rotor_pos, dtype=float),
        np.asarray(vehicle.spin, float),
        1.0 / np.asarray(vehicle.inertia, float),
        float(vehicle.mass_kg),
        vehicle.hover_speed(),
        float(vehicle.blades),
        amp / np.sqrt(vehicle.rotors),
        gyro_amp / np.sqrt(vehicle.rotors),
        bool(amp.any() or gyro_amp.any()),
        offsets,
        np.asarray(lever, float),
    )


def no_rotor_vibration(lever) -> RotorVibration:
    """The vibration model of a prescribed motion, which has no rotors: its tone comes from
    :func:`vibration` and is given to :func:`sample_imu` as it is."""
    return RotorVibration(
        np.zeros((0, 3)),
        np.zeros(0),
        np.ones(3),
        1.0,
        1.0,
        1.0,
        np.zeros(3),
        np.zeros(3),
        False,
        np.zeros((0, 4)),
        np.asarray(lever, float),
    )


def rotor_vibration_offsets(rotors: int, rng) -> np.ndarray:
    """One run's phases of a flown vehicle's vibration (:func:`rotor_vibration_model`)."""
    return rng.uniform(0.0, 2 * np.pi, (rotors, 4))


def vibration_state(rotors: int) -> np.ndarray:
    """The state :func:`rotor_vibration_step` carries from sample to sample: each rotor's angle,
    its previous speed and the previous time (NaN: no sample yet)."""
    state = np.zeros(2 * rotors + 1)
    state[rotors:] = np.nan
    return state


@njit(cache=True, inline="always")
def rotor_vibration_step(rv, t, speeds, imbalance, state, acc, gyr):
    """The vibration a flown vehicle's IMU sees at time ``t`` from its rotors' ``speeds``
    (rad/s) and propeller ``imbalance`` (kg m, mass times radius; 0 for a sound propeller),
    into ``acc`` (m/s²) and ``gyr`` (rad/s); ``state`` (:func:`vibration_state`) carries the
    rotor angles ``ψ_i = ψ_i0 + ∫ Ω_i dt`` (trapezoid between samples).

    - **Blade pass**: per rotor and axis ``a_bp (Ω_i/Ω_hover)² sin(B ψ_i + φ_ia)``, B blades;
      the amplitude at hover ``a_bp`` is chosen (a property of the frame and the IMU's mount,
      which a rigid-body model does not have); in the gyroscope ``g_bp (Ω_i/Ω_hover)²
      sin(B ψ_i + φ_i,a+1)`` (the frame's rocking at the same tone, the next axis's phase).
    - **Imbalance** of a damaged propeller: the centrifugal force of the missing mass,
      ``F_i = u Ω² [cos ψ, s sin ψ, 0]`` (body; ``s`` the rotor's sense, ψ measured in it),
      acting at the rotor ``r_i``. The rigid body's response, superposed on the flown motion:
      ``δa = F/m``, ``δω̇ = J⁻¹ (r_i × F)``, ``δω = J⁻¹ (r_i × ∫F dt)`` with the zero-mean
      ``∫F dt = u Ω [sin ψ, −s cos ψ, 0]`` (Ω slowly varying); at the IMU
      ``δf = δa + δω̇ × r_imu``, the gyroscope ``δω``. Neglected, and why: the response is
      not fed back into the flight (its displacement is ``u/m``, 10 µm for 5 g mm on 0.5 kg,
      its attitude ``|r × u|/J``, a fraction of a milliradian); the gyroscopic coupling
      ``ω × J δω`` (``|ω|/Ω``, about 2 %); the attitude ripple's share of gravity (``δθ g``, mm/s²)."""
    n = rv.pos.shape[0]
    first = not np.isfinite(state[2 * n])
    for i in range(n):
        if first:
            state[i] = rv.offsets[i, 3]
        else:
            state[i] += 0.5 * (speeds[i] + state[n + i]) * (t - state[2 * n])
        state[n + i] = speeds[i]
    state[2 * n] = t
    for a in range(3):
        acc[a] = 0.0
        gyr[a] = 0.0
    for i in range(n):
        w, psi = speeds[i], state[i]
        if rv.has_bp:
            s2 = (w / rv.omega_hover) ** 2
            for a in range(3):
                acc[a] += rv.bp_amp[a] * s2 * np.sin(rv.blades * psi + rv.offsets[i, a])
                gyr[a] += rv.bp_gyr[a] * s2 * np.sin(rv.blades * psi + rv.offsets[i, (a + 1) % 3])
        u = imbalance[i]
        if u > 0.0:
            c, sn, sp = np.cos(psi), np.sin(psi), rv.spin[i]
            f0, f1 = u * w * w * c, u * w * w * sp * sn  # the force (its z part is 0)
            h0, h1 = u * w * sn, -u * w * sp * c  # its zero-mean time integral
            r0, r1, r2 = rv.pos[i, 0], rv.pos[i, 1], rv.pos[i, 2]
            # δω̇ = J⁻¹ (r × F), δω = J⁻¹ (r × ∫F dt), F and ∫F dt in the disc plane
            d0, d1, d2 = (
                -r2 * f1 * rv.inv_inertia[0],
                r2 * f0 * rv.inv_inertia[1],
                (r0 * f1 - r1 * f0) * rv.inv_inertia[2],
            )
            gyr[0] += -r2 * h1 * rv.inv_inertia[0]
            gyr[1] += r2 * h0 * rv.inv_inertia[1]
            gyr[2] += (r0 * h1 - r1 * h0) * rv.inv_inertia[2]
            l0, l1, l2 = rv.lever[0], rv.lever[1], rv.lever[2]
            acc[0] += f0 / rv.mass + (d1 * l2 - d2 * l1)
            acc[1] += f1 / rv.mass + (d2 * l0 - d0 * l2)
            acc[2] += d0 * l1 - d1 * l0


@njit(cache=True)
def _rotor_vibration(rv, t, speeds, imbalance, acc, gyr):
    state = np.zeros(2 * speeds.shape[1] + 1)
    state[speeds.shape[1] :] = np.nan
    for k in range(t.shape[0]):
        rotor_vibration_step(rv, t[k], speeds[k], imbalance[k], state, acc[k], gyr[k])


def rotor_vibration(rv: RotorVibration, t, speeds, imbalance):
    """:func:`rotor_vibration_step` over a whole flight (rows of ``t``, ``speeds``,
    ``imbalance``): the accelerometer's and the gyroscope's vibration, each (n, 3)."""
    t = np.ascontiguousarray(t, dtype=float)
    acc, gyr = np.zeros((len(t), 3)), np.zeros((len(t), 3))
    _rotor_vibration(
        rv, t, np.ascontiguousarray(speeds, dtype=float), np.ascontiguousarray(imbalance, dtype=float), acc, gyr
    )
    return acc, gyr


def mag_noise(n: int, model: Magnetometer, rng) -> np.ndarray:
    """White noise of ``n`` magnetometer samples."""
    return rng.normal(0.0, model.noise_std, (n, 3)) if model.noise_std > 0 else np.zeros((n, 3))


def distortion_sources(env: Environment):
    """The indoor distortion's dipoles: positions (K, 3; NED, a 3 x 3 grid ``distortion_spacing_m``
    apart, ``distortion_depth_m`` below the origin) and moments (K, 3; directions drawn from
    ``distortion_seed``, scaled so that their field at the origin is ``distortion_ut``). None
    when there is no distortion."""
    if env.distortion_ut <= 0:
        return None
    g = env.distortion_spacing_m * np.arange(-1.0, 2.0)
    src = np.array([(x, y, env.distortion_depth_m) for x in g for y in g])
    mom = np.random.default_rng(np.random.SeedSequence([int(env.distortion_seed), 29])).normal(size=src.shape)
    mom /= np.linalg.norm(mom, axis=1, keepdims=True)
    at0 = np.array(distortion_at(0.0, 0.0, 0.0, src, mom))
    return src, mom * (env.distortion_ut / np.linalg.norm(at0))


@njit(cache=True, inline="always")
def distortion_at(p0, p1, p2, src, mom):
    """The dipoles' field at ``p`` (NED): ``Σ (3 (m·r) r/|r|² − m)/|r|³`` with ``r = p − s_j``
    (the moments carry µ0/4π and the unit µT m³)."""
    b0 = b1 = b2 = 0.0
    for j in range(src.shape[0]):
        r0, r1, r2 = p0 - src[j, 0], p1 - src[j, 1], p2 - src[j, 2]
        d2 = r0 * r0 + r1 * r1 + r2 * r2
        inv3 = 1.0 / (d2 * np.sqrt(d2))
        md = 3.0 * (mom[j, 0] * r0 + mom[j, 1] * r1 + mom[j, 2] * r2) / d2
        b0 += (md * r0 - mom[j, 0]) * inv3
        b1 += (md * r1 - mom[j, 1]) * inv3
        b2 += (md * r2 - mom[j, 2]) * inv3
    return b0, b1, b2


@njit(cache=True)
def _distortion_rows(pos, src, mom, out):
    for k in range(pos.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = distortion_at(pos[k, 0], pos[k, 1], pos[k, 2], src, mom)


def field_at(env: Environment, pos) -> np.ndarray:
    """The field in NED (µT) at the positions ``pos`` (n, 3): the earth's plus the indoor
    distortion (:func:`distortion_sources`)."""
    pos = np.ascontiguousarray(pos, dtype=float)
    out = np.zeros((len(pos), 3))
    sources = distortion_sources(env)
    if sources is not None:
        _distortion_rows(pos, sources[0], sources[1], out)
    return out + earth_field(env)


def mag_rows(k, imu_rate, mag_rate):
    """Rows (by nominal IMU index ``k``) at which a new magnetometer sample arrives: the first
    IMU row at or after each magnetometer tick."""
    if mag_rate <= 0:
        return np.zeros(len(k), bool)
    tick = np.floor(k * (mag_rate / imu_rate) + 1e-9)
    return np.concatenate([[True], tick[1:] > tick[:-1]])


@njit(cache=True)
def motor_current(load, n_active, thrust_to_weight):
    """Motor current over its maximum, the magnetometer's disturbance. A rotor's power grows as
    thrust^1.5 (momentum theory): ``(n_active/4) (load/TW)^1.5`` with ``load`` the thrust per
    rotor over its hover value and ``TW`` the thrust-to-weight ratio (the load at full thrust).
    Losing a rotor at equal total thrust raises the current by √(4/3). Scalars or arrays."""
    return (n_active / 4.0) * (np.maximum(load, 0.0) / thrust_to_weight) ** 1.5


SensorModel = namedtuple(
    "SensorModel",
    [
        "gyr_matrix", "gyr_bias", "gyr_noise", "gyr_range",
        "acc_matrix", "acc_bias", "acc_noise", "acc_range", "lever", "gravity",
        "rv", "vib_acc", "vib_gyr",
        "has_mag", "mag_index", "mag_soft", "mag_hard", "mag_motor", "mag_noise", "mag_range", "field_n",
        "dist_src", "dist_mom", "has_dist",
        "mag_hist", "gyr_alpha", "acc_alpha", "lp",
    ],
)  # fmt: skip
"""What the compiled sensors read: the configuration's constants, one run's draws, the rotors'
vibration model (``rv``; none for a prescribed motion) with its output, and the state the
sensors carry from sample to sample (the low-passes ``lp``, the magnetometer's history)."""


def sensor_model(cfg: SimConfig, processes, has_mag, vehicle: MultirotorParams | None = None) -> SensorModel:
    """Pack a configuration and one run's draws (``draw_processes``, with the vehicle's rotors for
    a flown ``vehicle``, whose rotors vibrate) for :func:`sample_imu` and :func:`sample_mag`.
    Stateful: one per run."""
    has_mag = np.asarray(has_mag, bool)
    index = np.cumsum(has_mag) - 1  # row k's magnetometer noise is mag_noise[index[k]]
    mag_noise = processes.mag_noise if len(processes.mag_noise) else np.zeros((1, 3))
    sources = distortion_sources(cfg.environment)
    src, mom = sources if sources is not None else (np.zeros((0, 3)), np.zeros((0, 3)))
    if vehicle is None:
        rv = no_rotor_vibration(cfg.acc.lever_arm)
    else:
        rv = rotor_vibration_model(
            vehicle, cfg.acc.vibration_amp, processes.vib_offsets, cfg.acc.lever_arm, cfg.gyro.vibration_amp
        )
    c = np.ascontiguousarray
    return SensorModel(
        c(processes.gyro_errors["matrix"]), c(processes.gyr_bias), c(processes.gyr_noise), float(cfg.gyro.range),
        c(processes.acc_errors["matrix"]), c(processes.acc_bias), c(processes.acc_noise), float(cfg.acc.range),
        np.asarray(cfg.acc.lever_arm, float), float(cfg.environment.gravity),
        rv, np.zeros(3), np.zeros(3),
        has_mag, index.astype(np.int64), c(cfg.mag.soft_iron, dtype=float), np.asarray(cfg.mag.hard_iron, float),
        np.asarray(cfg.mag.motor_coef, float), c(mag_noise), float(cfg.mag.range), earth_field(cfg.environment),
        src, mom, sources is not None,
        np.zeros((int(round(cfg.mag.latency_s * cfg.imu.rate_hz)) + 1, 8)),
        dlpf_alpha(cfg.gyro.dlpf_hz, cfg.imu.rate_hz), dlpf_alpha(cfg.acc.dlpf_hz, cfg.imu.rate_hz), np.zeros(6),
    )  # fmt: skip


@njit(cache=True, inline="always")
def _clip(v, limit):
    return min(max(v, -limit), limit)


@njit(cache=True, inline="always")
def sample_imu(m, k, q, acc_n, w, wdot, vib_acc, vib_gyr, gyr, acc):
    """IMU sample ``k`` from the true attitude ``q``, acceleration ``acc_n`` (navigation frame),
    rate ``w`` and angular acceleration ``wdot`` (body), and the vibration at the IMU
    (``vib_acc``, ``vib_gyr``: :func:`rotor_vibration_step` or a prescribed motion's tone), into
    ``gyr`` and ``acc``::

        gyr = clip(DLPF(M_g ω + b_g[k] + δω + n_g[k]))
        acc = clip(DLPF(M_a f_imu + b_a[k] + δa + n_a[k])),  f_imu = Rᵀ(a − g) + ω̇ × r + ω × (ω × r)

    Returns ``f_imu``, the true specific force at the IMU."""
    for i in range(3):
        u = (
            (m.gyr_matrix[i, 0] * w[0] + m.gyr_matrix[i, 1] * w[1] + m.gyr_matrix[i, 2] * w[2] + m.gyr_bias[k, i])
            + vib_gyr[i]
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
        u = (a + vib_acc[i]) + m.acc_noise[k, i]
        if m.acc_alpha < 1.0:
            m.lp[3 + i] = lowpass_step(m.lp[3 + i], u, m.acc_alpha) if k > 0 else u
            u = m.lp[3 + i]
        acc[i] = _clip(u, m.acc_range)
    return f0, f1, f2


@njit(cache=True, inline="always")
def sample_mag(m, k, q, pos, current, mag):
    """Magnetometer sample on IMU row ``k`` into ``mag`` (NaN where no sample arrives), from the
    attitude, position and motor current of ``latency`` samples before (``m.mag_hist`` keeps
    them; call it every sample, the first at ``k = 0``)."""
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
def _sample_rows(m, motion, vibration, pos, current, out):
    """Every row of the ``motion`` (``(q, acc_n, w, wdot)``) and ``vibration`` (``(acc, gyr)``)
    sampled into ``out`` (``(gyr, acc, mag, f_imu)``)."""
    (q, acc_n, w, wdot), (vib_acc, vib_gyr), (gyr, acc, mag, f_imu) = motion, vibration, out
    for k in range(q.shape[0]):
        f_imu[k] = sample_imu(m, k, q[k], acc_n[k], w[k], wdot[k], vib_acc[k], vib_gyr[k], gyr[k], acc[k])
        sample_mag(m, k, q[k], pos[k], current[k], mag[k])


def sample_all(m: SensorModel, q, acc_n, w, wdot, vib_acc, vib_gyr, pos, current):
    """:func:`sample_imu` and :func:`sample_mag` over a whole trajectory, row by row (``m`` fresh
    from :func:`sensor_model`). Returns the gyroscope, accelerometer, magnetometer (NaN rows where
    none) and the true specific force at the IMU, each (n, 3)."""
    c = np.ascontiguousarray
    n = len(q)
    gyr, acc, mag, f_imu = (np.empty((n, 3)) for _ in range(4))
    motion = tuple(c(v, dtype=float) for v in (q, acc_n, w, wdot))
    vibration = (c(vib_acc, dtype=float), c(vib_gyr, dtype=float))
    _sample_rows(m, motion, vibration, c(pos, dtype=float), c(current, dtype=float), (gyr, acc, mag, f_imu))
    return gyr, acc, mag, f_imu
