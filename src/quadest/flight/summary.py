"""What a flight's summary says (:func:`quadest.flight.fly`): survived or crashed, why and
when, the position error after settling, the attitude error in the loop, the settled spin and
tilt after a complete rotor loss, a clipped gyroscope's rate, what the detector found; the
table over many flights, and a flight's per-sample table (``quadest fly``'s Parquet file)."""

from __future__ import annotations

import numpy as np

from quadest.control import FtcParams
from quadest.control.ftc import relaxed_hover
from quadest.detect import RatePredictorParams
from quadest.filters import make_filter
from quadest.flight.common import Flight, angle_errors, mean_present, rms
from quadest.flight.detection import found_damaged
from quadest.flight.loop import OK, STATUS
from quadest.flight.spec import FlightSpec, Resolved
from quadest.rotation import quat_rotate
from quadest.sim.faults import Failure


def add_detection(flight: Flight, det, mode: str, failure: Failure | None, flown: int) -> None:
    """The detector's estimates and statistics per sample, and its summary; a false alarm makes
    the run a failed one."""
    flight.effectiveness = det.eta[:flown].copy()
    flight.detector_statistics = det.statistics[:flown].copy()
    flight.summary["detection"] = detection_summary(det, mode, failure, flight.recording.t)
    if flight.summary["detection"]["false_alarm"]:
        flight.summary["status"] = "false alarm"


def detection_summary(det, mode: str, failure: Failure | None, t: np.ndarray) -> dict:
    """What the detector in the loop found: the rotor found lost and when (s; ``delay_s`` after
    the failure), whether it is the rotor that failed, whether it was a false alarm (a rotor found
    lost before any failed: it counts as a failed run, the controller gives an intact rotor up),
    and the rotor found damaged."""
    k, rotor = (int(v) for v in det.found)
    found_s = float(t[k]) if k >= 0 else None
    fail_s = failure.time_s if failure is not None else None
    out = {
        "mode": mode,
        "lost_rotor": rotor if k >= 0 else None,
        "lost_s": found_s,
        "delay_s": None if found_s is None or fail_s is None or found_s < fail_s else found_s - fail_s,
        "isolated": None if k < 0 or failure is None else rotor == failure.rotor,
        "false_alarm": k >= 0 and (fail_s is None or found_s < fail_s),
    }
    damaged = found_damaged(det)
    out["damaged_rotor"], out["damaged_s"], out["damaged_effectiveness"] = (
        (None, None, None) if damaged is None else (damaged[0], float(t[0]) + damaged[1], damaged[2])
    )
    return out


def summarize(flight: Flight, spec: FlightSpec, r: Resolved, status: int, estimator: str, ref) -> dict:
    """The summary of one run of ``spec`` (module doc; ``r`` the spec resolved, ``status`` the
    loop's, ``estimator`` the name of the one in the loop, ``ref`` the reference position and
    heading flown); with a gyroscope that clipped, :func:`clipping_summary`'s too."""
    scenario, seed, ftc = spec.scenario, spec.seed, spec.ftc or FtcParams()
    duration, failure, controller, params, vehicle = r.duration, r.failure, r.controller, r.params, r.vehicle
    rec, x = flight.recording, flight.states
    t = rec.t
    p_d, _ = ref
    err = np.linalg.norm(x[:, 0:3] - p_d[: len(t)], axis=1)
    start = failure.time_s if failure is not None else 0.0
    s = {
        "scenario": scenario,
        "controller": controller,
        "estimator": estimator,
        "seed": int(seed),
        "status": "survived" if status == OK else "crashed" if status in (1, 2) else "stopped",
        "reason": STATUS[status],
        "duration_s": float(duration),
        "flown_s": float(t[-1] + (t[1] - t[0] if len(t) > 1 else 0)),
        "end_time_s": None if status == OK else float(t[-1]),
    }
    # settled: the position error stays below settle_m from then to the end
    after = t >= start
    above = np.flatnonzero(after & (err >= params.settle_m))
    if status != OK:
        settle = None
    elif len(above) == 0:
        settle = float(start)
    elif above[-1] + 1 < len(t):
        settle = float(t[above[-1] + 1])
    else:
        settle = None
    s["time_to_settle_s"] = None if settle is None else settle - start
    s["position_rms_settled_m"] = rms(err[t >= settle]) if settle is not None else None
    total, tilt = angle_errors(x[:, 6:10], flight.q_est)
    ok = np.isfinite(total)  # a recovery in flight reads no attitude until its bank hands over
    s["attitude_error_rms_deg"] = rms(total[ok])
    s["tilt_error_rms_deg"] = rms(tilt[ok])
    s["tilt_error_max_deg"] = float(tilt[ok].max())
    if failure is not None:
        s["drop_m"] = float(x[t >= start, 2].max()) if (t >= start).any() else None  # below the hover point
        after = (t >= start) & ok
        s["attitude_error_after_failure_rms_deg"] = rms(total[after])
        s["tilt_error_after_failure_rms_deg"] = rms(tilt[after])
    if failure is not None and failure.complete and controller == "ftc":
        late = t >= max(start + 0.5 * (duration - start), start + 1.0)
        if status == OK and late.any():
            # spin: the body rate about the vertical (navigation z); tilt: body −z from the vertical
            w_n = quat_rotate(x[late, 6:10], x[late, 10:13])
            down_b = quat_rotate(x[late, 6:10], np.tile([0.0, 0.0, 1.0], (late.sum(), 1)))
            s["spin_rate_rad_s"] = float(np.mean(w_n[:, 2]))
            s["tilt_deg"] = float(np.degrees(np.mean(np.arccos(np.clip(down_b[:, 2], -1.0, 1.0)))))
        hover = relaxed_hover(ftc.model(vehicle), failure.rotor, ftc.rho)
        s["relaxed_hover_model"] = {
            "spin_rate_rad_s": float(-hover.spin),
            "tilt_deg": hover.tilt_deg,
            "thrusts_n": [float(v) for v in hover.thrusts],
        }
    s.update(clipping_summary(flight, float(r.cfg.gyro.range), failure))
    return s


