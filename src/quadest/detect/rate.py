"""The body rate of a clipped gyroscope axis, predicted from the vehicle model (docs/vehicle.md,
*A clipped gyroscope*).

The rate follows the Euler equations with the detector's model of the vehicle
(:mod:`quadest.detect.model`: its arms, thrust with inflow, reaction torque, rotor drag
and drag; never the simulated truth's), integrated once per sample (Heun's method)::

    J ω̇ = Σ_i η_i M_i(Ω_i, ω) − ω × (J ω + h e_z) − ḣ e_z − D ω − C_r |ω| ω + J b

with ``h = I_p Σ_i η_i s_i Ω_i`` the rotors' angular momentum (``rotor_inertia``),
``Ω_i`` the rotor speeds, measured (ESC telemetry) or from the commands through the
model's motor, ``η_i`` the rotors' effectiveness as the controller knows it (a rotor given up:
0), and ``b`` per axis the angular acceleration the model misses, a random walk
(``bias_walk``). Each axis is a two-state Kalman filter (rate and ``b``) whose rate is
disturbed by white angular acceleration (``moment_noise``, and a share of the rotors' moment,
``model_error``):

- an axis reading within range corrects it with the reading (variance ``gyro_noise²``) and
  returns the reading itself;
- a clipped axis (within ``clip_margin`` of the range) returns the filter's rate, raised to the
  reading where it falls below it; at each magnetometer sample its rate over the interval
  from the field's turning in the body (robust's eq R4, :func:`quadest.rotation.kernels.mag_rate_terms`)
  corrects it, with the field's noise learnt while the axis reads within range (over
  ``mag_learn_tau``), innovations beyond ``mag_gate`` standard deviations refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import NO_ALLOCATION, njit
from quadest.detect import inputs
from quadest.detect.layout import MAX_ROTORS, MODEL
from quadest.detect.model import body_moments, model_coefficients, motor_step, rotor_thrust_yaw
from quadest.records import Params, check, layout, pack, param, params_record
from quadest.rotation.kernels import mag_rate_terms

if TYPE_CHECKING:
    from quadest.models.multirotor import MultirotorParams

STATE = layout(
    ("w", 3),  # the model's rate
    ("b", 3),  # the angular acceleration it misses
    ("P", 9),  # per axis the covariance of (w, b): P_ww, P_wb, P_bb
    ("omega_end", MAX_ROTORS),  # the rotor speeds at the end of the last interval
    ("init", 1),
    ("mprev", 3),  # the previous magnetometer sample (NaN: none yet)
    ("wsum", 3),  # the rate returned, integrated since it
    ("mdt", 1),  # the time since it
    ("gclip", 3),  # an axis clipped since it
    ("V", 3),  # per axis the field's noise (the variance of num − ω den)
    ("Vt", 3),  # and how long it has been learnt
    ("h_dot", 1),  # the rate of the rotors' angular momentum about z over the last interval
)


@dataclass(frozen=True)
class RatePredictorParams(Params):
    rotor_speeds: bool = param(
        False,
        "-",
        "the rotor speeds are measured (ESC telemetry); otherwise they follow from the commands "
        "through the model's motor",
    )
    gyro_noise: float = param(
        0.02,
        "rad/s",
        "gyroscope noise with vibration, per sample",
        "chosen: the detector's (the presets' noise and vibration)",
        "(0, 10]",
    )
    moment_noise: float = param(
        8.0,
        "rad/s²",
        "angular acceleration the model misses whatever the rotors do, white",
        "chosen: the detector's (10 % of the 80 rad/s² of aggressive flight)",
        "(0, 1e4]",
    )
    model_error: float = param(
        0.15,
        "-",
        "relative error of the modelled roll and pitch moments of the rotors, white",
        "chosen: the detector's (the ±10 % model errors the flights draw, with margin)",
        "[0, 10]",
    )
    yaw_model_error: float = param(
        0.3, "-", "relative error of the modelled yaw moment, white", "chosen: the detector's", "[0, 10]"
    )
    bias_walk: float = param(
        0.5,
        "rad/s²/√s",
        "random walk of the angular acceleration the model misses (b)",
        "tuned on flown rotor losses with a ±500 °/s gyro, seeds 100-109 (0, 0.1, 0.5, 2, 8 tried; "
        "docs/vehicle.md): the model's error moves with the operating point (a hover, a spin)",
        "[0, 1e4]",
    )
    use_mag: bool = param(True, "-", "correct a clipped axis with the magnetometer's rate (eq R4)")
    mag_learn_tau: float = param(
        1.0,
        "s",
        "time constant over which the field's noise is learnt while an axis reads within range",
        "chosen: robust's clip_learn_tau",
        "(0, 1e4]",
    )
    mag_gate: float = param(
        4.0,
        "-",
        "a magnetometer rate further than this many standard deviations from the filter's is refused",
        "chosen: a step of the motors' field at a rotor loss reads as a burst of rate",
        "(0, 1e3]",
    )
    clip_margin: float = param(
        0.005,
        "-",
        "an axis reading within this share of the gyroscope's range is clipped",
        "chosen: robust's clip_flat (a clipped reading wanders by a few tenths of a percent)",
        "[0, 0.5]",
    )


PARAM = Record = params_record(RatePredictorParams)


def rate_values(params: RatePredictorParams | None = None) -> np.ndarray:
    """The predictor's parameters packed for :func:`rate_step`."""
    params = params or RatePredictorParams()
    return pack(params.values()[f] for f in PARAM._fields)


