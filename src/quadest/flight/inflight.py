"""A recovery started in flight (:mod:`quadest.flight.collision`): what :func:`quadest.flight.fly`
adds to a flight for it (the collision, the estimator's reset, the bank with its aerodynamic
model, the checks, the recovery controller's thresholds) and its summary."""

from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np

from quadest.flight import build
from quadest.flight.collision import Collision, CollisionParams, draw_collision
from quadest.flight.collision import watch as watch_record
from quadest.flight.phases import HOLD_Z, reads_truth
from quadest.flight.throw import ThrowParams, _held_from, _tilt_deg, fit_throw_model
from quadest.recovery import RecoveryParams
from quadest.recovery.divergence import STATE, fired_names
from quadest.rotation import quat_conj, quat_rotate


def collision_of(kind: str, seed: int, p: CollisionParams | None = None) -> Collision | None:
    """The flight's collision (:class:`~quadest.flight.common.FlightParams`' ``collision``):
    ``none``, or drawn from ``seed`` with the estimator reset or left as drawn (``drawn``) or
    always ``reset`` or ``left``."""
    if kind == "none":
        return None
    event = draw_collision(p or CollisionParams(), seed)
    if kind == "left":
        return replace(event, reset_q=None)
    if kind == "reset" and event.reset_q is None:
        return draw_collision(replace(p or CollisionParams(), reset_share=1.0), seed)
    return event


def reset(event: Collision | None, est, rate: float):
    """``(sample, state)``: the state of an estimator of ``est``'s kind (an ``InLoop``) started
    afresh at the collision's random attitude, swapped in at the collision (none: no reset, the
    truth, or a peer, whose state is its package's: left to diverge)."""
    if event is None or event.reset_q is None or est.args is None:
        return None
    fresh = copy.deepcopy(est.instance)
    fresh.reset(q0=np.array(event.reset_q))
    return int(round(event.time_s * rate)), fresh.get_state()


def bank(vehicle, cfg, gains, rp: RecoveryParams | None = None):
    """The bank of EKFs with the aerodynamic model fitted on throws at the throw's rotor speed
    (:func:`~quadest.flight.throw.fit_throw_model`, the flight's sensors)."""
    throw = ThrowParams()
    model = fit_throw_model(vehicle, cfg, throw)
    t_throw = vehicle.rotors * gains.k_f * throw.rotor_speed**2
    return build.bank(model, rp or RecoveryParams(), mass=vehicle.mass_kg, t_throw=t_throw)


def watch(params, model, rate: float, reading_hz: float):
    """The checks (off without ``params``) with ``model`` the vehicle as the controller knows it."""
    if params is None:
        return watch_record()
    return watch_record(params, model, rate_hz=rate, reading_hz=reading_hz, idle=ThrowParams().rotor_speed)


def recovery_control(params) -> dict:
    """The recovery controller's thresholds (a throw's), with the checks on."""
    if params is None:
        return {}
    throw = ThrowParams()
    return {"beta3": np.radians(throw.beta3_deg), "upright_rad": np.radians(throw.upright_switch_deg)}


def summary(flight, out: dict, loop, event: Collision | None, status, rate: float) -> dict:
    """The collision, the checks (fired or not, which, when), the recovery's handover and
    gravity error there, the fall, and whether the vehicle recovered to a hover: upright within
    30° after the handover, then its height within 0.5 m of the held height for 10 s (a throw's
    criterion); without a recovery, the height within 0.5 m of the reference for the last 10 s."""
    t, x = flight.recording.t, flight.states
    throw = ThrowParams()
    k_hit = -1 if event is None else int(round(event.time_s * rate))
    st, events = loop.watch.st, loop.record.events
    k_fire = int(st[STATE.fired_k]) if loop.watch.on else -1
    k_conv = int(events[1])
    t0 = t[k_hit] if k_hit >= 0 else 0.0
    s = {
        "collision": None if event is None else event.summary(),
        "recovery_started": k_fire >= 0,
        "divergence_s": float(t[k_fire]) if k_fire >= 0 else None,
        "divergence_delay_s": float(t[k_fire] - t0) if k_fire >= 0 and k_hit >= 0 else None,
        "checks": fired_names(int(st[STATE.fired])) if k_fire >= 0 else [],
        "check_peaks": dict(zip(("impact", "rate", "innovation"), map(float, st[STATE.peak : STATE.peak + 3])))
        if loop.watch.on
        else None,
        "free_fall_s": float(t[events[0]] - t0) if events[0] >= 0 else None,
        "handover_s": float(t[k_conv] - t0) if k_conv >= 0 else None,
        "fall_m": float(x[max(k_hit, 0) :, 2].max() - x[max(k_hit, 0), 2]) if len(x) else None,
    }
    if k_conv >= 0 and not reads_truth(loop.nav.kind):  # the bank's estimate (the truth hands over at once)
        q = x[k_conv, 6:10]
        g_true = quat_rotate(quat_conj(q[None]), np.array([[0.0, 0.0, 1.0]]))[0]
        s["gravity_error_at_handover_deg"] = float(np.degrees(np.arccos(np.clip(out["gdir"][k_conv] @ g_true, -1, 1))))
    s["hover_from_s"] = _hover_from(t, x, k_conv, k_hit, loop, throw, status)
    s["recovered"] = s["hover_from_s"] is not None if event is not None else None
    return s


def _hover_from(t, x, k_conv, k_hit, loop, throw, ok_status):
    """When the hover of :func:`summary` starts (from the collision), or None."""
    t0 = t[max(k_hit, 0)]
    if k_conv >= 0:
        up = np.flatnonzero((t >= t[k_conv]) & (_tilt_deg(x[:, 6:10]) < throw.recovered_tilt_deg))
        if not len(up):
            return None
        return _held_from(t, x[:, 2], up[0], float(loop.held[HOLD_Z]), throw.hover_tol_m, throw.hover_s, t0)
    if ok_status != 0 or t[-1] - t0 < throw.hover_s:
        return None
    last = t >= t[-1] - throw.hover_s
    off = np.abs(x[last, 2] - loop.control.p_d[: len(t)][last, 2]).max()
    return float(t[last][0] - t0) if off < throw.hover_tol_m else None