def clipping_summary(flight: Flight, gyro_range: float, failure: Failure | None) -> dict:
    """With a gyroscope that clipped (from the failure on, if any): the share of samples with an
    axis clipped and, per axis, the RMS error of the rate the controller read against the true
    rate on that axis's clipped samples (None for an axis that never clipped). Empty otherwise."""
    if not np.isfinite(gyro_range) or flight.rate_est is None:
        return {}
    t = flight.recording.t
    after = t >= (failure.time_s if failure is not None else 0.0)
    margin = RatePredictorParams().clip_margin
    clipped = (np.abs(flight.recording.gyr) >= gyro_range * (1.0 - margin)) & after[:, None]
    if not clipped.any():
        return {}
    err = flight.rate_est - flight.states[:, 10:13]
    return {
        "gyro_clipped_share": float(clipped.any(axis=1).sum() / max(after.sum(), 1)),
        "clip_rate_error_rms_rad_s": [rms(err[clipped[:, j], j]) if clipped[:, j].any() else None for j in range(3)],
    }


def offline_errors(flight: Flight, estimator: str) -> dict:
    """``estimator`` run afterwards over a flight's recording (not in its loop): its tilt and
    attitude error, as the controller's estimator's are summarised."""
    rec = flight.recording
    q = make_filter(estimator, declination=rec.declination).run(rec).q
    total, tilt = angle_errors(rec.true_q, q)
    out = {"attitude_error_rms_deg": rms(total), "tilt_error_rms_deg": rms(tilt)}
    if rec.meta.get("failure"):
        after = rec.t >= rec.meta["failure"]["time_s"]
        out.update(
            attitude_error_after_failure_rms_deg=rms(total[after]), tilt_error_after_failure_rms_deg=rms(tilt[after])
        )
    return out


def campaign_table(summaries: list[dict]) -> list[dict]:
    """Per estimator over the runs: how many survived and settled, the tilt error in the loop and
    offline (over the truth-controlled flight), the settled spin and tilt (rotor loss)."""
    rows = []
    for name in dict.fromkeys(s["estimator"] for s in summaries):
        runs = [s for s in summaries if s["estimator"] == name]
        ok = [s for s in runs if s["status"] == "survived"]
        mean = mean_present

        rows.append(
            {
                "estimator": name,
                "runs": len(runs),
                "survived": len(ok),
                "settled": sum(s["time_to_settle_s"] is not None for s in runs),
                "tilt_error_in_loop_deg": mean([s["tilt_error_rms_deg"] for s in runs]),
                "tilt_error_offline_deg": mean(
                    [s.get("offline_on_truth_flight", {}).get("tilt_error_rms_deg") for s in runs]
                )
                if name != "truth"
                else 0.0,
                "position_rms_settled_m": mean([s["position_rms_settled_m"] for s in runs]),
                "spin_rate_rad_s": mean([s.get("spin_rate_rad_s") for s in ok]),
                "tilt_deg": mean([s.get("tilt_deg") for s in ok]),
            }
        )
        if any(s["scenario"] == "throw" for s in runs):  # throws
            rows[-1].update(
                {
                    "recovered": sum(bool(s.get("recovered")) for s in runs),
                    "handover_s": mean([s.get("handover_s") for s in runs]),
                    "gravity_error_at_handover_deg": mean([s.get("gravity_error_at_handover_deg") for s in runs]),
                    "velocity_error_at_handover_m_s": mean([s.get("velocity_error_at_handover_m_s") for s in runs]),
                    "lowest_point_m": mean([s.get("lowest_point_m") for s in runs]),
                }
            )
    return rows


def flight_table(flight) -> dict:
    """Per IMU sample: the true state, the rotor speeds and commands, what the controller read
    (attitude, position, velocity, body rate), the barometer (NaN between its samples) and a throw's recovery state."""
    x = flight.states
    cols = {"t": flight.recording.t}
    names = ["pn", "pe", "pd", "vn", "ve", "vd", "qw", "qx", "qy", "qz", "wx", "wy", "wz"]
    for i, n in enumerate(names):
        cols[f"true_{n}"] = x[:, i]
    for i in range(x.shape[1] - 13):
        cols[f"rotor{i}_speed"] = x[:, 13 + i]
        cols[f"rotor{i}_cmd"] = flight.commands[:, i]
    for i, n in enumerate(("qw", "qx", "qy", "qz")):
        cols[f"est_{n}"] = flight.q_est[:, i]
    for i, n in enumerate(("pn", "pe", "pd", "vn", "ve", "vd")):
        cols[f"est_{n}"] = flight.pv_est[:, i]
    if flight.rate_est is not None:  # the body rate the controller read (on a clipped axis the predicted one)
        for i, n in enumerate(("wx", "wy", "wz")):
            cols[f"est_{n}"] = flight.rate_est[:, i]
    if flight.baro is not None:
        cols["baro_alt"] = flight.baro
    if flight.modes is not None:
        cols["recovery_mode"] = flight.modes
    return cols
