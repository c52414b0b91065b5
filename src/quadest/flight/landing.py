"""The landing that ends a flight (`FlightParams.landing_m_s`), as an autopilot flies it.

- The reference its trajectory generator would give: from the flight's own position, velocity
  and acceleration it stops, then descends at the landing's speed onto the ground and on (the
  descent's speed holds until the autopilot knows it has landed), touching down a given time
  before the end, within PX4's default limits. In that descent the SE(3) controller keeps
  PX4's thrust limits (:func:`~quadest.control.se3.limited_thrust`).
- Its land detector (PX4's multicopter one, its defaults): a ground contact (a commanded descent
  with low thrust and no motion) turns the horizontal thrust off, a maybe-landed (less thrust
  still, no rotation) turns all thrust off: the rotors at idle.

docs/detection.md, *The landing's reference* and *The land detector*."""

from __future__ import annotations

import math

import numpy as np

from quadest._jit import njit
from quadest.control.se3 import thrust_floor
from quadest.errors import UsageError
from quadest.flight.phases import FLYING, PHASE
from quadest.records import compiled_record
from quadest.rotation.kernels import rot_entries

LANDING_JERK = 4.0
"""m/s³: the landing's largest jerk once the flight's acceleration is unwound (PX4's default,
MPC_JERK_AUTO)."""

UNWIND_S = 0.5
"""s: the longest the landing takes to unwind the flight's own acceleration (the stop's jerk
raised to ``|a0| / UNWIND_S`` when that is more than :data:`LANDING_JERK`); chosen: at 4 m/s³
a figure eight's 7-12 m/s² took 2-3 s to unwind and the reference ran on sideways (20 m from a
circle at 8 m/s²)."""

GRID_S = 0.01
"""s: the spacing of the starts tried before the one nearest the touchdown asked is refined
to the sample."""

STOPPED_M_S = 0.05
"""m/s: the stop is complete below this horizontal speed (with the acceleration below 0.5 m/s²)."""


def landing_reference(ref, t, speed: float, height: float, after_s: float = 1.0, accel: float = 3.0):
    """``ref`` ending in a landing: from the start that touches down ``after_s`` before the end
    the reference, starting from the flight's own position, velocity and acceleration, stops,
    then descends at ``speed`` (m/s; less where the height does not allow it) to ``height``
    below the origin and on into the ground until the end (as an autopilot's landing does until
    its land detector says landed: :func:`land_detector`), with at most
    ``accel`` (m/s²) and a bounded jerk (:func:`landing_path`); ``accel`` 0: all at once,
    steps in speed that cut the thrust. The heading holds the start's. A flight too short to
    stop and descend is a usage error."""
    if not (np.isfinite(speed) and 0.0 < speed <= 10.0):
        raise UsageError(f"landing speed must be within (0, 10] m/s, got {speed}")
    if not (np.isfinite(accel) and 0.0 <= accel <= 100.0):
        raise UsageError(f"landing acceleration must be within [0, 100] m/s², got {accel}")
    p, v, a, yaw = (np.array(x, dtype=float) for x in ref)
    t = np.asarray(t, dtype=float)
    if not all(np.isfinite(x).all() for x in (t, p, v, a, yaw)):
        raise UsageError("the reference to end in a landing has non-finite values")
    k = landing_start(p, v, a, t, speed, height, t[-1] - after_s, accel)
    out = np.empty((3, len(t) - k, 3))
    landing_path(p[k], v[k], a[k], t[k:], speed, height, accel, out, False)
    p[k:], v[k:], a[k:], yaw[k:] = out[0], out[1], out[2], yaw[k]
    return p, v, a, yaw


def landing_start(p, v, a, t, speed: float, height: float, touch_t: float, accel: float) -> int:
    """The sample from which the landing touches down nearest ``touch_t``, having stopped first:
    every start on a :data:`GRID_S` grid tried (the touchdown's time is not monotonic in the
    start: the stop's length depends on where in a manoeuvre it begins), then the samples about
    the best; a start that touches down 2 s late or more is not one."""
    n = len(t)
    step = max(1, int(round(GRID_S / max(float(np.median(np.diff(t))), 1e-9)))) if n > 1 else 1
    reach = (height - p[:, 2].min()) / speed + 2.0 * np.abs(v).max() / max(accel, 0.5)
    first = int(np.searchsorted(t, touch_t - reach - 2.0 * np.abs(a).max() / LANDING_JERK - 3.0))
    last, end = int(np.searchsorted(t, touch_t)), min(int(np.searchsorted(t, touch_t + 2.0)) + 1, n)
    buf = np.empty((3, n, 3))

    def miss(k):
        down = landing_path(p[k], v[k], a[k], t[k:end], speed, height, accel, buf[:, : end - k], True)
        return abs(t[k + down] - touch_t) if down >= 0 else np.inf

    tried = {k: miss(k) for k in range(max(first, 0), min(last, n - 1) + 1, step)}
    best = min(tried, key=tried.get, default=None)
    if best is None or not np.isfinite(tried[best]):
        raise UsageError(
            f"a landing at {speed:g} m/s does not fit in this flight: it cannot stop and reach the ground "
            f"{height:g} m down by {touch_t:.2f} s; fly longer or land faster (FlightParams.landing_m_s)"
        )
    near = {k: miss(k) for k in range(max(best - step, 0), min(best + step, n - 1) + 1)}
    return min(near, key=near.get)


