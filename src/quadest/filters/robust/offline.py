"""``robust-offline``: an acausal estimate from ``robust``'s model for a recording analysed
after the fact (docs/estimators.md, robust-offline). ``robust`` runs forward over the recording
and forward over the time-reversed recording (gyro negated: the same compiled step); the two
attitudes are fused sample by sample in the tangent space with the error variances each pass
reports (eq O1), and their biases by the biases' variances (eq O2). The tilt is then made
again without delay (eq O3): the strapdown with the smoothed bias, the specific force in the
almost-inertial frame low-passed forward and backward, robust's inclination correction; the
heading is the fused passes'."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, NoReturn

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import njit
from quadest.data.checks import GAP_FACTOR, GAP_MIN_S
from quadest.errors import UsageError
from quadest.filters.base import FilterResult
from quadest.filters.common import finite3
from quadest.filters.robust.params import UNKNOWN_HEADING_VAR, RobustParams
from quadest.filters.robust.step import Robust
from quadest.filters.timing import nominal_interval, sample_intervals, sample_times
from quadest.records import param
from quadest.rotation.kernels import FASTMATH, normalize_s, qmul_s, rotate_s

if TYPE_CHECKING:
    from quadest.data.recording import Recording


def reversed_recording(t, gyr, acc, mag) -> tuple:
    """The recording played backwards: times ``−t`` reversed, the accelerometer and magnetometer
    reversed, the gyro reversed, negated and moved one row (sample ``k`` spans ``(t_{k−1},
    t_k]``, so the reversed interval ``(−t_{k+1}, −t_k]`` takes ``−ω_{k+1}``; the first row,
    which spans a nominal interval, repeats the next one)."""
    t, gyr = np.asarray(t, dtype=np.float64), np.asarray(gyr, dtype=np.float64)
    g = -gyr[::-1]
    g = np.concatenate([g[:1], g[:-1]]) if len(g) else g
    mag = None if mag is None else np.ascontiguousarray(np.asarray(mag, dtype=np.float64)[::-1])
    return -t[::-1], np.ascontiguousarray(g), np.ascontiguousarray(np.asarray(acc, dtype=np.float64)[::-1]), mag


@njit(cache=True, inline="always")
def _log_s(w, x, y, z):
    """The rotation vector of a unit quaternion (the shorter way round); below 3° by the series
    of ``atan`` (to 1e-12)."""
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(x * x + y * y + z * z)
    if s < 0.025 * w:
        u2 = s * s / (w * w)
        a = 2.0 / w * (1.0 - u2 / 3.0 + u2 * u2 / 5.0)  # 2 atan(s/w) / s
    else:
        a = 2.0 * math.atan2(s, w) / s
    return a * x, a * y, a * z


@njit(cache=True, inline="always")
def _exp_s(a, b, c):
    """The unit quaternion of a rotation vector; below 0.05 rad by the series of ``cos`` and
    ``sin`` (to 1e-12: a step of the strapdown, a fused correction)."""
    th2 = a * a + b * b + c * c
    if th2 < 0.0025:
        x2 = 0.25 * th2
        s = 0.5 * (1.0 - x2 / 6.0 + x2 * x2 / 120.0)  # sin(θ/2) / θ
        return 1.0 - x2 / 2.0 + x2 * x2 / 24.0, a * s, b * s, c * s
    th = math.sqrt(th2)
    s = math.sin(0.5 * th) / th
    return math.cos(0.5 * th), a * s, b * s, c * s


def _pass_columns(res: FilterResult) -> np.ndarray:
    """A pass's diagnostics as one array, in robust's order (the batch run's own diagnostics array when
    its columns are views of it in robust's order: no copy)."""
    whole = res.diag[Robust.diag_names[0]].base
    if whole is not None and whole.shape == (len(res.t), len(Robust.diag_names)):
        return whole
    return np.column_stack([res.diag[c] for c in Robust.diag_names])


_COL = {name: i for i, name in enumerate(Robust.diag_names)}
VT, VH, CLIP, BIAS, VBIAS = (
    _COL["var_tilt"],
    _COL["var_heading"],
    _COL["clipped_axes"],
    _COL["bias_x"],
    _COL["var_bias_x"],
)
"""The columns of a pass's diagnostics the fusion reads (bias and its variance: x, y, z from there)."""


@njit(cache=True, inline="always")
def _share(pf, pb):
    """``P_f / (P_f + P_b)``: the backward pass's weight (a half where both are zero)."""
    return pf / (pf + pb) if pf + pb > 0.0 else 0.5


@njit(cache=True, inline="always")
def _fuse_attitude(qf, qb, wt, wh):
    """Eq O1: ``Exp(W Log(q_b ⊗ q_f⁻¹)) ⊗ q_f``, ``W = diag(w_t, w_t, w_h)`` in the navigation frame."""
    fw, fx, fy, fz = qf
    rw, rx, ry, rz = qmul_s(qb[0], qb[1], qb[2], qb[3], fw, -fx, -fy, -fz)
    e0, e1, e2 = _log_s(rw, rx, ry, rz)
    dw, dx, dy, dz = _exp_s(wt * e0, wt * e1, wh * e2)
    return qmul_s(dw, dx, dy, dz, fw, fx, fy, fz)


@njit(cache=True, inline="always")
def _rate_between(q0, q1, h):
    """The body rate taking ``q0`` to ``q1`` in ``h`` seconds: ``Log(q0⁻¹ ⊗ q1) / h``."""
    rw, rx, ry, rz = qmul_s(q0[0], -q0[1], -q0[2], -q0[3], q1[0], q1[1], q1[2], q1[3])
    e0, e1, e2 = _log_s(rw, rx, ry, rz)
    return e0 / h, e1 / h, e2 / h


@njit(cache=True, fastmath=FASTMATH)
def fuse_and_strapdown(passes, yaw, dt, gyr, acc, gap, out):
    """Per sample (``passes``: ``(qf, df, qb, db)``, the forward and backward passes' attitudes
    and diagnostics, robust's; the backward pass in its own, reversed order, its heading turned
    by ``yaw``; ``out``: ``(q_out, d_out, q_ib, f_i)``): eq O1, the attitudes fused, and the
    fused variances ``P = P_f P_b / (P_f + P_b)`` (tilt and heading); eq O2, the biases fused
    by theirs (the reversed gyro's bias negated); ``d_out`` = bias x/y/z, var_tilt,
    var_heading, weight_tilt, weight_heading. Then the strapdown ``q_Ib`` with the smoothed bias
    (from the identity again after a gap longer than ``gap``; a clipped sample's rate from the
    fused attitude, whose passes took it from the field, eq R4) and ``f_I = R(q_Ib) f``; an
    unusable sample holds both."""
    (qf, df, qb, db), (q_out, d_out, q_ib, f_i) = passes, out
    n = len(dt)
    cz, sz = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    gw, gx, gy, gz = 1.0, 0.0, 0.0, 0.0
    a0, a1, a2 = 0.0, 0.0, 0.0
    for k in range(n):
        j = n - 1 - k
        qbk = qmul_s(cz, 0.0, 0.0, sz, qb[j, 0], qb[j, 1], qb[j, 2], qb[j, 3])
        wt, wh = _share(df[k, VT], db[j, VT]), _share(df[k, VH], db[j, VH])
        q_out[k, 0], q_out[k, 1], q_out[k, 2], q_out[k, 3] = _fuse_attitude(
            (qf[k, 0], qf[k, 1], qf[k, 2], qf[k, 3]), qbk, wt, wh
        )
        for i in range(3):
            w = _share(df[k, VBIAS + i], db[j, VBIAS + i])
            d_out[k, i] = (1.0 - w) * df[k, BIAS + i] - w * db[j, BIAS + i]
        d_out[k, 3], d_out[k, 4] = (1.0 - wt) * df[k, VT], (1.0 - wh) * df[k, VH]  # = P_f P_b / (P_f + P_b)
        d_out[k, 5], d_out[k, 6] = wt, wh
        usable = dt[k] > 0.0 and finite3(gyr[k]) and finite3(acc[k])
        if usable:
            a0, a1, a2 = acc[k, 0], acc[k, 1], acc[k, 2]
        if dt[k] > gap:
            gw, gx, gy, gz = 1.0, 0.0, 0.0, 0.0
        elif k > 0 and usable:
            u0, u1, u2 = gyr[k, 0] - d_out[k, 0], gyr[k, 1] - d_out[k, 1], gyr[k, 2] - d_out[k, 2]
            if df[k, CLIP] > 0.0 or db[j, CLIP] > 0.0:
                u0, u1, u2 = _rate_between(q_out[k - 1], q_out[k], dt[k])
            dw, dx, dy, dz = _exp_s(u0 * dt[k], u1 * dt[k], u2 * dt[k])
            aw, ax, ay, az = qmul_s(gw, gx, gy, gz, dw, dx, dy, dz)
            gw, gx, gy, gz = normalize_s(aw, ax, ay, az)
        q_ib[k, 0], q_ib[k, 1], q_ib[k, 2], q_ib[k, 3] = gw, gx, gy, gz
        f_i[k, 0], f_i[k, 1], f_i[k, 2] = rotate_s(gw, gx, gy, gz, a0, a1, a2)


def _mean_interval(t, a, z, h) -> float:
    """The mean interval of rows ``a:z`` (the sample clock robust's low-passes run at, eq R9);
    ``h`` for a single row."""
    return float(t[z - 1] - t[a]) / (z - 1 - a) if z - 1 > a else h


@njit(cache=True, fastmath=FASTMATH)
def zero_phase_lowpass(x, h, tau, out):
    """Each of the three columns of ``x`` low-passed forward and then backward by robust's Butterworth
    (cut-off ``√2/(2π τ)``): no delay, the magnitude squared; each direction starts in steady
    state at the mean of its first ``τ`` of input (``h``: the sampling interval)."""
    n = len(x)
    fc = math.sqrt(2.0) / (2.0 * math.pi * tau)
    kk = math.tan(math.pi * min(fc * h, 0.49))
    nrm = 1.0 / (1.0 + math.sqrt(2.0) * kk + kk * kk)
    b0, a1, a2 = kk * kk * nrm, 2.0 * (kk * kk - 1.0) * nrm, (1.0 - math.sqrt(2.0) * kk + kk * kk) * nrm
    m = max(1, min(n, int(tau / h)))
    s1, s2 = np.empty(3), np.empty(3)
    for j in range(3):  # forward, from steady state at the mean of the first τ
        y0 = x[:m, j].mean()
        s1[j], s2[j] = y0 - b0 * y0, b0 * y0 - a2 * y0
    for k in range(n):
        for j in range(3):
            v = x[k, j]
            y = b0 * v + s1[j]
            s1[j] = 2.0 * b0 * v - a1 * y + s2[j]
            s2[j] = b0 * v - a2 * y
            out[k, j] = y
    for j in range(3):  # backward over the forward output, from the mean of its last τ
        y0 = out[n - m :, j].mean()
        s1[j], s2[j] = y0 - b0 * y0, b0 * y0 - a2 * y0
    for k in range(n - 1, -1, -1):
        for j in range(3):
            v = out[k, j]
            y = b0 * v + s1[j]
            s1[j] = 2.0 * b0 * v - a1 * y + s2[j]
            s2[j] = b0 * v - a2 * y
            out[k, j] = y


@njit(cache=True, fastmath=FASTMATH)
def tilt_without_delay(q_ib, y, q_h, out):
    """Eq O3: eq R1 with the zero-phase low-passed force ``y`` (``q_EI ← q_c ⊗ q_EI`` at every
    sample, ``q_Eb = q_EI ⊗ q_Ib``), and ``Rz(δ) ⊗ q_Eb`` with ``δ`` the twist about down of
    ``q_h ⊗ q_Eb⁻¹``: the tilt made here, the heading of ``q_h``."""
    iw, ix, iy, iz = 1.0, 0.0, 0.0, 0.0
    for k in range(len(y)):
        v0, v1, v2 = rotate_s(iw, ix, iy, iz, -y[k, 0], -y[k, 1], -y[k, 2])
        vn = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if vn > 0.0:
            cw = math.sqrt(max(0.0, 0.5 * (1.0 + v2 / vn)))
            cx, cy = (0.5 * v1 / vn / cw, -0.5 * v0 / vn / cw) if cw > 1e-6 else (1.0, 0.0)
            aw, ax, ay, az = qmul_s(cw, cx, cy, 0.0, iw, ix, iy, iz)
            iw, ix, iy, iz = normalize_s(aw, ax, ay, az)
        ew, ex, ey, ez = qmul_s(iw, ix, iy, iz, q_ib[k, 0], q_ib[k, 1], q_ib[k, 2], q_ib[k, 3])
        rw, rx, ry, rz = qmul_s(q_h[k, 0], q_h[k, 1], q_h[k, 2], q_h[k, 3], ew, -ex, -ey, -ez)
        tn = math.sqrt(rw * rw + rz * rz)  # the twist about down: [r_w, 0, 0, r_z] / its norm
        tw, tz = (rw / tn, rz / tn) if tn > 0.0 else (1.0, 0.0)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = qmul_s(tw, 0.0, 0.0, tz, ew, ex, ey, ez)


def heading_offset(qf, qb) -> float:
    """The constant heading (rad, about down) that takes the backward pass's frame onto the
    forward pass's when neither knows north (6-axis): the circular mean of the heading
    difference of the two attitudes."""
    dw = qf[:, 0] * qb[:, 0] + qf[:, 1] * qb[:, 1] + qf[:, 2] * qb[:, 2] + qf[:, 3] * qb[:, 3]
    dz = qb[:, 0] * qf[:, 3] - qb[:, 3] * qf[:, 0] + qb[:, 1] * qf[:, 2] - qb[:, 2] * qf[:, 1]  # (q_f ⊗ q_b⁻¹)_z
    ang = 2.0 * np.arctan2(dz, dw)
    ok = np.isfinite(ang)
    return float(np.arctan2(np.sin(ang[ok]).sum(), np.cos(ang[ok]).sum())) if ok.any() else 0.0


@dataclass(frozen=True)
class RobustOfflineParams(RobustParams):
    """robust's parameters (both passes run robust with them), and the offline stage's."""

    zero_phase_tilt: bool = param(
        True,
        "-",
        "make the tilt again from the specific force low-passed forward and backward (eq O3); "
        "off: the fused passes' tilt",
        "quadest: the fused passes' tilt keeps each pass's low-pass delay (docs/estimators.md, robust-offline)",
    )


class RobustOffline(Robust):
    """``robust`` forward and backward over a whole recording, fused by their reported
    covariances, the tilt made again without delay (acausal: batch only). Diagnostics: the
    smoothed bias ``bias_x/y/z`` (rad/s), the fused ``var_tilt`` and ``var_heading`` (rad², as
    robust's), and ``weight_tilt`` / ``weight_heading``, the backward pass's share."""

    name = "robust-offline"
    Params = RobustOfflineParams
    streaming = False
    acausal = True
    stream = None
    diag_names = ("bias_x", "bias_y", "bias_z", "var_tilt", "var_heading", "weight_tilt", "weight_heading")

    def update(self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None, *, dt: float) -> NoReturn:
        raise UsageError(
            f"{self.name} is acausal (each estimate uses the whole recording): use run() on a recording, "
            "or robust for one sample at a time"
        )

    def compiled(self) -> NoReturn:
        raise UsageError(f"{self.name} is acausal: it cannot fly in the loop (robust can)")

    def get_state(self) -> NoReturn:
        raise UsageError(f"{self.name} is acausal: it keeps no state between runs (run() takes the whole recording)")

    def set_state(self, x: ArrayLike) -> NoReturn:
        self.get_state()

    def _pass(self) -> Robust:
        """The robust that runs both passes, with this estimator's parameters, declination and
        gap; built and checked once per parameter record, started afresh (without ``q0``)."""
        one = self.__dict__.get("_one")
        if one is None or self.__dict__.get("_one_for") is not self.params:
            own = {f.name for f in fields(RobustOfflineParams)} - {f.name for f in fields(RobustParams)}
            values = {k: v for k, v in self.params.values().items() if k not in own}
            one = self._one = Robust(RobustParams(**values))
            self._one_for = self.params
        one.declination, one.max_gap_s = self.declination, self.max_gap_s
        one.reset()
        return one

    def run(
        self,
        rec: Recording | None = None,
        *,
        t: ArrayLike | None = None,
        gyr: ArrayLike | None = None,
        acc: ArrayLike | None = None,
        mag: ArrayLike | None = None,
        rate: float | None = None,
    ) -> FilterResult:
        """The smoothed attitude over a whole recording (or arrays timed by ``t`` or ``rate``),
        each run from the recording's own start and end (``q0``, if given, starts the forward
        pass)."""
        if rec is not None:
            t, gyr, acc, mag = rec.t, rec.gyr, rec.acc, rec.mag
        t = sample_times(t, rate, gyr, self.name)
        f, b = self.passes(t, gyr, acc, mag)
        return self._fused(t, gyr, acc, f, b)

    def passes(
        self, t: ArrayLike, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
    ) -> tuple[FilterResult, FilterResult]:
        """The forward pass and the backward one: ``robust`` on the recording and on
        :func:`reversed_recording` (its rows in the reversed order)."""
        one = self._pass()  # the backward pass first, then from the start again (from q0 if given)
        tr, gr, ar, mr = reversed_recording(t, gyr, acc, mag)
        b = one.run(t=tr, gyr=gr, acc=ar, mag=mr)
        if self._q0 is not None:
            one.reset(self._q0)
            f = one.run(t=t, gyr=gyr, acc=acc, mag=mag)
            self._one = None  # it keeps q0: the next backward pass must not start from it
            return f, b
        one.reset()
        return one.run(t=t, gyr=gyr, acc=acc, mag=mag), b

    def _fused(self, t, gyr, acc, f: FilterResult, b: FilterResult) -> FilterResult:
        """The forward pass ``f`` and the backward pass ``b`` (in its own reversed order) fused
        (eqs O1, O2), the tilt made again without delay (eq O3)."""
        n = len(t)
        df, db = _pass_columns(f), _pass_columns(b)
        yaw = 0.0
        if n and (df[:, VH] >= UNKNOWN_HEADING_VAR).all() and (db[:, VH] >= UNKNOWN_HEADING_VAR).all():
            yaw = heading_offset(f.q, b.q[::-1])  # neither knows north: the backward heading is its own
        dt = sample_intervals(t)
        h = nominal_interval(dt) or 1.0
        gap = self.max_gap_s or max(GAP_FACTOR * h, GAP_MIN_S)
        q, d = np.empty((n, 4)), np.empty((n, len(self.diag_names)))
        q_ib, f_i = np.empty((n, 4)), np.empty((n, 3))
        gyr, acc = (np.ascontiguousarray(v, dtype=np.float64) for v in (gyr, acc))
        fuse_and_strapdown((np.ascontiguousarray(f.q), df, b.q, db), yaw, dt, gyr, acc, gap, (q, d, q_ib, f_i))
        if self.params.zero_phase_tilt:
            bounds = [0, *np.flatnonzero(dt > gap).tolist(), n]
            y = np.empty((n, 3))
            for a, z in ((a, z) for a, z in zip(bounds[:-1], bounds[1:]) if z > a):  # each stretch between gaps
                zero_phase_lowpass(f_i[a:z], _mean_interval(t, a, z, h), self.params.tau_acc, y[a:z])
                tilt_without_delay(q_ib[a:z], y[a:z], q[a:z], q[a:z])
        return FilterResult(
            self.name,
            np.asarray(t, dtype=np.float64),
            q,
            {name: d[:, i] for i, name in enumerate(self.diag_names)},
            self.params,
            f.skipped,
            f.restarts,
            mag_skipped=f.mag_skipped,
        )
