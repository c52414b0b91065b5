"""Compiled pieces shared by the estimators (quadest conventions: NED/FRD, ``q_nb``).

State arrays of every estimator start with the same slots (:data:`COMMON`): ``x[0:4]`` the
attitude ``q_nb``, ``x[INIT]`` 1 once the attitude has been initialised, ``x[YAW_PENDING]`` 1
while the heading still waits for a first magnetometer sample, ``x[T_LAST]`` the timestamp of
the last sample of a batch run (NaN before; lets a run resume exactly), ``x[DECL:DECL + 2]`` the
cosine and sine of half the declination and ``x[Q_OUT:Q_OUT + 4]`` the attitude in the geographic
frame, written by :func:`publish` at the end of every step (streaming returns it without any
further arithmetic in Python). Each estimator's own
state follows from ``x[BASE]``, declared once with :func:`layout`.
"""

from pathlib import Path

import numpy as np

from quadest._jit import carray, njit
from quadest.records import layout

COMMON = layout(
    ("q", 4),
    ("init", 1),
    ("yaw_pending", 1),
    ("t_last", 1),
    ("skipped", 1),
    ("restarts", 1),
    ("mag_skipped", 1),
    ("decl", 2),
    ("q_out", 4),
    ("mag", 3),
)
INIT, YAW_PENDING, T_LAST, BASE = COMMON.init, COMMON.yaw_pending, COMMON.t_last, COMMON.end
SKIPPED, RESTARTS, MAG_SKIPPED = COMMON.skipped, COMMON.restarts, COMMON.mag_skipped
DECL, Q_OUT, MAG = COMMON.decl, COMMON.q_out, COMMON.mag

# Beyond these a value is not a measurement (docs/reliability.md): the sample is skipped.
RATE_LIMIT = 1e3  # rad/s, gyroscope (MEMS gyroscopes end near 35 rad/s)
ACC_LIMIT = 1e4  # m/s², accelerometer (about 1000 g)
MAG_LIMIT = 1e9  # magnetometer, any unit (the earth's field is 5e4 nT)
DT_LIMIT = 1e3  # s, one interval
DT_MIN = 1e-9  # s: a shorter interval is no sensor's (1/dt overflows the steps' arithmetic near 1e-308)


@njit(cache=True, inline="always")
def publish(x):
    """The end of every step: ``x[Q_OUT] = Rz(declination) ⊗ x[0:4]`` (the magnetic frame's
    attitude in the geographic frame; ``[c, 0, 0, s] ⊗ q``)."""
    c, s = x[DECL], x[DECL + 1]
    w, a, b, d = x[0], x[1], x[2], x[3]
    x[Q_OUT] = c * w - s * d
    x[Q_OUT + 1] = c * a - s * b
    x[Q_OUT + 2] = c * b + s * a
    x[Q_OUT + 3] = c * d + s * w


@njit(cache=True, inline="always")
def wrap_angle(a):
    """An angle (rad) in [−π, π)."""
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@njit(cache=True, inline="always")
def within3(v, limit):
    """Every component finite and within ±limit."""
    return abs(v[0]) <= limit and abs(v[1]) <= limit and abs(v[2]) <= limit


@njit(cache=True, inline="always")
def admit(x, gyr, acc, mag, dt):
    """Whether a sample can be used; a sample that cannot is skipped and counted in
    ``x[SKIPPED]`` (the state is left as it was, so it never becomes NaN). Refused: an interval
    that is not a finite number from ``DT_MIN`` up to ``DT_LIMIT``; a gyroscope or accelerometer value
    that is not finite or beyond any sensor. The magnetometer's value is put in ``x[MAG:MAG + 3]``
    for the step to read (:func:`admitted_mag`): as it is, or, when it is not finite or beyond any
    sensor, NaN ("no new sample": the rest of the sample is used) and counted in
    ``x[MAG_SKIPPED]``. A NaN magnetometer row means "no new sample" and is not counted."""
    ok = dt >= DT_MIN and dt <= DT_LIMIT and within3(gyr, RATE_LIMIT) and within3(acc, ACC_LIMIT)
    if not ok:
        x[SKIPPED] += 1.0
        return False
    none = np.isnan(mag[0]) and np.isnan(mag[1]) and np.isnan(mag[2])
    if none or within3(mag, MAG_LIMIT):
        x[MAG], x[MAG + 1], x[MAG + 2] = mag[0], mag[1], mag[2]
    else:
        x[MAG], x[MAG + 1], x[MAG + 2] = np.nan, np.nan, np.nan
        x[MAG_SKIPPED] += 1.0
    return True