@njit(cache=True)
def landing_path(p0, v0, a0, t, speed, height, accel, out, early=False):
    """Position, velocity and acceleration (``out[0..2]``) at ``t`` of a landing from
    ``(p0, v0, a0)`` at ``t[0]``: first to a standstill, then to ``speed`` down, the
    acceleration steered towards the speed error's direction, of size
    ``min(accel, √(2 j |Δv|), |Δv|/Δt)`` (what the jerk ``j`` can still bring to zero as the error
    closes, and no more than closes it within a sample) and changed by at most ``j``:
    max(:data:`LANDING_JERK`, ``|a0|`` / :data:`UNWIND_S`) until stopped, then
    :data:`LANDING_JERK`; on down through ``height`` at ``speed``. ``accel`` 0: the target
    speed at once. Returns the sample at which it reaches ``height`` having stopped (-1: none;
    ``early``: returns there)."""
    n = t.shape[0]
    pk, vk, ak = p0.copy(), v0.copy(), a0.copy()
    jerk = max(LANDING_JERK, math.sqrt(a0[0] ** 2 + a0[1] ** 2 + a0[2] ** 2) / UNWIND_S)
    stopped = accel <= 0.0
    down = -1
    for i in range(n):
        dt = t[i] - t[i - 1] if i > 0 else 0.0
        if accel <= 0.0:
            vk[0], vk[1], vk[2] = 0.0, 0.0, speed
            ak[:] = 0.0
        elif dt > 0.0:
            _steer(vk, ak, speed if stopped else 0.0, jerk, accel, dt)
        for j in range(3):
            if accel > 0.0 or j == 2:
                pk[j] += vk[j] * dt
        if not stopped and math.hypot(vk[0], vk[1]) < STOPPED_M_S and math.sqrt(ak @ ak) < 0.5:
            stopped, jerk = True, LANDING_JERK
        if down < 0 and pk[2] >= height:
            down = i if stopped else n
            if early:
                break
        out[0, i], out[1, i], out[2, i] = pk, vk, ak
    return down if down < n else -1


@njit(cache=True, inline="always")
def _steer(v, a, down_speed, jerk, accel, dt):
    """One sample of the speed's approach to ``(0, 0, down_speed)`` (:func:`landing_path`)."""
    e0, e1, e2 = -v[0], -v[1], down_speed - v[2]
    size = max(math.sqrt(e0 * e0 + e1 * e1 + e2 * e2), 1e-12)
    want = min(accel, math.sqrt(2.0 * jerk * size), size / dt) / size
    s0, s1, s2 = e0 * want - a[0], e1 * want - a[1], e2 * want - a[2]
    step = min(1.0, jerk * dt / max(math.sqrt(s0 * s0 + s1 * s1 + s2 * s2), 1e-12))
    a[0] += s0 * step
    a[1] += s1 * step
    a[2] += s2 * step
    v[0] += a[0] * dt
    v[1] += a[1] * dt
    v[2] += a[2] * dt


CONTACT_S, MAYBE_S = 0.35, 0.25
"""s: how long a ground contact's and a maybe-landed's conditions must hold (PX4's
GROUND_CONTACT_TRIGGER_TIME_US, MAYBE_LAND_DETECTOR_TRIGGER_TIME_US)."""

Z_VEL_MAX, XY_VEL_MAX, ROT_MAX = 0.25, 1.5, math.radians(20.0)
"""The land detector's limits on the vertical and horizontal speed (m/s) and the roll and pitch
rate (rad/s): PX4's LNDMC_Z_VEL_MAX (as most ``0.45`` times the landing's speed), LNDMC_XY_VEL_MAX,
LNDMC_ROT_MAX; widened 2.5 times once maybe landed (its LAND_DETECTOR_LAND_PHASE)."""

CONTACT_THRUST, MAYBE_THRUST = 0.3, 0.1
"""The collective thrust below which a ground contact and a maybe-landed may be, as a share of
the way from the controller's least thrust in the descent (PX4's MPC_THR_MIN) to the hover's
(PX4's, without a hover-thrust estimate)."""

LandDetector = compiled_record(
    "LandDetector",
    "The autopilot's land detector (:func:`land_detector`): the sample from which the reference "
    "descends at the landing's speed (-1: no landing), the limits on the vertical and horizontal "
    "speed and the roll and pitch rate, the collective thrusts (N) below which a ground contact and "
    "a maybe-landed may be, the samples each must hold, the rotors' thrust coefficient; the samples "
    "each stage's conditions have held and the sample each stage was first reached (-1: never).",
    descend_k="i8",
    climb_max="f8",
    xy_max="f8",
    rot_max="f8",
    thr_contact="f8",
    thr_maybe="f8",
    contact_n="i8",
    maybe_n="i8",
    k_f="f8",
    held="i8[:]",
    first="i8[:]",
)


