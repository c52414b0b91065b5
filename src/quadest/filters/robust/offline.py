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
from typing import TYPE_CHECKING, NoReturn

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import njit
from quadest.data.checks import GAP_FACTOR, GAP_MIN_S
from quadest.errors import UsageError
from quadest.filters.base import FilterResult, _nominal_interval, sample_intervals, sample_times
from quadest.filters.common import finite3
from quadest.filters.robust.params import UNKNOWN_HEADING_VAR
from quadest.filters.robust.step import Robust
from quadest.rotation import quat_conj, quat_mul
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
    """The rotation vector of a unit quaternion (the shorter way round)."""
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return 2.0 * x, 2.0 * y, 2.0 * z
    a = 2.0 * math.atan2(s, w) / s
    return a * x, a * y, a * z


@njit(cache=True, inline="always")
def _exp_s(a, b, c):
    """The unit quaternion of a rotation vector."""
    th = math.sqrt(a * a + b * b + c * c)
    if th < 1e-12:
        return 1.0, 0.5 * a, 0.5 * b, 0.5 * c
    s = math.sin(0.5 * th) / th
    return math.cos(0.5 * th), a * s, b * s, c * s


@njit(cache=True, fastmath=FASTMATH)
def fuse_passes(qf, vtf, vhf, qb, vtb, vhb, q_out, vt_out, vh_out):
    """Eq O1, per sample: ``e = Log(q_b ⊗ q_f⁻¹)`` (navigation frame), ``q = Exp(W e) ⊗ q_f`` with
    ``W = diag(w_t, w_t, w_h)``, ``w = P_f / (P_f + P_b)``, and the fused variance
    ``P = P_f P_b / (P_f + P_b)``, for the tilt (about north and east) and the heading (down)."""
    for k in range(len(qf)):
        fw, fx, fy, fz = qf[k, 0], qf[k, 1], qf[k, 2], qf[k, 3]
        rw, rx, ry, rz = qmul_s(qb[k, 0], qb[k, 1], qb[k, 2], qb[k, 3], fw, -fx, -fy, -fz)
        e0, e1, e2 = _log_s(rw, rx, ry, rz)
        st, sh = vtf[k] + vtb[k], vhf[k] + vhb[k]
        wt = vtf[k] / st if st > 0.0 else 0.5
        wh = vhf[k] / sh if sh > 0.0 else 0.5
        dw, dx, dy, dz = _exp_s(wt * e0, wt * e1, wh * e2)
        q_out[k, 0], q_out[k, 1], q_out[k, 2], q_out[k, 3] = qmul_s(dw, dx, dy, dz, fw, fx, fy, fz)
        vt_out[k] = vtf[k] * vtb[k] / st if st > 0.0 else 0.0
        vh_out[k] = vhf[k] * vhb[k] / sh if sh > 0.0 else 0.0


@njit(cache=True, fastmath=FASTMATH)
def strapdown_forces(dt, gyr, acc, bias, q_ib, f_i):
    """The strapdown ``q_Ib`` with the smoothed bias (item 1) and the specific force in I,
    ``f_I = R(q_Ib) f``, for every sample; an unusable sample (its interval or a value not
    finite) holds both."""
    gw, gx, gy, gz = 1.0, 0.0, 0.0, 0.0
    a0, a1, a2 = 0.0, 0.0, 0.0
    for k in range(len(dt)):
        usable = dt[k] > 0.0 and finite3(gyr[k]) and finite3(acc[k])
        if usable:
            a0, a1, a2 = acc[k, 0], acc[k, 1], acc[k, 2]
        if k > 0 and usable:
            u0, u1, u2 = gyr[k, 0] - bias[k, 0], gyr[k, 1] - bias[k, 1], gyr[k, 2] - bias[k, 2]
            dw, dx, dy, dz = _exp_s(u0 * dt[k], u1 * dt[k], u2 * dt[k])
            aw, ax, ay, az = qmul_s(gw, gx, gy, gz, dw, dx, dy, dz)
            gw, gx, gy, gz = normalize_s(aw, ax, ay, az)
        q_ib[k, 0], q_ib[k, 1], q_ib[k, 2], q_ib[k, 3] = gw, gx, gy, gz
        f_i[k, 0], f_i[k, 1], f_i[k, 2] = rotate_s(gw, gx, gy, gz, a0, a1, a2)