@njit(cache=True, inline="always")
def start_filter(x, p, c, gyr, rotors):
    """The first sample: the rate from the gyroscope, no bias known, the rotor speeds read (or
    commanded), no magnetometer sample yet."""
    for j in range(3):
        x[STATE.w + j] = gyr[j]
        x[STATE.b + j] = 0.0
        x[STATE.P + 3 * j] = p[PARAM.gyro_noise] ** 2
        x[STATE.P + 3 * j + 1] = 0.0
        x[STATE.P + 3 * j + 2] = p[PARAM.moment_noise] ** 2
        x[STATE.mprev + j] = np.nan
        x[STATE.wsum + j] = 0.0
        x[STATE.gclip + j] = 0.0
        x[STATE.V + j] = 0.0
        x[STATE.Vt + j] = 0.0
    x[STATE.h_dot] = 0.0
    x[STATE.mdt] = 0.0
    for i in range(int(c[MODEL.rotors])):
        x[STATE.omega_end + i] = rotors[i]
    x[STATE.init] = 1.0


@njit(cache=True, inline="always")
def rate_derivative(c, w0, w1, w2, x, eta):
    """``ω̇`` of the model without ``b`` at the rate ``ω`` with the speeds
    ``x[STATE.omega_end:]`` (module doc), and the rotors' share of it per axis."""
    m0, m1, m2 = body_moments(c, w0, w1, w2)
    r0, r1, r2 = 0.0, 0.0, 0.0
    h = 0.0  # the rotors' angular momentum about z: gyroscopic −ω × h e_z, reaction −ḣ
    for i in range(int(c[MODEL.rotors])):
        thrust, yaw = rotor_thrust_yaw(c, i, x[STATE.omega_end + i], w0, w1, w2)
        r0 += eta[i] * thrust * c[MODEL.g + 3 * i]
        r1 += eta[i] * thrust * c[MODEL.g + 3 * i + 1]
        r2 += eta[i] * yaw
        h += eta[i] * c[MODEL.ip_s + i] * x[STATE.omega_end + i]
    m0 -= w1 * h
    m1 += w0 * h
    m2 -= x[STATE.h_dot]
    J0, J1, J2 = c[MODEL.inertia], c[MODEL.inertia + 1], c[MODEL.inertia + 2]
    D0, D1, D2 = c[MODEL.damping], c[MODEL.damping + 1], c[MODEL.damping + 2]
    return (
        (m0 + r0 - D0 * w0) / J0,
        (m1 + r1 - D1 * w1) / J1,
        (m2 + r2 - D2 * w2) / J2,
        r0 / J0,
        r1 / J1,
        r2 / J2,
    )


