"""``simulate``: a scenario, a preset and a seed in, a :class:`~quadest.data.Recording` out."""

from __future__ import annotations

import math
from collections import namedtuple
from pathlib import Path

import numpy as np

from quadest.data.recording import Recording
from quadest.models.aero import AeroModel
from quadest.models.multirotor import MultirotorParams
from quadest.progress import bar as progress_bar
from quadest.rotation import quat_continuous
from quadest.sim import sensors
from quadest.sim.params import SimConfig, load_toml_overrides, preset_config
from quadest.sim.truth import PRESCRIBED_SCENARIOS, Truth, default_duration, make_motion

BYTES_PER_SAMPLE = 1500
"""What a simulation holds per IMU sample, with a margin: the peak memory of a hover grew by
870 (``quadest simulate``) to 1060 bytes (``quadest.sim.simulate``) a sample from 20 s to 200 s
at 500 Hz (``tests/unit/test_memory_budget.py``)."""
MEMORY_BUDGET_BYTES = 4 * 2**30
"""The most one simulation may hold (4 GiB), refused before it starts past that."""
MAX_SAMPLES = MEMORY_BUDGET_BYTES / BYTES_PER_SAMPLE
"""The most IMU samples one simulation makes (2.9·10⁶: 1.6 h at 500 Hz)."""
CHUNK_S = 10.0  # simulated seconds per chunk (memory and progress granularity)


def build_config(
    preset: str = "bebop2", overrides: dict | None = None, toml: str | Path | None = None, ideal: bool = False
) -> SimConfig:
    """A preset; ``ideal`` removes every sensor error (:meth:`SimConfig.idealized`); then a TOML
    file's overrides and ``overrides`` (``{"gyro.noise_std": 0.02}``), so that chosen errors can
    be put back on ideal sensors."""
    cfg = preset_config(preset)
    if ideal:
        cfg = cfg.idealized()
    if toml is not None:
        cfg = cfg.with_overrides(load_toml_overrides(toml), source=str(toml))
    if overrides:
        cfg = cfg.with_overrides(overrides)
    return cfg


def aero_model(cfg: SimConfig) -> AeroModel:
    """The aerodynamic model (recovery paper eq 9) a configuration simulates: ``cfg.aero`` and
    the vehicle mass."""
    return AeroModel(cfg.aero.A, cfg.aero.B, cfg.aero.C, cfg.vehicle.mass_kg)


def aero_model_of(rec: Recording) -> AeroModel:
    """The aerodynamic model a simulated recording was made with (from its metadata)."""
    cfg = rec.meta.get("config") if isinstance(rec.meta, dict) else None
    if not cfg or "aero" not in cfg:
        raise ValueError(
            "this recording does not carry a simulation's aerodynamic model: give one "
            "(quadest fit-aero, or an aero calibration)"
        )
    return aero_model(SimConfig().with_overrides({"aero": cfg["aero"], "vehicle.mass_kg": cfg["vehicle"]["mass_kg"]}))


