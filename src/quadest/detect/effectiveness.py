"""Rotor-failure detection and isolation: a Kalman filter on each rotor's effectiveness, and a
sequential test on what it finds (docs/detection.md).

The filter's state is the body rate ``ω`` and each rotor's effectiveness ``η_i`` (1 intact, 0
lost). Between samples the rate follows the detector's model of the vehicle (docs/detection.md
has the inflow and rotor-drag terms)::

    J ω̇ = Σ_i η_i k_f Ω_i² g_i − ω × J ω − D ω − C_r |ω| ω,   g_i = (−r_iy, r_ix, −s_i k_m/k_f)

with ``Ω_i`` the rotor speeds (measured, or from the commands through the detector's motor
model), and the effectiveness walks randomly. The gyroscope measures ``ω``; the
accelerometer's z measures ``−Σ η_i k_f Ω_i² / m``. Both are linear in the state given the
rotor speeds and the measured rate, so the filter is a linear Kalman filter, updated one scalar
at a time. The accelerometer is read at the centre of mass: what its lever arm adds is taken out
first (``lever_arm``, the IMU's position given).

The yaw moment of the rotors' drag as the vehicle moves through the air is read from the
accelerometer's x and y (``air_drag``). The rotors' moment about each axis is scaled by what
the flight shows of it against the model (``moment_scale_s``: inertia, mass and thrust
coefficient are never known exactly). Each rotor's deficit ``d_i`` is the mean effectiveness
of the others minus its own, relative to theirs (a common error of ``k_f`` or of the mass
moves every ``η`` alike and cancels). Two CUSUM tests
(Page 1954) accumulate it: ``S_i ← max(0, S_i + Δt (d_i − ν))``; the rotor whose sum first
passes its threshold ``h`` is the one that failed. The test with the larger drift answers
"lost" (the fault-tolerant controller takes over), the one with the smaller drift "damaged".
Beside them a fast test (``glr``) reads a loss's first samples directly: a generalised
likelihood ratio of each rotor lost at the start of each of the last few samples' windows.
With the rotor speeds measured and the commands given, the speed test (``speed_test``,
:mod:`quadest.detect.speed`) names a rotor lost whose speed falls below what its commands give
any working motor within the model's errors: a stopped motor or a desync, whose propeller still
pushes at the speed it turns, so that its effectiveness stays 1.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import NO_ALLOCATION, njit
from quadest.detect.filter import correct, gyro_noise_estimate, note_commands, predict, start_filter
from quadest.detect.layout import DIAG, DIAGNOSTICS, MODEL, STAT, STATE, STATISTICS
from quadest.detect.model import air_lowpass, model_coefficients, motor_step
from quadest.detect.params import PARAM, DetectorParams
from quadest.detect.sequential import cusum_test, glr_store, glr_test
from quadest.detect.speed import speed_test
from quadest.records import check, pack

if TYPE_CHECKING:
    from quadest.models.multirotor import MultirotorParams


@njit(cache=True, **NO_ALLOCATION)
def detect_step(x, p, c, gyr, acc, rotors, dt, diag):
    """One sample: gyroscope (rad/s), accelerometer (m/s²), each rotor's measured speed or the
    command it was given over the interval that ends here (rad/s, ``p.rotor_speeds``), the
    interval (s). ``diag``: each rotor's effectiveness.
    Returns the rotor found lost (-1: none yet)."""
    if not (dt > 0.0 and np.isfinite(gyr[0]) and np.isfinite(gyr[1]) and np.isfinite(gyr[2])):
        return int(x[STATE.lost])
    n = int(c[MODEL.rotors])
    if x[STATE.init] == 0.0:
        start_filter(x, p, c, gyr, rotors)
        air_lowpass(x, c, acc, gyr[2], 1.0)  # from the first reading
        x[STATE.init] = 1.0
        for i in range(n):
            diag[i] = 1.0
        for j in range(STATISTICS):
            diag[STAT + j] = 0.0
        return -1
    measured = p[PARAM.rotor_speeds] != 0.0
    if not measured:
        note_commands(x, p, c, rotors)
    for i in range(n):  # the speeds over the interval: √(½(Ω²_begin + Ω²_end)), Ω² being what thrust needs
        begin = x[STATE.omega_end + i]
        end = rotors[i] if measured else motor_step(begin, rotors[i], c, dt)
        x[STATE.omega + i] = np.sqrt(0.5 * (begin * begin + end * end))
        x[STATE.omega_end + i] = end
    gyro_noise_estimate(x, p, gyr, dt)
    predict(x, p, c, gyr, dt)
    correct(x, p, c, gyr, acc)
    acc = x[STATE.acc_cg : STATE.acc_cg + 3]
    air_lowpass(x, c, acc, gyr[2], dt)
    x[STATE.time] += dt
    if measured:
        speed_test(x, p, c, rotors, dt)
    cusum_test(x, p, c, dt)
    if p[PARAM.glr] != 0.0:
        glr_store(x, p, c, gyr, acc, dt)
        glr_test(x, p, c, dt)
    for j in range(STATISTICS):
        diag[STAT + j] = 0.0
    for i in range(n):
        diag[DIAGNOSTICS.eta + i] = x[STATE.eta + i]
        if x[STATE.s_lost + i] > diag[DIAGNOSTICS.lost_sum]:
            diag[DIAGNOSTICS.lost_sum], diag[DIAGNOSTICS.lost_rotor] = x[STATE.s_lost + i], i
        if x[STATE.s_damaged + i] > diag[DIAGNOSTICS.damaged_sum]:
            diag[DIAGNOSTICS.damaged_sum], diag[DIAGNOSTICS.damaged_rotor] = x[STATE.s_damaged + i], i
        if x[STATE.s_speed + i] > diag[DIAGNOSTICS.speed_sum]:
            diag[DIAGNOSTICS.speed_sum], diag[DIAGNOSTICS.speed_rotor] = x[STATE.s_speed + i], i
    return int(x[STATE.lost])


@njit(cache=True, **NO_ALLOCATION)
def detect_run(x, p, c, dt, gyr, acc, rotors, diag_out, commands):
    """Batch: the same step over every sample; ``commands`` the speeds commanded over each
    interval (:func:`note_commands`), or no rows."""
    noted = commands.shape[0] == len(dt)
    for k in range(len(dt)):
        if noted:
            note_commands(x, p, c, commands[k])
        detect_step(x, p, c, gyr[k], acc[k], rotors[k], dt[k], diag_out[k])


@dataclass
class Detection:
    """What the detector found over a run: each rotor's effectiveness per sample, and the rotor
    found lost and the one found damaged (0-based; None when none), with when (s from the
    start) and the effectiveness left (relative to the other rotors)."""

    t: np.ndarray
    effectiveness: np.ndarray
    lost: int | None
    lost_t: float | None
    lost_effectiveness: float | None
    damaged: int | None
    damaged_t: float | None
    damaged_effectiveness: float | None
    statistics: np.ndarray | None = None
    """Per sample: the largest 'lost' sum and its rotor, the largest 'damaged' sum and its rotor,
    the largest speed test's sum and its rotor."""