@njit(cache=True, fastmath=FASTMATH)
def zero_phase_lowpass(x, dt, tau, out):
    """Each column of ``x`` low-passed forward and then backward by robust's Butterworth
    (cut-off ``√2/(2π τ)``): no delay, the magnitude squared; each direction starts in steady
    state at the mean of its first ``τ`` of input."""
    n = len(x)
    h = np.median(dt[1:]) if n > 1 else 1.0
    fc = math.sqrt(2.0) / (2.0 * math.pi * tau)
    kk = math.tan(math.pi * min(fc * h, 0.49))
    nrm = 1.0 / (1.0 + math.sqrt(2.0) * kk + kk * kk)
    b0, a1, a2 = kk * kk * nrm, 2.0 * (kk * kk - 1.0) * nrm, (1.0 - math.sqrt(2.0) * kk + kk * kk) * nrm
    m = max(1, min(n, int(tau / h)))
    for j in range(x.shape[1]):
        for direction in range(2):
            src = x[:, j] if direction == 0 else out[:, j]
            order = range(n) if direction == 0 else range(n - 1, -1, -1)
            y0 = src[:m].mean() if direction == 0 else src[n - m :].mean()
            s1, s2 = y0 - b0 * y0, b0 * y0 - a2 * y0
            for k in order:
                v = src[k]
                y = b0 * v + s1
                s1 = 2.0 * b0 * v - a1 * y + s2
                s2 = b0 * v - a2 * y
                out[k, j] = y


@njit(cache=True, fastmath=FASTMATH)
def inclination(q_ib, y, q_eb):
    """Eq R1 with the zero-phase low-passed force ``y``: ``q_EI ← q_c ⊗ q_EI`` at every sample,
    and ``q_Eb = q_EI ⊗ q_Ib``."""
    iw, ix, iy, iz = 1.0, 0.0, 0.0, 0.0
    for k in range(len(y)):
        v0, v1, v2 = rotate_s(iw, ix, iy, iz, -y[k, 0], -y[k, 1], -y[k, 2])
        vn = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if vn > 0.0:
            cw = math.sqrt(max(0.0, 0.5 * (1.0 + v2 / vn)))
            cx, cy = (0.5 * v1 / vn / cw, -0.5 * v0 / vn / cw) if cw > 1e-6 else (1.0, 0.0)
            aw, ax, ay, az = qmul_s(cw, cx, cy, 0.0, iw, ix, iy, iz)
            iw, ix, iy, iz = normalize_s(aw, ax, ay, az)
        q_eb[k, 0], q_eb[k, 1], q_eb[k, 2], q_eb[k, 3] = qmul_s(
            iw, ix, iy, iz, q_ib[k, 0], q_ib[k, 1], q_ib[k, 2], q_ib[k, 3]
        )


@njit(cache=True, fastmath=FASTMATH)
def with_heading_of(q_eb, q_h, out):
    """``Rz(δ) ⊗ q_Eb`` with ``δ`` the rotation about down that takes ``q_Eb``'s heading onto
    ``q_h``'s (the twist about down of ``q_h ⊗ q_Eb⁻¹``): the tilt of the one, the heading of
    the other."""
    for k in range(len(q_eb)):
        ew, ex, ey, ez = q_eb[k, 0], q_eb[k, 1], q_eb[k, 2], q_eb[k, 3]
        rw, rx, ry, rz = qmul_s(q_h[k, 0], q_h[k, 1], q_h[k, 2], q_h[k, 3], ew, -ex, -ey, -ez)
        d = 2.0 * math.atan2(rz, rw)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = qmul_s(
            math.cos(0.5 * d), 0.0, 0.0, math.sin(0.5 * d), ew, ex, ey, ez
        )


def heading_offset(qf, qb) -> float:
    """The constant heading (rad, about down) that takes the backward pass's frame onto the
    forward pass's when neither knows north (6-axis): the circular mean of the heading
    difference of the two attitudes."""
    dw = qf[:, 0] * qb[:, 0] + qf[:, 1] * qb[:, 1] + qf[:, 2] * qb[:, 2] + qf[:, 3] * qb[:, 3]
    dz = qb[:, 0] * qf[:, 3] - qb[:, 3] * qf[:, 0] + qb[:, 1] * qf[:, 2] - qb[:, 2] * qf[:, 1]  # (q_f ⊗ q_b⁻¹)_z
    ang = 2.0 * np.arctan2(dz, dw)
    ok = np.isfinite(ang)
    return float(np.arctan2(np.sin(ang[ok]).sum(), np.cos(ang[ok]).sum())) if ok.any() else 0.0


def turned(q, yaw: float) -> np.ndarray:
    """``Rz(yaw) ⊗ q`` for each row."""
    c, s = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    out = np.empty_like(q)
    out[:, 0] = c * q[:, 0] - s * q[:, 3]
    out[:, 1] = c * q[:, 1] - s * q[:, 2]
    out[:, 2] = c * q[:, 2] + s * q[:, 1]
    out[:, 3] = c * q[:, 3] + s * q[:, 0]
    return out