def simulate(
    scenario: str,
    preset: str = "bebop2",
    seed: int = 0,
    duration: float | None = None,
    overrides: dict | None = None,
    *,
    config: SimConfig | None = None,
    ideal: bool = False,
    toml: str | Path | None = None,
    progress: bool = False,
    return_truth: bool = False,
) -> Recording | tuple[Recording, Truth]:
    """Simulate one flight and its sensors. Deterministic for a given seed and configuration.

    Parameters
    ----------
    scenario : one of ``hover``, ``nominal``, ``damaged-rotor``, ``throw``.
    preset : ``bebop2``, ``lowcost-20hz`` or ``fma``; with ``config`` given, only the name
        recorded in the metadata (the configuration itself is stored there in full).
    seed : seed of every random draw (motion, sensor errors, timing).
    duration : seconds; the scenario's default when None.
    overrides : ``{"section.field": value}`` on top of the preset (docs/simulator.md).
    ideal : remove all sensor errors (noise, bias, scale, misalignment, saturation, jitter...).
    progress : show a progress bar for runs that take more than a second.
    return_truth : also return the :class:`~quadest.sim.truth.Truth` (with angular acceleration and
        the sensors' true biases over time, random walk included).
    """
    if scenario not in PRESCRIBED_SCENARIOS:
        raise ValueError(f"unknown scenario {scenario!r}; scenarios: {', '.join(PRESCRIBED_SCENARIOS)}")
    cfg = config if config is not None else build_config(preset, overrides, toml, ideal)
    if config is not None and ideal:
        cfg = cfg.idealized()
    cfg.validate()
    if duration is None:
        duration = default_duration(scenario, cfg)
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds, got {duration}")
    rate = cfg.imu.rate_hz
    if duration * rate > MAX_SAMPLES:
        raise ValueError(
            f"{duration:g} s at {rate:g} Hz is {duration * rate:.3g} samples, about "
            f"{duration * rate * BYTES_PER_SAMPLE / 2**30:.3g} GiB in memory, past one simulation's budget of "
            f"{MEMORY_BUDGET_BYTES / 2**30:g} GiB ({MAX_SAMPLES:.2g} samples); simulate shorter flights"
        )
    ss = np.random.SeedSequence(int(seed))
    rng_motion, rng_gyro, rng_acc, rng_mag, rng_time, rng_vib = (np.random.default_rng(s) for s in ss.spawn(6))

    # sampling instants: nominal grid, jitter, then dropped rows
    k = np.arange(int(np.floor(duration * rate + 1e-9)) + 1)
    t = k / rate
    if cfg.imu.jitter_std_s > 0:
        t = t + np.clip(rng_time.normal(0, cfg.imu.jitter_std_s, len(t)), -0.3 / rate, 0.3 / rate)
    keep = rng_time.random(len(t)) >= cfg.imu.drop_prob if cfg.imu.drop_prob > 0 else np.ones(len(t), bool)
    has_mag = sensors.mag_rows(k, rate, cfg.mag.rate_hz)

    motion = make_motion(scenario, cfg, rng_motion, duration)
    chunk = max(1, int(CHUNK_S * rate))
    parts = []
    with progress_bar(
        total=len(t), unit="sample", desc=f"simulate {scenario}", delay=1.0, disable=not progress, leave=False
    ) as bar:
        for i in range(0, len(t), chunk):
            parts.append(motion.evaluate(t[i : i + chunk]))
            bar.update(len(parts[-1].t))
    truth = Truth.concat(parts)
    truth.meta = motion.meta
    truth.q = quat_continuous(truth.q)

    meta = {
        "source": "quadest simulate",
        "scenario": scenario,
        "preset": preset,
        "seed": int(seed),
        "ideal_sensors": bool(ideal),
    }
    rec, gyr_bias, acc_bias = sample_sensors(truth, cfg, keep, has_mag, (rng_gyro, rng_acc, rng_mag, rng_vib), meta)
    if return_truth:
        sel = {
            n: getattr(truth, n)[keep]
            for n in ("t", "q", "gyr", "gyr_dot", "pos", "vel", "acc_n", "current", "rotor_load")
        }
        return rec, Truth(**sel, meta=truth.meta, gyr_bias=gyr_bias[keep], acc_bias=acc_bias[keep])
    return rec


Processes = namedtuple(
    "Processes",
    ["gyro_errors", "acc_errors", "gyr_bias", "gyr_noise", "acc_bias", "acc_noise", "vib_offsets", "mag_noise"],
)
"""Every sensor error that does not depend on the motion, drawn for one run (:func:`draw_processes`)."""


def draw_processes(cfg: SimConfig, t, has_mag, rngs, rotors: int = 0) -> Processes:
    """Draw a run's sensor errors at the IMU instants ``t`` (magnetometer noise on the rows
    ``has_mag``), always in the same order from the four generators ``(gyro, acc, mag,
    vibration)``: the sensors sampled from a whole trajectory (:func:`sample_sensors`) and
    sample by sample in a closed loop read the same draws (:func:`quadest.sim.sensors.sensor_model`).
    ``rotors``: a flown vehicle's rotor count (its vibration's phases per rotor,
    :func:`quadest.sim.sensors.rotor_vibration_offsets`); 0 for a prescribed motion (one tone)."""
    rng_gyro, rng_acc, rng_mag, rng_vib = rngs
    g_err = sensors.draw_errors(cfg.gyro, rng_gyro)
    a_err = sensors.draw_errors(cfg.acc, rng_acc)
    gyr_bias, gyr_noise = sensors.inertial_processes(t, cfg.gyro, g_err, rng_gyro)
    vib_offsets = (
        sensors.rotor_vibration_offsets(rotors, rng_vib)
        if rotors
        else sensors.vibration_offsets(cfg.acc.vibration_amp, rng_vib)
    )
    acc_bias, acc_noise = sensors.inertial_processes(t, cfg.acc, a_err, rng_acc)
    mag_noise = sensors.mag_noise(int(np.count_nonzero(has_mag)), cfg.mag, rng_mag)
    return Processes(g_err, a_err, gyr_bias, gyr_noise, acc_bias, acc_noise, vib_offsets, mag_noise)


