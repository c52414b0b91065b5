"""The closed loop's records (:mod:`quadest.flight.loop`) built by name from the flight's
values: every flight (:func:`quadest.flight.fly`, a throw, the truth-only SE(3) flight) makes
its loop here."""

from __future__ import annotations

import numpy as np

from quadest.control import FtcParams
from quadest.control.registry import Control, controller_id
from quadest.detect import Detector, DetectorParams
from quadest.detect.layout import DIAG, STATE, STATISTICS
from quadest.flight.collision import watch as watch_record
from quadest.flight.detection import DETECTION_MODES, Detection
from quadest.flight.landing import land_detector
from quadest.flight.loop import MAX_RATE, MAX_SPEED, Loop, Navigation, Plant, Record, Sensing, record_arrays
from quadest.flight.phases import NAV, PHASES, Bank
from quadest.flight.rate import clip_rate
from quadest.models.multirotor import with_ground, work
from quadest.recovery import RecoveryParams
from quadest.recovery.logic import initial_bank
from quadest.recovery.sphere import spread_points


def plant(
    vehicle, *, h, substeps, ground_z, failure=None, sampled=(1.0, 1), hand=None, limits=True, zero_failed=True,
    collision=None, wind=None, legs=False,
):  # fmt: skip
    """The :data:`~quadest.flight.loop.Plant` of ``vehicle``: a ``failure``
    (:class:`~quadest.sim.faults.Failure`) over a flight ``sampled`` at ``rate`` Hz for ``n``
    samples (``(rate, n)``), the ``hand``'s ``(states, derivatives)`` until the release, a
    ``collision`` (:class:`~quadest.flight.collision.Collision`), the flight ended by the ground
    at ``ground_z`` and (``limits``) by lost control; the ``wind`` (NED, m/s, one row per sample;
    none: still air); with ``legs`` the vehicle stands on legs that touch the ground first
    (:func:`~quadest.models.multirotor.with_ground`)."""
    (rate, n), n_rot, nx = sampled, vehicle.rotors, 13 + vehicle.rotors
    dynamics = vehicle.vehicle()
    if legs:
        dynamics = with_ground(dynamics, ground_z)
    hand_x, hand_dx = hand if hand is not None else (np.zeros((1, nx)), np.zeros((0, nx)))
    return Plant.make(
        vehicle=dynamics,
        h=h,
        substeps=substeps,
        ground_z=ground_z,
        max_rate=MAX_RATE if limits else np.inf,
        max_speed=MAX_SPEED if limits else np.inf,
        tw=vehicle.rotors * vehicle.k_f * vehicle.omega_max**2 / (vehicle.mass_kg * vehicle.gravity),
        eta=np.ones(n_rot),
        drive=np.ones(n_rot),
        imb=np.zeros(n_rot),
        **failure_profile(failure, rate, n, n_rot),
        zero_failed=zero_failed,
        hit_k=-1 if collision is None else int(round(collision.time_s * rate)),
        hit_n=0 if collision is None else max(1, int(round(collision.impact_s * rate))),
        hit_dv=np.zeros(3) if collision is None else np.array(collision.dv, float),
        hit_dw=np.zeros(3) if collision is None else np.array(collision.dw, float),
        hand_x=np.ascontiguousarray(hand_x, dtype=float),
        hand_dx=np.ascontiguousarray(hand_dx, dtype=float),
        wind=np.zeros((0, 3)) if wind is None else np.ascontiguousarray(wind, dtype=float),
        work=work(dynamics, nx),
        dx=np.zeros(nx),
        Fb=np.empty(3),
        Mb=np.empty(3),
        thrusts=np.zeros(n_rot),
    )


def failure_profile(failure, rate, n, rotors) -> dict:
    """The plant's failure fields: the profile from its first sample (none: no rows) and the
    rotor the oracle knows lost and from which sample (only a complete loss)."""
    if failure is None:
        empty = np.zeros((0, rotors))
        return dict(fail_k=-1, fail_eta=empty, fail_drive=empty, fail_imb=empty, lost_rotor=-1, lost_k=-1)
    k0, eta, drive, imb = failure.profile(rate, n, rotors)
    lost = failure.rotor if failure.complete else -1
    return dict(
        fail_k=k0, fail_eta=eta, fail_drive=drive, fail_imb=imb, lost_rotor=lost, lost_k=round(failure.lost_s * rate)
    )