def land_detector(vehicle=None, rate: float = 1.0, descend_k: int = -1, speed: float = 0.0):
    """The :data:`LandDetector` of a flight flown at ``rate`` (Hz) whose reference's final
    descent starts at sample ``descend_k`` (:func:`descent_start`) and lands at ``speed`` (m/s;
    0 or ``descend_k`` -1: the detector off): PX4's multicopter land detector with its defaults
    (module doc); its least thrust the SE(3) controller's in the descent (PX4's MPC_THR_MIN,
    :func:`~quadest.control.se3.limited_thrust`)."""
    on = speed > 0.0 and descend_k >= 0 and vehicle is not None
    descend_k = descend_k if on else -1
    hover = vehicle.mass_kg * vehicle.gravity if on else 0.0
    idle = thrust_floor(hover, vehicle.rotors * vehicle.k_f * vehicle.omega_max**2) if on else 0.0
    return LandDetector.make(
        descend_k=descend_k,
        climb_max=min(0.45 * speed, Z_VEL_MAX),
        xy_max=XY_VEL_MAX,
        rot_max=ROT_MAX,
        thr_contact=idle + CONTACT_THRUST * (hover - idle),
        thr_maybe=idle + MAYBE_THRUST * (hover - idle),
        contact_n=max(1, int(round(CONTACT_S * rate))),
        maybe_n=max(1, int(round(MAYBE_S * rate))),
        k_f=float(vehicle.k_f) if on else 0.0,
        held=np.zeros(2, np.int64),
        first=np.full(2, -1, np.int64),
    )


def descent_start(v_down, speed: float) -> int:
    """The first sample of the reference's final descent at 0.9 of ``speed`` or more (PX4's
    commanded descent) given its NED z speed per sample ``v_down``; -1: none (``speed`` 0: no
    landing)."""
    if speed <= 0.0:
        return -1
    v_down = np.asarray(v_down, float)
    below = np.flatnonzero(v_down < 0.9 * speed)
    start = 0 if below.size == 0 else int(below[-1]) + 1
    return start if start < v_down.shape[0] else -1


@njit(cache=True, inline="always")
def detect_landing(k, loop):
    """The land detector at sample ``k``, before the controller (PX4's, module doc), from the
    estimated velocity and rate and the collective thrust last commanded; once a ground contact
    holds, the reference's sample ``k`` asks for no horizontal force and the present heading."""
    land, nav, control = loop.landing, loop.nav, loop.control
    if land.descend_k < 0 or k < land.descend_k or loop.state[PHASE] != FLYING:
        return
    xh, cmd = nav.xh, control.cmd
    thrust = 0.0
    for i in range(cmd.shape[0]):
        thrust += land.k_f * cmd[i] * cmd[i]
    widen = 2.5 if land.held[1] >= land.maybe_n else 1.0
    contact = (
        thrust <= land.thr_contact and abs(xh[5]) <= land.climb_max * widen and math.hypot(xh[3], xh[4]) <= land.xy_max
    )
    land.held[0] = land.held[0] + 1 if contact else 0
    touching = land.held[0] >= land.contact_n
    maybe = touching and thrust <= land.thr_maybe and math.hypot(xh[10], xh[11]) <= land.rot_max * widen
    land.held[1] = land.held[1] + 1 if maybe else 0
    for s in range(2):
        if land.first[s] < 0 and land.held[s] >= (land.contact_n if s == 0 else land.maybe_n):
            land.first[s] = k
    if touching:
        _no_horizontal_force(k, xh, control)


@njit(cache=True, inline="always")
def _no_horizontal_force(k, xh, control):
    """The reference's sample ``k`` where the vehicle is, at its speed and heading: the SE(3)
    controller's horizontal force is then zero (PX4 zeroes the horizontal thrust on a ground
    contact and sets the heading's setpoint to the present one)."""
    for j in range(2):
        control.p_d[k, j], control.v_d[k, j], control.a_d[k, j] = xh[j], xh[3 + j], 0.0
    R = rot_entries(xh[6], xh[7], xh[8], xh[9])
    control.yaw_d[k] = math.atan2(R[1][0], R[0][0])


@njit(cache=True, inline="always")
def idle_when_landed(loop):
    """Maybe landed: every rotor commanded to idle (PX4 sets the thrust's setpoint to zero)."""
    land = loop.landing
    if land.descend_k >= 0 and land.held[1] >= land.maybe_n and loop.state[PHASE] == FLYING:
        for i in range(loop.control.cmd.shape[0]):
            loop.control.cmd[i] = 0.0


def landing_summary(land, t) -> dict:
    """``{"landing": ...}``: when the land detector found the ground contact and the vehicle maybe
    landed (s; None: not); empty without a land detector."""
    if land.descend_k < 0:
        return {}
    names = ("ground_contact_s", "maybe_landed_s")
    return {"landing": {name: (float(t[k]) if 0 <= k < len(t) else None) for name, k in zip(names, land.first)}}