def sample_sensors(
    truth: Truth,
    cfg: SimConfig,
    keep,
    has_mag,
    rngs,
    meta: dict,
    processes: Processes | None = None,
    vehicle: MultirotorParams | None = None,
):
    """The sensors of ``cfg`` sampled from a true motion (prescribed or flown) at its instants:
    IMU with lever arm, errors, vibration and saturation, magnetometer on the rows ``has_mag``;
    rows ``keep`` are recorded (the others were dropped). Returns the recording and the true
    gyro and accelerometer biases over time (all rows). ``processes``: draws made beforehand
    for at least these rows (a closed loop that ended early), used instead of ``rngs``.
    ``vehicle``: a flown vehicle, whose vibration comes from each rotor's speed and imbalance
    (``truth.rotor_speeds``, ``truth.rotor_imbalance``; :func:`quadest.sim.sensors.rotor_vibration_step`)
    instead of the prescribed motion's one tone."""
    t = truth.t
    rate = cfg.imu.rate_hz
    flown = vehicle is not None
    if flown and truth.rotor_speeds is None:
        raise ValueError("sample_sensors: a flown vehicle's truth must carry its rotor speeds")
    if processes is None:
        pr = draw_processes(cfg, t, has_mag, rngs, rotors=vehicle.rotors if flown else 0)
    else:
        n, m = len(t), int(np.count_nonzero(has_mag))
        pr = processes._replace(
            gyr_bias=processes.gyr_bias[:n],
            gyr_noise=processes.gyr_noise[:n],
            acc_bias=processes.acc_bias[:n],
            acc_noise=processes.acc_noise[:n],
            mag_noise=processes.mag_noise[:m],
        )
    g_err, a_err = pr.gyro_errors, pr.acc_errors
    sm = sensors.sensor_model(cfg, pr, has_mag, vehicle)
    if flown:
        imbalance = np.zeros_like(truth.rotor_speeds) if truth.rotor_imbalance is None else truth.rotor_imbalance
        vib, gyr_vib = sensors.rotor_vibration(sm.rv, t, truth.rotor_speeds, imbalance)
    else:
        vib = sensors.vibration(
            t, truth.rotor_load, cfg.vehicle.rotor_hz_hover, cfg.acc.vibration_amp, offsets=pr.vib_offsets
        )
        gyr_vib = np.zeros_like(vib)
    gyr, acc, mag, f_imu = sensors.sample_all(
        sm, truth.q, truth.acc_n, truth.gyr, truth.gyr_dot, vib, gyr_vib, truth.pos, truth.current
    )
    gyr_bias, acc_bias = pr.gyr_bias, pr.acc_bias
    sat = np.abs(truth.gyr @ g_err["matrix"].T + gyr_vib) > cfg.gyro.range
    meta = {
        **{k: v for k, v in meta.items() if k != "ideal_sensors"},
        "imu_rate_hz": rate,
        "mag_rate_hz": cfg.mag.rate_hz,
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
        **({"ideal_sensors": meta["ideal_sensors"]} if "ideal_sensors" in meta else {}),
        "earth_field_ned_ut": sensors.earth_field(cfg.environment).tolist(),
        "gyro_saturated_share": float(sat.any(axis=1)[keep].mean()),
        "sensor_errors": {
            "gyr": {k_: v.tolist() for k_, v in g_err.items()},
            "acc": {k_: v.tolist() for k_, v in a_err.items()},
        },
        "scenario_info": truth.meta,
        "config": cfg.to_dict(),
    }
    rec = Recording(
        t=t[keep],
        gyr=gyr[keep],
        acc=acc[keep],
        mag=mag[keep],
        true_q=truth.q[keep],
        true_gyr=truth.gyr[keep],
        true_pos=truth.pos[keep],
        true_vel=truth.vel[keep],
        true_acc=f_imu[keep],
        meta=meta,
        check_units=False,
    )
    return rec, gyr_bias, acc_bias