@njit(cache=True, inline="always")
def _grow(x, p, j, dt, rotors_part, rel):
    """Axis ``j``'s covariance over ``dt``: ``F = [[1, dt], [0, 1]]``, the rate's white
    disturbance and the bias's walk."""
    i = STATE.P + 3 * j
    pww, pwb, pbb = x[i], x[i + 1], x[i + 2]
    q = (p[PARAM.moment_noise] * dt) ** 2 + (rel * dt * rotors_part) ** 2
    x[i] = pww + 2.0 * dt * pwb + dt * dt * pbb + q
    x[i + 1] = pwb + dt * pbb
    x[i + 2] = pbb + p[PARAM.bias_walk] ** 2 * dt


@njit(cache=True, inline="always")
def _propagate(x, p, c, eta, dt):
    """The model's rate over the interval (Heun's method: the Euler step, then the mean of the
    derivatives at both ends, plus ``b``) and the covariances grown (:func:`_grow`)."""
    w0, w1, w2 = x[STATE.w], x[STATE.w + 1], x[STATE.w + 2]
    b0, b1, b2 = x[STATE.b], x[STATE.b + 1], x[STATE.b + 2]
    a0, a1, a2, r0, r1, r2 = rate_derivative(c, w0, w1, w2, x, eta)
    e0, e1, e2, _, _, _ = rate_derivative(c, w0 + dt * (a0 + b0), w1 + dt * (a1 + b1), w2 + dt * (a2 + b2), x, eta)
    x[STATE.w] = w0 + dt * (0.5 * (a0 + e0) + b0)
    x[STATE.w + 1] = w1 + dt * (0.5 * (a1 + e1) + b1)
    x[STATE.w + 2] = w2 + dt * (0.5 * (a2 + e2) + b2)
    _grow(x, p, 0, dt, r0, p[PARAM.model_error])
    _grow(x, p, 1, dt, r1, p[PARAM.model_error])
    _grow(x, p, 2, dt, r2, p[PARAM.yaw_model_error])


@njit(cache=True, inline="always")
def correct(x, j, innovation, r):
    """Axis ``j``'s scalar Kalman update of ``(w, b)`` by a rate measured ``innovation`` away
    from the filter's, with variance ``r``."""
    i = STATE.P + 3 * j
    pww, pwb, pbb = x[i], x[i + 1], x[i + 2]
    s = pww + r
    kw, kb = pww / s, pwb / s
    x[STATE.w + j] += kw * innovation
    x[STATE.b + j] += kb * innovation
    x[i] = pww - kw * pww
    x[i + 1] = pwb - kw * pwb
    x[i + 2] = pbb - kb * pwb


@njit(cache=True, inline="always")
def _fuse_axis(x, p, j, g, limit, out):
    """Axis ``j``'s reading ``g``: within range (``limit``: the range less the margin; 0: none)
    the filter corrected by it and the reading returned; clipped, the filter's rate returned,
    raised to the reading where it falls below it. Returns 1 if clipped."""
    if limit > 0.0 and abs(g) >= limit:
        if x[STATE.w + j] * g < g * g:  # below the limit, or of the other sign
            x[STATE.w + j] = g
        out[j] = x[STATE.w + j]
        x[STATE.gclip + j] = 1.0
        return 1
    correct(x, j, g - x[STATE.w + j], p[PARAM.gyro_noise] ** 2)
    out[j] = g
    return 0


@njit(cache=True, inline="always")
def _mag_axis(x, p, i, num, den, kl):
    """Axis ``i`` at a magnetometer sample (eq R4's ``num``, ``den``): within range over the
    interval, the field's noise learnt against the returned (measured) rate; clipped, the
    filter corrected by the field's rate unless beyond the gate."""
    mdt = x[STATE.mdt]
    wi = x[STATE.wsum + i] / mdt
    if x[STATE.gclip + i] == 0.0:
        e = num - wi * den
        x[STATE.Vt + i] += mdt
        x[STATE.V + i] += max(kl, mdt / x[STATE.Vt + i]) * (e * e - x[STATE.V + i])
        return
    if den <= 0.0 or x[STATE.V + i] <= 0.0 or x[STATE.Vt + i] < p[PARAM.mag_learn_tau]:
        return
    r = x[STATE.V + i] / (den * den)
    innovation = num / den - wi
    if innovation * innovation > p[PARAM.mag_gate] ** 2 * (x[STATE.P + 3 * i] + r):
        return
    correct(x, i, innovation, r)