class Detector:
    """Rotor-failure detection and isolation for one vehicle (module doc): ``vehicle`` is the
    detector's model (a :class:`~quadest.models.multirotor.MultirotorParams`), ``params`` a
    :class:`DetectorParams` (or keyword overrides), ``imu_position`` the accelerometer's place
    from the centre of mass (m, body FRD; an autopilot's ``INS_POS`` / ``EKF2_IMU_POS``).
    Streaming :meth:`update` and batch :meth:`run` call one compiled step."""

    def __init__(
        self,
        vehicle: MultirotorParams,
        params: DetectorParams | None = None,
        *,
        imu_position: ArrayLike = (0.0, 0.0, 0.0),
        **overrides,
    ):
        params = params if params is not None else DetectorParams()
        if overrides:
            params = replace(params, **overrides)
        check(params, "detector")
        self.params, self.vehicle = params, vehicle
        self._values = pack(params.values()[f] for f in PARAM._fields)
        self._model = model_coefficients(vehicle, imu_position)
        self.rotors = vehicle.rotors
        self.reset()

    def reset(self) -> None:
        """Back to the start: every rotor intact, nothing found."""
        self._state = np.zeros(STATE.end)
        self._state[STATE.cut_t] = -np.inf
        self._state[STATE.scale : STATE.scale + 3] = 1.0
        self._out = np.zeros(DIAG)

    def compiled(self) -> tuple:
        """The live arrays of the compiled step ``detect_step(x, p, c, ...)`` for a compiled loop."""
        return self._state, self._values, self._model, self._out

    def update(
        self, gyr: ArrayLike, acc: ArrayLike, rotors: ArrayLike, *, dt: float, commands: ArrayLike | None = None
    ) -> int | None:
        """One sample (rotor speeds or commands, rad/s, one per rotor; with measured speeds, the
        ``commands`` over the interval too, for the thrust cut's hold and the speed test): the rotor
        found lost, or None."""
        if commands is not None:
            note_commands(self._state, self._values, self._model, _vec(commands, self.rotors))
        lost = detect_step(
            self._state,
            self._values,
            self._model,
            _vec(gyr, 3),
            _vec(acc, 3),
            _vec(rotors, self.rotors),
            float(dt),
            self._out,
        )
        return None if lost < 0 else lost

    @property
    def effectiveness(self) -> np.ndarray:
        return self._state[STATE.eta : STATE.eta + self.rotors].copy()

    @property
    def moment_scale(self) -> np.ndarray:
        """The rotors' moment about x, y and z against the model's, learnt so far (1: the model's)."""
        return self._state[STATE.scale : STATE.scale + 3].copy()

    def result(self, t: ArrayLike | None = None, effectiveness: ArrayLike | None = None) -> Detection:
        """What was found so far (with the per-sample times and effectiveness given, if any)."""
        x = self._state

        def found(key):
            return None if x[key] < 0 else int(x[key])

        lost, damaged = found(STATE.lost), found(STATE.damaged)
        return Detection(
            np.asarray(t if t is not None else []),
            np.asarray(effectiveness if effectiveness is not None else np.empty((0, self.rotors))),
            lost,
            None if lost is None else float(x[STATE.lost_t]),
            None if lost is None else float(x[STATE.lost_eta]),
            damaged,
            None if damaged is None else float(x[STATE.damaged_t]),
            None if damaged is None else float(x[STATE.damaged_eta]),
        )

    def run(
        self, t: ArrayLike, gyr: ArrayLike, acc: ArrayLike, rotors: ArrayLike, commands: ArrayLike | None = None
    ) -> Detection:
        """Over whole arrays (rows of samples; ``commands`` as in :meth:`update`), from the current
        state. Times in the result are seconds from the first sample the detector saw."""
        t = np.asarray(t, float)
        n = len(t)
        gyr, acc = (np.ascontiguousarray(a, dtype=float) for a in (gyr, acc))
        rotors = np.ascontiguousarray(rotors, dtype=float)
        cmds = np.ascontiguousarray(np.zeros((0, self.rotors)) if commands is None else commands, dtype=float)
        if gyr.shape != (n, 3) or acc.shape != (n, 3) or rotors.shape != (n, self.rotors):
            raise ValueError(f"detector: gyr and acc must be ({n}, 3) and rotors ({n}, {self.rotors})")
        if commands is not None and cmds.shape != (n, self.rotors):
            raise ValueError(f"detector: commands must be ({n}, {self.rotors})")
        dt = np.diff(t, prepend=t[0] - (np.median(np.diff(t)) if n > 1 else 0.0))
        diag = np.zeros((n, DIAG))
        detect_run(self._state, self._values, self._model, dt, gyr, acc, rotors, diag, cmds)
        res = self.result(t, diag[:, : self.rotors])
        res.statistics = diag[:, STAT:DIAG]
        return res


def _vec(v, n):
    a = np.ascontiguousarray(v, dtype=np.float64)
    if a.shape != (n,):
        raise ValueError(f"detector: expected {n} values, got shape {a.shape}")
    return a