class RobustOffline(Robust):
    """``robust`` forward and backward over a whole recording, fused by their reported
    covariances, the tilt made again without delay (acausal: batch only). Diagnostics: the
    smoothed bias ``bias_x/y/z`` (rad/s), the fused ``var_tilt`` and ``var_heading`` (rad², as
    robust's), and ``weight_tilt`` / ``weight_heading``, the backward pass's share."""

    name = "robust-offline"
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

    def _pass(self) -> Robust:
        return Robust(self.params, declination=self.declination, max_gap_s=self.max_gap_s)

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
        fwd = self._pass()
        if self._q0 is not None:
            fwd.reset(self._q0)
        tr, gr, ar, mr = reversed_recording(t, gyr, acc, mag)
        return fwd.run(t=t, gyr=gyr, acc=acc, mag=mag), self._pass().run(t=tr, gyr=gr, acc=ar, mag=mr)

    def _fused(self, t, gyr, acc, f: FilterResult, b: FilterResult) -> FilterResult:
        """The forward pass ``f`` and the backward pass ``b`` (in its own reversed order) fused
        (eqs O1, O2), the tilt made again without delay (eq O3)."""
        n = len(t)
        qb = np.ascontiguousarray(b.q[::-1])
        vtb, vhb = (np.ascontiguousarray(b.diag[k][::-1]) for k in ("var_tilt", "var_heading"))
        vtf, vhf = f.diag["var_tilt"], f.diag["var_heading"]
        if n and ((vhf >= UNKNOWN_HEADING_VAR) & (vhb >= UNKNOWN_HEADING_VAR)).all():
            qb = turned(qb, heading_offset(f.q, qb))  # neither knows north: the backward heading is its own
        q, vt, vh = np.empty((n, 4)), np.empty(n), np.empty(n)
        fuse_passes(np.ascontiguousarray(f.q), vtf, vhf, qb, vtb, vhb, q, vt, vh)
        bias = np.empty((n, 3))
        for i, a in enumerate("xyz"):
            pf, pb = f.diag[f"var_bias_{a}"], b.diag[f"var_bias_{a}"][::-1]
            w = _share(pf, pb)
            bias[:, i] = (1 - w) * f.diag[f"bias_{a}"] - w * b.diag[f"bias_{a}"][::-1]  # the reversed gyro's is negated
        clipped = (f.diag["clipped_axes"] > 0) | (b.diag["clipped_axes"][::-1] > 0)
        gyr = rates_where_clipped(t, np.array(gyr, dtype=np.float64), q, bias, clipped)
        q = self._without_delay(t, gyr, np.ascontiguousarray(acc, dtype=np.float64), bias, q)
        diag = dict(zip(self.diag_names, (*bias.T, vt, vh, _share(vtf, vtb), _share(vhf, vhb))))
        return FilterResult(
            self.name,
            np.asarray(t, dtype=np.float64),
            q,
            diag,
            self.params,
            f.skipped,
            f.restarts,
            mag_skipped=f.mag_skipped,
        )

    def _without_delay(self, t, gyr, acc, bias, q_fused) -> np.ndarray:
        """Eq O3 over each stretch between gaps: the tilt of the strapdown corrected by the
        zero-phase low-pass, the heading of ``q_fused``."""
        dt = sample_intervals(t)
        gap = self.max_gap_s or max(GAP_FACTOR * _nominal_interval(dt), GAP_MIN_S)
        bounds = [0, *np.flatnonzero(dt > gap).tolist(), len(t)]
        q = np.array(q_fused)
        for a, b in zip(bounds[:-1], bounds[1:]):
            if b - a < 2:
                continue
            n = b - a
            q_ib, f_i, y, q_eb = np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 4))
            strapdown_forces(dt[a:b], gyr[a:b], acc[a:b], bias[a:b], q_ib, f_i)
            zero_phase_lowpass(f_i, dt[a:b], self.params.tau_acc, y)
            inclination(q_ib, y, q_eb)
            with_heading_of(q_eb, np.ascontiguousarray(q_fused[a:b]), q[a:b])
        return q


def _share(pf, pb) -> np.ndarray:
    """``P_f / (P_f + P_b)``: the backward pass's weight (a half where both are zero)."""
    return np.divide(pf, pf + pb, out=np.full(len(pf), 0.5), where=pf + pb > 0)


def rates_where_clipped(t, gyr, q, bias, clipped) -> np.ndarray:
    """The gyro with each clipped row replaced by the fused attitude's rate plus the bias (the
    passes take a clipped axis's rate from the field, eq R4): ``Log(q_{k−1}⁻¹ ⊗ q_k) / Δt``."""
    rows = np.flatnonzero(clipped[1:]) + 1
    if len(rows):
        d = quat_mul(quat_conj(q[rows - 1]), q[rows])
        d *= np.where(d[:, :1] < 0, -1.0, 1.0)
        s = np.linalg.norm(d[:, 1:], axis=1, keepdims=True)
        ang = 2.0 * np.arctan2(s, d[:, :1])
        rv = np.where(s > 1e-12, d[:, 1:] * ang / np.maximum(s, 1e-300), 2.0 * d[:, 1:])
        h = np.diff(t)[rows - 1][:, None]
        gyr[rows] = np.where(h > 0, rv / np.where(h > 0, h, 1.0) + bias[rows], gyr[rows])
    return np.ascontiguousarray(gyr)