@njit(cache=True, inline="always")
def _magnetometer(x, p, mag, dt):
    """The rate returned integrated over the magnetometer's interval; at a new sample (a finite
    ``mag``) eq R4 per axis with the interval's mean rates (:func:`_mag_axis`), and the interval
    starts again."""
    if not (np.isfinite(mag[0]) and np.isfinite(mag[1]) and np.isfinite(mag[2])):
        return
    mdt = x[STATE.mdt]
    if p[PARAM.use_mag] != 0.0 and np.isfinite(x[STATE.mprev]) and mdt > 0.0:
        kl = 1.0 - math.exp(-mdt / p[PARAM.mag_learn_tau])
        m0, m1, m2 = mag[0], mag[1], mag[2]
        q0, q1, q2 = x[STATE.mprev], x[STATE.mprev + 1], x[STATE.mprev + 2]
        c0, c1, c2 = 0.5 * (m0 + q0), 0.5 * (m1 + q1), 0.5 * (m2 + q2)
        d0, d1, d2 = (m0 - q0) / mdt, (m1 - q1) / mdt, (m2 - q2) / mdt
        v0, v1, v2 = x[STATE.wsum] / mdt, x[STATE.wsum + 1] / mdt, x[STATE.wsum + 2] / mdt
        nu, de = mag_rate_terms(c0, c1, c2, d1, d2, v1, v2)
        _mag_axis(x, p, 0, nu, de, kl)
        nu, de = mag_rate_terms(c1, c2, c0, d2, d0, v2, v0)
        _mag_axis(x, p, 1, nu, de, kl)
        nu, de = mag_rate_terms(c2, c0, c1, d0, d1, v0, v1)
        _mag_axis(x, p, 2, nu, de, kl)
    for j in range(3):
        x[STATE.mprev + j] = mag[j]
        x[STATE.wsum + j] = 0.0
        x[STATE.gclip + j] = 0.0
    x[STATE.mdt] = 0.0


@njit(cache=True, **NO_ALLOCATION)
def rate_step(x, p, c, gyr, mag, rotors, eta, gyro_range, dt, out):
    """One sample: the gyroscope (rad/s), the magnetometer (any unit; NaN: no new sample), each
    rotor's measured speed or the command it was given over the interval that ends here (rad/s,
    ``p.rotor_speeds``), each rotor's effectiveness, the gyroscope's range (rad/s; 0 or inf: it
    does not clip) and the interval (s). Writes the rate into ``out`` (the reading on every
    axis within range) and returns how many axes clipped. A non-finite reading is returned as it
    is and leaves the state alone."""
    if not (np.isfinite(gyr[0]) and np.isfinite(gyr[1]) and np.isfinite(gyr[2])):
        for j in range(3):
            out[j] = gyr[j]
        return 0
    if x[STATE.init] == 0.0:
        start_filter(x, p, c, gyr, rotors)
        for j in range(3):
            out[j] = gyr[j]
        _magnetometer(x, p, mag, dt)
        return 0
    if dt > 0.0:
        measured = p[PARAM.rotor_speeds] != 0.0
        x[STATE.h_dot] = 0.0
        for i in range(int(c[MODEL.rotors])):
            begin = x[STATE.omega_end + i]
            x[STATE.omega_end + i] = rotors[i] if measured else motor_step(begin, rotors[i], c, dt)
            x[STATE.h_dot] += eta[i] * c[MODEL.ip_s + i] * (x[STATE.omega_end + i] - begin) / dt
        _propagate(x, p, c, eta, dt)
    limit = gyro_range * (1.0 - p[PARAM.clip_margin]) if np.isfinite(gyro_range) else 0.0
    n = _fuse_axis(x, p, 0, gyr[0], limit, out)
    n += _fuse_axis(x, p, 1, gyr[1], limit, out)
    n += _fuse_axis(x, p, 2, gyr[2], limit, out)
    if dt > 0.0:
        for j in range(3):
            x[STATE.wsum + j] += out[j] * dt
        x[STATE.mdt] += dt
    _magnetometer(x, p, mag, dt)
    return n


