"""``robust``'s step, joining its phases in the order of the block diagram (docs/estimators.md,
robust), the batch loop and the stream function over it, and the estimator's class."""

from __future__ import annotations

import math

import numpy as np

from quadest._jit import NO_ALLOCATION, njit
from quadest.filters.base import Estimator
from quadest.filters.common import INIT, admit, admitted_mag, publish, run_and_stream
from quadest.filters.robust.bias import rest_and_bias
from quadest.filters.robust.clipping import detect_clipping, held_rates, hold_clipped, rates_from_field
from quadest.filters.robust.heading import heading, latency_corrected
from quadest.filters.robust.params import PARAM, STATE, UNKNOWN_HEADING_VAR, Record, RobustParams, coefficients
from quadest.filters.robust.tilt import lever_arm, sample_clock, step_coefficients, strapdown, tilt
from quadest.rotation.kernels import FASTMATH


@njit(cache=True, fastmath=FASTMATH, **NO_ALLOCATION)
def robust_step(x, p, c, gyr, acc, mag, dt, diag):
    """One sample: clipping and the field's rates, the strapdown, rest and bias, tilt, heading."""
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    have_mag = (
        p[PARAM.use_mag] != 0.0
        and not (np.isnan(mag[0]) or np.isnan(mag[1]) or np.isnan(mag[2]))
        and (mag[0] != 0.0 or mag[1] != 0.0 or mag[2] != 0.0)
    )
    dtc = sample_clock(x, dt)  # the low-passes run at the clock's interval, the strapdown at each sample's
    step_coefficients(x, p, dtc)
    x[STATE.mag_dt] += dt
    nclip = detect_clipping(x, p, gyr, dt)
    w0, w1, w2 = held_rates(x, gyr, nclip)  # the latency is rotated out with the last rate held
    m0 = m1 = m2 = 0.0
    if have_mag:
        m0, m1, m2 = latency_corrected(p, mag, w0, w1, w2)
        rates_from_field(x, p, c, m0, m1, m2)
    if nclip:
        hold_clipped(x, p, gyr, dt, 0.0 if have_mag else x[STATE.mag_dt])
        w0, w1, w2 = held_rates(x, gyr, nclip)
    f0, f1, f2 = lever_arm(p, c, acc, w0, w1, w2)
    fn = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    # initialisation: the strapdown starts from q0 (or the identity), the rest detection's
    # low-passes from the first sample
    if x[INIT] == 0.0:
        if not fn > 0.0:
            return
        x[INIT] = 1.0
    if x[STATE.mean_n] == 0.0:
        for i in range(3):
            x[STATE.rest_g + i] = gyr[i]
            x[STATE.rest_a + i] = acc[i]
    u0, u1, u2 = strapdown(x, w0, w1, w2, dt)
    clip_b = p[PARAM.bias_clip] + p[PARAM.scale_max] * math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    at_rest, rest_rate2 = rest_and_bias(x, p, gyr, acc, nclip, dt)
    tilt(x, p, c, gyr, (f0, f1, f2), fn, (u0, u1, u2), at_rest, nclip, rest_rate2, clip_b, dtc)
    mupd = heading(x, p, c, (m0, m1, m2), have_mag, (u0, u1, u2), at_rest, nclip, clip_b, dt)
    diag[0] = 1.0 if at_rest else 0.0
    diag[1] = x[STATE.disturbed]
    diag[2] = float(nclip)
    diag[3], diag[4], diag[5] = x[STATE.bias], x[STATE.bias + 1], x[STATE.bias + 2]
    diag[6] = x[STATE.Pt]
    diag[7] = x[STATE.Ph]
    diag[8] = mupd
    diag[9], diag[10], diag[11] = x[STATE.Pb], x[STATE.Pb + 4], x[STATE.Pb + 8]
    publish(x)


robust_run, robust_stream = run_and_stream(robust_step, fastmath=FASTMATH)


class Robust(Estimator):
    """quadest's own estimator. Diagnostics: ``rest`` (1 at rest), ``mag_disturbed``,
    ``clipped_axes``, the bias ``bias_x/y/z`` (rad/s), the reported error variances ``var_tilt``
    (about north and about east, each) and ``var_heading`` (about down), rad², ``mag_update``,
    and the bias's variances ``var_bias_x/y/z`` ((rad/s)²)."""

    name = "robust"
    Params = RobustParams
    Record = Record
    coefficients = staticmethod(coefficients)
    state_size = STATE.end
    none_yet = (STATE.mprev, STATE.mprev + 1, STATE.mprev + 2)  # the last magnetometer sample: none before the first
    diag_names = (
        "rest",
        "mag_disturbed",
        "clipped_axes",
        "bias_x",
        "bias_y",
        "bias_z",
        "var_tilt",
        "var_heading",
        "mag_update",
        "var_bias_x",
        "var_bias_y",
        "var_bias_z",
    )
    step = staticmethod(robust_step)
    batch = staticmethod(robust_run)
    stream = staticmethod(robust_stream)

    def _init_state(self, x):
        p = self.params
        x[STATE.qg : STATE.qg + 4] = x[0:4]  # q0 (in the magnetic frame) or the identity: δ = 0, q_EI = 1
        x[STATE.qi] = 1.0
        x[STATE.Pb : STATE.Pb + 9] = (np.eye(3) * p.bias_init**2).ravel()
        x[STATE.mprev : STATE.mprev + 3] = np.nan
        x[STATE.Pt] = 0.0
        x[STATE.Ph] = UNKNOWN_HEADING_VAR
        x[STATE.coef_dt] = -1.0