@njit(cache=True, inline="always")
def admitted_mag(x):
    """The magnetometer sample :func:`admit` let through (NaN where it had none or a bad one)."""
    return x[MAG : MAG + 3]


@njit(cache=True, inline="always")
def finite3(v):
    return np.isfinite(v[0]) and np.isfinite(v[1]) and np.isfinite(v[2])


@njit(cache=True, inline="always")
def norm3(v):
    return np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit(cache=True)
def euler_to_q(roll, pitch, yaw):
    """ZYX Euler angles to ``q_nb`` (same as :func:`quadest.rotation.euler_to_quat`)."""
    cr, sr = np.cos(0.5 * roll), np.sin(0.5 * roll)
    cp, sp = np.cos(0.5 * pitch), np.sin(0.5 * pitch)
    cy, sy = np.cos(0.5 * yaw), np.sin(0.5 * yaw)
    q = np.empty(4)
    q[0] = cy * cp * cr + sy * sp * sr
    q[1] = cy * cp * sr - sy * sp * cr
    q[2] = cy * sp * cr + sy * cp * sr
    q[3] = sy * cp * cr - cy * sp * sr
    return q


@njit(cache=True)
def q_to_euler(q):
    """``[roll, pitch, yaw]`` of ``q_nb`` (ZYX), as :func:`quadest.rotation.quat_to_euler`
    away from gimbal lock."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    r20 = 2.0 * (x * z - w * y)
    sinp = min(1.0, max(-1.0, -r20))
    out = np.empty(3)
    out[0] = np.arctan2(2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))
    out[1] = np.arcsin(sinp)
    out[2] = np.arctan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))
    return out


@njit(cache=True)
def tilt_from_acc(acc):
    """Roll and pitch from a specific-force sample (``f_b = −g Rᵀ e_z`` at rest):
    ``roll = atan2(−f_y, −f_z)``, ``pitch = atan2(f_x, √(f_y² + f_z²))``."""
    roll = np.arctan2(-acc[1], -acc[2])
    pitch = np.arctan2(acc[0], np.sqrt(acc[1] * acc[1] + acc[2] * acc[2]))
    return roll, pitch


@njit(cache=True)
def mag_heading(mag, roll, pitch):
    """Tilt-compensated magnetic heading, rad: the magnetometer levelled by roll and pitch,
    ``m_h = Ry(pitch) Rx(roll) m``, and ``yaw = atan2(−m_h,y, m_h,x)`` (NED, FRD)."""
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    mhx = mag[0] * cp + (mag[1] * sr + mag[2] * cr) * sp
    mhy = mag[1] * cr - mag[2] * sr
    return np.arctan2(-mhy, mhx)


@njit(cache=True)
def initialise(x, acc, mag, use_mag):
    """Attitude from the first usable accelerometer (and magnetometer) sample. Returns True
    once initialised. Without a magnetometer sample the heading is 0 and ``YAW_PENDING`` is set."""
    if not finite3(acc) or norm3(acc) == 0.0:
        return False
    roll, pitch = tilt_from_acc(acc)
    yaw = 0.0
    have_mag = use_mag and finite3(mag) and norm3(mag) > 0.0
    if have_mag:
        yaw = mag_heading(mag, roll, pitch)
    x[0:4] = euler_to_q(roll, pitch, yaw)
    x[INIT] = 1.0
    x[YAW_PENDING] = 1.0 if (use_mag and not have_mag) else 0.0
    return True


@njit(cache=True)
def settle_heading(x, mag):
    """First magnetometer sample after a start without one: set the heading, keep the tilt."""
    e = q_to_euler(x[0:4])
    x[0:4] = euler_to_q(e[0], e[1], mag_heading(mag, e[0], e[1]))
    x[YAW_PENDING] = 0.0


@njit(cache=True)
def prepare(x, acc, mag, use_mag):
    """Common start of every step: initialise on the first usable sample, set a pending heading.
    Returns False while the attitude is not initialised (the step then does nothing)."""
    if x[INIT] == 0.0:
        return initialise(x, acc, mag, use_mag)
    if x[YAW_PENDING] != 0.0 and use_mag and finite3(mag) and norm3(mag) > 0.0:
        settle_heading(x, mag)
    return True


@njit(cache=True, inline="always")
def gravity_objective(qw, qx, qy, qz, a0, a1, a2):
    """The gravity objective of Madgwick's filter in the z-up earth frame (Madgwick 2011 eqs
    25-26, AFCKF eqs 21-22): ``f_g = R(q)ᵀ [0, 0, 1] − a`` for a unit up-pointing specific force
    ``a``, and the rows of its Jacobian ``J_g`` (3x4) with respect to ``q = [qw, qx, qy, qz]``.
    Returns ``(f0, f1, f2, J0, J1, J2)``; the gradient is ``J_gᵀ f_g``."""
    f0 = 2.0 * (qx * qz - qw * qy) - a0
    f1 = 2.0 * (qw * qx + qy * qz) - a1
    f2 = 2.0 * (0.5 - qx * qx - qy * qy) - a2
    J0 = (-2.0 * qy, 2.0 * qz, -2.0 * qw, 2.0 * qx)
    J1 = (2.0 * qx, 2.0 * qw, 2.0 * qz, 2.0 * qy)
    J2 = (0.0, -4.0 * qx, -4.0 * qy, 0.0)
    return f0, f1, f2, J0, J1, J2


@njit(cache=True)
def omega_matrix(w, dt):
    """``I + dt/2 Ω(ω)`` with ``Ω(ω) q = q ⊗ [0, ω]`` (first-order quaternion integration)."""
    F = np.eye(4)
    h = 0.5 * dt
    F[0, 1], F[0, 2], F[0, 3] = -h * w[0], -h * w[1], -h * w[2]
    F[1, 0], F[1, 2], F[1, 3] = h * w[0], h * w[2], -h * w[1]
    F[2, 0], F[2, 1], F[2, 3] = h * w[1], -h * w[2], h * w[0]
    F[3, 0], F[3, 1], F[3, 2] = h * w[2], h * w[1], -h * w[0]
    return F


# The batch run and the streaming call of an estimator's step: one template for every estimator.
# numba cannot cache a closure, so each estimator's pair is compiled from this source, under this
# file's name and at these lines (a compile error points here), with the step as a global.
_RUN_AND_STREAM = """\
@njit(cache=True, fastmath=fastmath)
def NAME_run(x, p, c, dt, gyr, acc, mag, q_out, diag_out):
    '''Batch: the same step over every sample, in compiled code.'''
    for k in range(len(dt)):
        step(x, p, c, gyr[k], acc[k], mag[k], dt[k], diag_out[k])
        q_out[k] = x[Q_OUT : Q_OUT + 4]  # published: in the geographic frame