@njit(cache=True, **NO_ALLOCATION)
def rate_run(x, p, c, gyr, mag, rotors, eta, gyro_range, dt, out):
    """Batch: :func:`rate_step` over every sample (rows of ``gyr``, ``mag``, ``rotors``, ``eta``,
    ``dt``, ``out``)."""
    for k in range(dt.shape[0]):
        rate_step(x, p, c, gyr[k], mag[k], rotors[k], eta[k], gyro_range, dt[k], out[k])


def rate_sample(
    x: np.ndarray,
    p: np.ndarray,
    c: np.ndarray,
    gyr: ArrayLike,
    mag: ArrayLike,
    rotors: ArrayLike,
    eta: ArrayLike,
    gyro_range: float,
    dt: float,
    out: np.ndarray,
) -> int:
    """:func:`rate_step` (one sample, compiled, checking nothing: what compiled loops call) after
    checking its arguments: the model's rotor count, shapes and the units of the speeds
    (:mod:`quadest.detect.inputs`)."""
    who = "rate_step"
    n = inputs.model_rotors(c, who)
    inputs.state_arrays(who, x=(x, STATE.end), p=(p, len(PARAM._fields)), out=(out, 3))
    gyr, mag = (inputs.rows(who, k, a, 3, None) for k, a in (("gyr", gyr), ("mag", mag)))
    rotors = inputs.rows(who, "rotors", rotors, n, None, inputs.rotor_hint(np.size(rotors), n))
    eta = inputs.rows(who, "eta", eta, n, None)
    inputs.rotor_speeds(who, "rotors", rotors, c, run=False)
    return rate_step(x, p, c, gyr, mag, rotors, eta, float(gyro_range), float(dt), out)


class RatePredictor:
    """The rate of a clipped gyroscope axis (module doc) for one vehicle: ``vehicle`` is the
    predictor's model (a :class:`~quadest.models.multirotor.MultirotorParams`, never the
    simulated truth's), ``gyro_range`` the gyroscope's (rad/s; inf: it does not clip). Batch
    :meth:`run` and the loop's step are one compiled function."""

    def __init__(self, vehicle: MultirotorParams, gyro_range: float, params: RatePredictorParams | None = None):
        self.params = params or RatePredictorParams()
        check(self.params, "rate predictor")
        self.vehicle, self.gyro_range = vehicle, float(gyro_range)
        self._values = rate_values(self.params)
        self._model = model_coefficients(vehicle)
        self.rotors = vehicle.rotors
        self.reset()

    def reset(self) -> None:
        """Back to the start (the next sample starts from the gyroscope)."""
        self._state = np.zeros(STATE.end)

    def compiled(self) -> tuple:
        """The live arrays of :func:`rate_step` ``(x, p, c)`` for a compiled loop."""
        return self._state, self._values, self._model

    def run(
        self,
        dt: ArrayLike,
        gyr: ArrayLike,
        rotors: ArrayLike,
        eta: ArrayLike | None = None,
        mag: ArrayLike | None = None,
    ) -> np.ndarray:
        """The rate per sample over whole arrays (rows of samples; ``dt`` the interval ending at
        each, ``rotors`` the speeds or the commands over it, ``eta`` each rotor's effectiveness,
        1 if not given, ``mag`` the magnetometer, NaN rows between its samples, none if not
        given), from the current state."""
        who, k = "rate predictor", self.rotors
        dt = inputs.rows(who, "dt", dt, np.shape(dt)[0] if np.ndim(dt) == 1 else -1, None)
        n = len(dt)
        gyr = inputs.rows(who, "gyr", gyr, n, 3)
        rotors = inputs.rows(who, "rotors", rotors, n, k, inputs.rotor_hint(np.shape(rotors)[-1], k))
        eta = np.ones((n, k)) if eta is None else inputs.rows(who, "eta", eta, n, k)
        mag = np.full((n, 3), np.nan) if mag is None else inputs.rows(who, "mag", mag, n, 3)
        inputs.rotor_speeds(who, "rotors", rotors, self._model)
        out = np.empty((n, 3))
        rate_run(self._state, self._values, self._model, gyr, mag, rotors, eta, self.gyro_range, dt, out)
        return out
