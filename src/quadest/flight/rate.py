"""The rate of a clipped gyroscope axis in the closed loop: the predictor of
:mod:`quadest.detect.rate` run on each sample, after the sensors and before the estimator.

It reads the gyroscope, the magnetometer, and either the rotor speeds (ESC telemetry: the true
speeds with a relative noise per reading) or the commands sent over the interval just ended; a
rotor the controller has given up counts as lost. Its model of the vehicle is the detector's
(the flown one with the per-flight errors of ``FlightParams.detector_model_error``), its gyroscope
range the sensor's configuration (as an autopilot knows it). On every axis within range it gives the gyroscope's
reading itself; on a clipped axis the model's rate. The controller reads that rate; the
estimator reads it too when asked (``to_estimator``), else the gyroscope as read.
"""

from __future__ import annotations

import numpy as np

from quadest._jit import copy_into, njit
from quadest.detect.rate import RatePredictor, RatePredictorParams, rate_step
from quadest.records import compiled_record

CLIP_RATE_MODES = ("off", "commands", "rotor-speeds")
"""Where a clipped axis's rate comes from: nowhere (the clipped reading), the model with the
rotor commands through its motor, or the model with the measured rotor speeds."""
OFF, COMMANDS, ROTOR_SPEEDS = 0, 1, 2

ClipRate = compiled_record(
    "ClipRate",
    "The rate of a clipped gyroscope axis: the mode (CLIP_RATE_MODES' index), the predictor's "
    "state, parameter and model arrays, the gyroscope's range, the speed readings' relative "
    "noise per sample, the rotors' reading and effectiveness of the sample, the rate the "
    "controller reads, what the estimator reads and whether that is the predicted rate.",
    mode="i8",
    x="f8[:]",
    p="f8[:]",
    c="f8[:]",
    gyro_range="f8",
    noise="f8[:, :]",
    reading="f8[:]",
    eta="f8[:]",
    rate="f8[:]",
    gyr="f8[:]",
    to_estimator="b1",
)


def clip_rate(mode: str = "off", *, vehicle=None, gyro_range=np.inf, n=1, noise=None, to_estimator=False):
    """The loop's :data:`ClipRate`: the predictor with ``vehicle`` as its model (its own, never
    the simulated truth's) for a gyroscope of ``gyro_range`` (rad/s), the rotor speed readings'
    relative ``noise`` per sample (``rotor-speeds``); ``off`` (or a gyroscope that does not
    clip): the reading as it is."""
    if mode not in CLIP_RATE_MODES:
        raise ValueError(f"unknown clip rate {mode!r}; clip_rate: {', '.join(CLIP_RATE_MODES)}")
    if vehicle is None or not np.isfinite(gyro_range) or gyro_range <= 0:
        mode = "off"
    rotors = 1 if vehicle is None else vehicle.rotors
    if mode == "off":
        x, p, c = np.zeros(1), np.zeros(1), np.zeros(1)
    else:
        params = RatePredictorParams(rotor_speeds=mode == "rotor-speeds")
        x, p, c = RatePredictor(vehicle, gyro_range, params).compiled()
    return ClipRate.make(
        mode=CLIP_RATE_MODES.index(mode),
        x=x,
        p=p,
        c=c,
        gyro_range=float(gyro_range),
        noise=np.zeros((n, rotors)) if noise is None else np.ascontiguousarray(noise, dtype=float),
        reading=np.zeros(rotors),
        eta=np.ones(rotors),
        rate=np.zeros(3),
        gyr=np.zeros(3),
        to_estimator=bool(to_estimator) and mode != "off",
    )


@njit(cache=True, inline="always")
def predict_rate(k, x, loop):
    """Sample ``k``: the rate the controller reads (``nav.clip.rate``) and what the estimator
    reads (``nav.clip.gyr``) from the gyroscope just sampled (module doc)."""
    cr, gyr = loop.nav.clip, loop.sensing.gyr
    if cr.mode == OFF:
        copy_into(cr.rate, gyr)
        copy_into(cr.gyr, gyr)
        return
    fault, cmd = loop.control.fault, loop.control.cmd
    for i in range(cr.reading.shape[0]):
        cr.eta[i] = 0.0 if fault[0] >= 0 and k >= fault[0] and i == fault[1] else 1.0
        cr.reading[i] = x[13 + i] * (1.0 + cr.noise[k, i]) if cr.mode == ROTOR_SPEEDS else cmd[i]
    sensing = loop.sensing
    rate_step(cr.x, cr.p, cr.c, gyr, sensing.mag, cr.reading, cr.eta, cr.gyro_range, sensing.dt, cr.rate)
    copy_into(cr.gyr, cr.rate if cr.to_estimator else gyr)
