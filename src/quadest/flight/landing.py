"""The landing that ends a flight (`FlightParams.landing_m_s`): a reference an autopilot's
trajectory generator would give. From the flight's own position, velocity and acceleration it
stops, then descends at the landing's speed onto the ground, touching down a given time before
the end, within PX4's default limits (docs/detection.md, *The landing's reference*)."""

from __future__ import annotations

import math

import numpy as np

from quadest._jit import njit
from quadest.errors import UsageError

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
    below the origin and 0.2 m further (pressing the vehicle down on its legs), with at most
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
    :data:`LANDING_JERK`; held 0.2 m below ``height`` once there. ``accel`` 0: the target
    speed at once. Returns the sample at which it reaches ``height`` having stopped (-1: none;
    ``early``: returns there)."""
    n = t.shape[0]
    pk, vk, ak = p0.copy(), v0.copy(), a0.copy()
    jerk = max(LANDING_JERK, math.sqrt(a0[0] ** 2 + a0[1] ** 2 + a0[2] ** 2) / UNWIND_S)
    stopped = accel <= 0.0
    floor = height + 0.2
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
        if pk[2] >= floor:
            pk[2], vk[2], ak[2] = floor, 0.0, 0.0
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
