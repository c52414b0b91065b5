"""quadest's vehicle and SE(3) controller against RotorPy: the same vehicle
(RotorPy's Hummingbird, quadest's ``hummingbird`` preset), the same controller and gains, the
same circle, flown by both simulators. RotorPy is optional (``pip install rotorpy``; the peers
and test extras install it).

What is compared: the rotor speeds in hover, the position-tracking RMS on the circle (after
the first lap), and the wall time per simulated step. What differs by construction: RotorPy
integrates each step with scipy's RK45 and holds the controller's command over it, quadest
with one RK4 step in compiled code; RotorPy adds translational lift (``k_h``, a few mN here),
which quadest's model does not have.
"""

from __future__ import annotations

import importlib.util
import time

import numpy as np

from quadest.control import SE3Params, circle_reference, hover_reference
from quadest.extras import need
from quadest.flight.truth import fly_se3
from quadest.models.multirotor import vehicle_preset

RADIUS_M = 1.0
FREQ_HZ = 0.2


def rotorpy_available() -> bool:
    return importlib.util.find_spec("rotorpy") is not None


def _rotorpy_flight(trajectory, x0, duration, rate_hz, start=None):
    need("rotorpy", "the cross-check against RotorPy")
    from rotorpy.controllers.quadrotor_control import SE3Control
    from rotorpy.environments import Environment
    from rotorpy.vehicles.hummingbird_params import quad_params
    from rotorpy.vehicles.multirotor import Multirotor

    state = {
        "x": np.asarray(x0 if start is None else start, float),
        "v": np.zeros(3),
        "q": np.array([0.0, 0.0, 0.0, 1.0]),
        "w": np.zeros(3),
        "wind": np.zeros(3),
        "rotor_speeds": np.full(4, vehicle_preset("hummingbird").hover_speed()),
    }
    if trajectory != "hover":
        state["v"] = np.array([0.0, RADIUS_M * 2 * np.pi * FREQ_HZ, 0.0])
    vehicle = Multirotor(quad_params, initial_state=state)
    controller = SE3Control(quad_params)
    if trajectory == "hover":
        from rotorpy.trajectories.hover_traj import HoverTraj

        traj = HoverTraj(x0=np.asarray(x0, float))
    else:
        from rotorpy.trajectories.circular_traj import ThreeDCircularTraj

        traj = ThreeDCircularTraj(
            center=np.zeros(3), radius=np.array([RADIUS_M, RADIUS_M, 0.0]), freq=np.full(3, FREQ_HZ)
        )
    env = Environment(vehicle=vehicle, controller=controller, trajectory=traj, sim_rate=rate_hz)
    t0 = time.perf_counter()
    res = env.run(t_final=duration, use_mocap=False, terminate=False, plot=False, animate_bool=False, verbose=False)
    wall = time.perf_counter() - t0
    return res["time"], res["state"]["x"], res["flat"]["x"], res["state"]["rotor_speeds"], wall


HOVER_START_M = (0.5, 0.0, 0.0)  # the hover starts this far from its setpoint (north / x)


def _quadest_flight(trajectory, duration, rate_hz):
    v = vehicle_preset("hummingbird")
    steps = int(round(duration * rate_hz))
    t = np.arange(1, steps + 1) / rate_hz
    x0 = v.hover_state()
    if trajectory == "hover":
        ref = hover_reference(steps)
        x0[0:3] = HOVER_START_M
    else:
        ref = circle_reference(t, RADIUS_M, FREQ_HZ)
        x0[0], x0[4] = RADIUS_M, RADIUS_M * 2 * np.pi * FREQ_HZ
    fly_se3(x0, (r[:10] for r in ref), vehicle=v, gains=SE3Params(), rate_hz=rate_hz)  # compile / warm up
    t0 = time.perf_counter()
    states, _ = fly_se3(x0, ref, vehicle=v, gains=SE3Params(), rate_hz=rate_hz)
    wall = time.perf_counter() - t0
    return t, states[:, 0:3], ref[0], states[:, 13:], wall


def _rms_after(t, pos, ref, t_from):
    keep = t >= t_from
    return float(np.sqrt(np.mean(np.sum((pos[keep] - ref[keep]) ** 2, axis=1))))


def crosscheck(duration: float = 10.0, rate_hz: float = 1000.0, hover_s: float = 4.0) -> dict:
    """Fly the Hummingbird in hover (``hover_s``, from 0.5 m off its setpoint) and on the circle (``duration``) in both
    simulators at ``rate_hz``; return hover rotor speeds, tracking RMS after the first lap and
    wall times."""
    if not rotorpy_available():
        raise RuntimeError("RotorPy is not installed: pip install rotorpy (or quadest's peers extra)")
    out = {"rate_hz": float(rate_hz), "duration_s": float(duration), "radius_m": RADIUS_M, "freq_hz": FREQ_HZ}
    lap = 1.0 / FREQ_HZ
    _, _, _, w_q, _ = _quadest_flight("hover", hover_s, rate_hz)
    _, _, _, w_r, _ = _rotorpy_flight("hover", np.zeros(3), hover_s, rate_hz, start=HOVER_START_M)
    out["hover_rotor_speed"] = {
        "quadest": float(np.mean(w_q[-1])),
        "rotorpy": float(np.mean(w_r[-1])),
        "model": vehicle_preset("hummingbird").hover_speed(),
    }
    tq, pq, rq, _, wall_q = _quadest_flight("circle", duration, rate_hz)
    tr, pr, rr, _, wall_r = _rotorpy_flight("circle", np.array([RADIUS_M, 0.0, 0.0]), duration, rate_hz)
    t_from = min(lap, 0.5 * duration)
    out["tracking_rms_m"] = {
        "quadest": _rms_after(tq, pq, rq, t_from),
        "rotorpy": _rms_after(tr, pr, rr, t_from),
        "from_s": t_from,
    }
    steps = duration * rate_hz
    out["wall_s"] = {"quadest": wall_q, "rotorpy": wall_r}
    out["ms_per_step"] = {"quadest": 1e3 * wall_q / steps, "rotorpy": 1e3 * wall_r / steps}
    out["speedup"] = wall_r / wall_q
    return out