def sensing(sm, *, dt, rotors, position0, every=1, delay=0, noise=None, n=1, on=True, baro=None):
    """The :data:`~quadest.flight.loop.Sensing` of the sensor model ``sm`` at ``dt``, and a
    position sensor every ``every`` samples, ``delay`` samples late, with ``noise`` (one row per
    reading; none: noise-free), its history starting at ``position0``; the barometer's
    ``(lag coefficients, noise)`` per sample (:func:`~quadest.flight.common.barometer_draws`;
    none: no barometer)."""
    n_read = (n - 1) // every + 1
    vib = np.zeros(2 * rotors + 1)  # quadest.sim.sensors.vibration_state
    vib[rotors:] = np.nan
    return Sensing.make(
        sm=sm,
        on=on,
        dt=dt,
        gyr=np.zeros(3),
        acc=np.zeros(3),
        mag=np.zeros(3),
        vib=vib,
        every=every,
        delay=delay,
        noise=np.zeros((n_read, 3)) if noise is None else np.ascontiguousarray(noise, dtype=float),
        hist=np.tile(np.asarray(position0, float), (delay + 1, 1)),
        reading=np.array(position0, float),
        baro_a=np.zeros(0) if baro is None else np.ascontiguousarray(baro[0], dtype=float),
        baro_noise=np.zeros(0) if baro is None else np.ascontiguousarray(baro[1], dtype=float),
        baro_lag=np.full(1, -float(position0[2])),
        baro=np.full(1, np.nan),
    )


def navigation(kind: str, x0, gain=None, clip=None, reset=None):
    """The :data:`~quadest.flight.loop.Navigation` reading ``kind`` (:data:`~quadest.flight.phases.NAV`);
    the position and velocity estimates start at the truth (on the pad); ``clip`` the rate of a
    clipped gyroscope axis (:func:`~quadest.flight.rate.clip_rate`; none: the reading as it is);
    ``reset`` ``(sample, state)``: the estimator's state swapped in at that sample (none: never)."""
    return Navigation.make(
        kind=NAV[kind],
        xh=np.zeros(13),
        q_est=np.array([1.0, 0.0, 0.0, 0.0]),
        ph=np.array(x0[0:3], float),
        vh=np.array(x0[3:6], float),
        gain=np.zeros((3, 2)) if gain is None else np.ascontiguousarray(gain, dtype=float),
        clip=clip_rate() if clip is None else clip,
        innov=np.zeros(3),
        reset_k=-1 if reset is None else int(reset[0]),
        reset_x=np.zeros(1) if reset is None else np.ascontiguousarray(reset[1], dtype=float),
    )


def control(
    controllers: dict, *, gains, ftc, reference, fault=(-1, -1), cmd0, beta3=0.0, upright_rad=0.0, limited_k=-1
):  # fmt: skip
    """The :data:`~quadest.control.registry.Control` flying ``controllers`` (phase name →
    controller name) along ``reference`` ``(p_d, v_d, a_d, yaw_d)``, the rotors first at ``cmd0``;
    ``ftc`` the fault-tolerant gains for each rotor, ``fault`` ``(sample, rotor)`` when the loss is
    known beforehand (an oracle; else found in flight); from sample ``limited_k`` on (-1: never)
    the SE(3) controller's thrust within an autopilot's limits (a landing's descent)."""
    by_phase = np.full(len(PHASES), controller_id("idle"), np.int64)
    for phase, name in controllers.items():
        by_phase[PHASES.index(phase)] = controller_id(name)
    p_d, v_d, a_d, yaw_d = (np.array(a, dtype=float) for a in reference)
    return Control.make(
        by_phase=by_phase,
        gains=gains,
        ftc=ftc,
        p_d=p_d,
        v_d=v_d,
        a_d=a_d,
        yaw_d=yaw_d,
        fault=np.array(fault, np.int64),
        integral=np.zeros(3),
        cmd=np.array(cmd0, float),
        beta3=beta3,
        upright_rad=upright_rad,
        limited_k=limited_k,
    )