def NAME_stream(x, nx, p, n_p, c, nc, gyr, acc, mag, dt, diag, nd):
    '''Streaming: the same step on the raw buffers of the C call; 1 if it raised (base.stream_address).'''
    try:
        step(carray(x, nx), carray(p, n_p), carray(c, nc), carray(gyr, 3), carray(acc, 3), carray(mag, 3), dt,
             carray(diag, nd))
    except Exception:  # a C callback cannot raise: the C call does, from the status
        return 1
    return 0
"""
_TEMPLATE_LINE = Path(__file__).read_text(encoding="utf-8").splitlines().index('_RUN_AND_STREAM = """\\') + 1


def run_and_stream(step, fastmath: bool = False) -> tuple:
    """``(run, stream)`` of the compiled ``step`` (named ``<name>_step``): ``<name>_run``, the
    batch run over every sample (``Estimator.batch``), and ``<name>_stream``, the streaming call
    (``Estimator.stream``, compiled as a C callback by ``base.stream_address``)."""
    name = step.__name__.removesuffix("_step")
    source = "\n" * _TEMPLATE_LINE + _RUN_AND_STREAM.replace("NAME", name)
    namespace = {
        "__name__": __name__,
        "njit": njit,
        "carray": carray,
        "Q_OUT": Q_OUT,
        "step": step,
        "fastmath": fastmath,
    }
    exec(compile(source, __file__, "exec"), namespace)  # noqa: S102 -- our own template, see above
    return namespace[f"{name}_run"], namespace[f"{name}_stream"]