def unused_ftc_gains(vehicle):
    """Fault-tolerant gains of the record's type for a loop that never flies that controller
    (given a yaw damping, so nothing is fitted)."""
    return (FtcParams(yaw_damping=1e-3).gains(vehicle, 0),) * vehicle.rotors


def bank(model=None, rp: RecoveryParams | None = None, *, mass=1.0, t_throw=0.0):
    """The recovery's :data:`~quadest.flight.phases.Bank` with the aerodynamic ``model`` (none:
    a bank of one hypothesis that never runs, for a flight without a throw)."""
    rp = rp or RecoveryParams()
    H = rp.n_hypotheses if model is not None else 1
    Vb, Qr, Pb, Lb, Zb = initial_bank(rp, spread_points(H) if model is not None else np.array([[0.0, 0.0, 1.0]]))
    A, B, C = (
        (model.A, model.B, model.C) if model is not None else (np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 10)))
    )
    A, B, C = (np.ascontiguousarray(m, dtype=float) for m in (A, B, C))
    return Bank.make(
        prm=rp.bank_record(mass),
        A=A,
        B=B,
        C=C,
        Cn=C.copy(),
        Vb=Vb,
        Qr=Qr,
        Pb=Pb,
        Lb=Lb,
        Zb=Zb,
        Qr0=Qr.copy(),
        Pb0=Pb.copy(),
        prob=np.empty(H),
        gd=np.empty((H, 3)),
        V1=np.zeros((1, 3)),
        Q1=np.zeros((1, 4)),
        P1=np.zeros((1, 6, 6)),
        Z1=np.zeros(1),
        w_prev=np.zeros(3),  # the gyro before the first sample: at rest in the hand
        beta1=rp.beta1,
        detect_samples=rp.detect_samples,
        beta2=rp.beta2,
        rearm_samples=rp.rearm_samples,
        dwell_s=rp.dwell_s,
        baro_var=rp.baro_std**2,
        t_throw=t_throw,
    )


def detection(mode="oracle", *, vehicle=None, params=None, n=1, noise=None, imu_position=(0.0, 0.0, 0.0)):
    """The loop's :data:`~quadest.flight.detection.Detection`: the detector (``params``, a
    :class:`~quadest.detect.DetectorParams`) with ``vehicle`` as its model of the vehicle (the
    detector's own), the rotor speed readings' relative ``noise`` per sample; ``oracle``: none."""
    rotors = 1 if vehicle is None else vehicle.rotors
    if mode == "oracle":
        x, p, c = np.zeros(STATE.end), np.zeros(1), np.zeros(1)
    else:
        det = Detector(
            vehicle, params or DetectorParams(rotor_speeds=mode == "rotor-speeds"), imu_position=imu_position
        )
        x, p, c, _ = det.compiled()
    return Detection.make(
        mode=DETECTION_MODES.index(mode),
        x=x,
        p=p,
        c=c,
        diag=np.zeros(DIAG),
        noise=np.zeros((n, rotors)) if noise is None else np.ascontiguousarray(noise, dtype=float),
        reading=np.zeros(rotors),
        found=np.full(2, -1, np.int64),
        eta=np.full((n if mode != "oracle" else 1, rotors), np.nan),
        statistics=np.full((n if mode != "oracle" else 1, STATISTICS), np.nan),
    )


def loop(*, plant, sensing, nav, bank, control, detection, n, rotors, phase, watch=None, landing=None):
    """The :data:`~quadest.flight.loop.Loop` of ``n`` samples starting in ``phase``, with its
    record; ``watch`` the divergence checks (:func:`~quadest.flight.collision.watch`; none: off);
    ``landing`` the land detector (:func:`~quadest.flight.landing.land_detector`; none: no landing)."""
    record = Record.make(**record_arrays(n, rotors))
    state = np.array([PHASES.index(phase), 0, 0], np.int64)
    return Loop.make(
        plant=plant,
        sensing=sensing,
        nav=nav,
        bank=bank,
        control=control,
        detection=detection,
        landing=land_detector() if landing is None else landing,
        watch=watch_record() if watch is None else watch,
        record=record,
        state=state,
        held=np.full(2, np.nan),
    )
