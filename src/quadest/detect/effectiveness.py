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

import warnings
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import NO_ALLOCATION, njit
from quadest.detect import inputs
from quadest.detect.filter import correct, gyro_noise_estimate, note_commands, predict, start_filter
from quadest.detect.layout import DIAG, DIAGNOSTICS, MODEL, SCALE_RANGE, STAT, STATE, STATISTICS
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
def detect_batch(x, p, c, dt, gyr, acc, rotors, diag_out, commands):
    """Batch: the same step over every sample; ``commands`` the speeds commanded over each
    interval (:func:`note_commands`), or no rows. Compiled: it checks nothing (:func:`detect_run`
    does)."""
    noted = commands.shape[0] == len(dt)
    for k in range(len(dt)):
        if noted:
            note_commands(x, p, c, commands[k])
        detect_step(x, p, c, gyr[k], acc[k], rotors[k], dt[k], diag_out[k])


def detect_run(
    x: np.ndarray,
    p: np.ndarray,
    c: np.ndarray,
    dt: ArrayLike,
    gyr: ArrayLike,
    acc: ArrayLike,
    rotors: ArrayLike,
    diag_out: np.ndarray,
    commands: ArrayLike,
) -> None:
    """:func:`detect_batch` on the arrays of :meth:`Detector.compiled` after checking them
    (:mod:`quadest.detect.inputs`): ``dt`` (N,) s, ``gyr`` and ``acc`` (N, 3), ``rotors`` (N, n)
    rad/s with n the model's rotors, ``diag_out`` (N, DIAG) written, ``commands`` (N, n) rad/s
    or no rows. A wrong shape, rotor count or unit is one ValueError naming the argument."""
    _checked_batch("detect_run", x, p, c, dt, gyr, acc, rotors, diag_out, commands)


def _checked_batch(who, x, p, c, dt, gyr, acc, rotors, diag_out, commands) -> None:
    """:func:`detect_run`'s checks and run, its errors naming ``who``."""
    n_rot = inputs.model_rotors(c, who)
    inputs.state_arrays(who, x=(x, STATE.end), p=(p, len(PARAM._fields)))
    dt = inputs.rows(who, "dt", dt, np.shape(dt)[0] if np.ndim(dt) else -1, None)
    n = len(dt)
    gyr, acc = (inputs.rows(who, k, a, n, 3) for k, a in (("gyr", gyr), ("acc", acc)))
    rotors = inputs.rows(who, "rotors", rotors, n, n_rot, inputs.rotor_hint(np.shape(rotors)[-1], n_rot))
    inputs.state_arrays(who, diag_out=(diag_out, DIAG))
    if diag_out.shape != (n, DIAG):
        raise ValueError(f"{who}: diag_out has shape {diag_out.shape}, expected ({n}, {DIAG})")
    cmd_rows = np.shape(commands)[0] if np.ndim(commands) == 2 else -1
    commands = inputs.rows(who, "commands", commands, 0 if cmd_rows == 0 else n, n_rot, " (or no rows)")
    inputs.rotor_speeds(who, "rotors", rotors, c)
    inputs.rotor_speeds(who, "commands", commands, c)
    detect_batch(x, p, c, dt, gyr, acc, rotors, diag_out, commands)


def detect_sample(
    x: np.ndarray,
    p: np.ndarray,
    c: np.ndarray,
    gyr: ArrayLike,
    acc: ArrayLike,
    rotors: ArrayLike,
    dt: float,
    diag: np.ndarray,
) -> int:
    """:func:`detect_step` (one sample, compiled, checking nothing: what compiled loops call)
    after checking its arguments as :func:`detect_run` does; the rotor found lost (-1: none)."""
    who = "detect_step"
    n_rot = inputs.model_rotors(c, who)
    inputs.state_arrays(who, x=(x, STATE.end), p=(p, len(PARAM._fields)), diag=(diag, DIAG))
    gyr, acc = (inputs.rows(who, k, a, 3, None) for k, a in (("gyr", gyr), ("acc", acc)))
    rotors = inputs.rows(who, "rotors", rotors, n_rot, None, inputs.rotor_hint(np.size(rotors), n_rot))
    inputs.rotor_speeds(who, "rotors", rotors, c, run=False)
    return detect_step(x, p, c, gyr, acc, rotors, float(dt), diag)


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
    moment_scale: np.ndarray | None = None
    """The rotors' moment about x, y and z learnt against the model's at the end (1: the model's)."""
    moment_scale_clamped: list[str] = field(default_factory=list)
    """The axes ('x', 'y', 'z') whose learnt moment reached its clamp (1 ± ``SCALE_RANGE``) at some
    sample: the model is off by more than the detector corrects there (its results are then the
    clamped model's; a warning said so)."""


class Detector:
    """Rotor-failure detection and isolation for one vehicle (module doc): ``vehicle`` is the
    detector's model (a :class:`~quadest.models.multirotor.MultirotorParams`), ``params`` a
    :class:`DetectorParams` (or keyword overrides), ``imu_position`` the accelerometer's place
    from the centre of mass (m, body FRD; an autopilot's ``INS_POS`` / ``EKF2_IMU_POS``),
    ``drag_moment`` the drag's moments (:func:`~quadest.detect.model.model_coefficients`; a
    vehicle file's ``identified.drag_moment``).
    Streaming :meth:`update` and batch :meth:`run` call one compiled step."""

    def __init__(
        self,
        vehicle: MultirotorParams,
        params: DetectorParams | None = None,
        *,
        imu_position: ArrayLike = (0.0, 0.0, 0.0),
        drag_moment: ArrayLike = ((0.0, 0.0), (0.0, 0.0)),
        **overrides,
    ):
        params = params if params is not None else DetectorParams()
        if overrides:
            params = replace(params, **overrides)
        check(params, "detector")
        self.params, self.vehicle = params, vehicle
        self._values = pack(params.values()[f] for f in PARAM._fields)
        self._model = model_coefficients(vehicle, imu_position, drag_moment)
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
            cmds = _vec(commands, self.rotors, "commands")
            inputs.rotor_speeds("detector", "commands", cmds, self._model, run=False)
            note_commands(self._state, self._values, self._model, cmds)
        speeds = _vec(rotors, self.rotors, "rotors")
        inputs.rotor_speeds("detector", "rotors", speeds, self._model, run=False)
        g = _vec(gyr, 3, "gyr")  # NaN: a bad sample, skipped by the step
        lost = detect_step(self._state, self._values, self._model, g, _vec(acc, 3, "acc"), speeds, float(dt), self._out)
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
        clamped = [a for j, a in enumerate("xyz") if x[STATE.scale_clamped + j] != 0.0]
        return Detection(
            np.asarray(t if t is not None else []),
            np.asarray(effectiveness if effectiveness is not None else np.empty((0, self.rotors))),
            lost,
            None if lost is None else float(x[STATE.lost_t]),
            None if lost is None else float(x[STATE.lost_eta]),
            damaged,
            None if damaged is None else float(x[STATE.damaged_t]),
            None if damaged is None else float(x[STATE.damaged_eta]),
            moment_scale=self.moment_scale,
            moment_scale_clamped=clamped,
        )

    def run(
        self, t: ArrayLike, gyr: ArrayLike, acc: ArrayLike, rotors: ArrayLike, commands: ArrayLike | None = None
    ) -> Detection:
        """Over whole arrays (rows of samples; ``commands`` as in :meth:`update`), from the current
        state. Times in the result are seconds from the first sample the detector saw."""
        t = inputs.rows("detector", "t", t, np.shape(t)[0] if np.ndim(t) == 1 else -1, None)
        n = len(t)
        clamped = {a for j, a in enumerate("xyz") if self._state[STATE.scale_clamped + j] != 0.0}
        dt = np.diff(t, prepend=t[0] - (np.median(np.diff(t)) if n > 1 else 0.0)) if n else t
        cmds = np.zeros((0, self.rotors)) if commands is None else commands
        diag = np.zeros((n, DIAG))
        _checked_batch("detector", self._state, self._values, self._model, dt, gyr, acc, rotors, diag, cmds)
        res = self.result(t, diag[:, : self.rotors])
        res.statistics = diag[:, STAT:DIAG]
        new = [a for a in res.moment_scale_clamped if a not in clamped]
        if new:
            warnings.warn(
                f"detector: the rotors' moment learnt about {', '.join(new)} reached its clamp (1 ± "
                f"{SCALE_RANGE:g} of the model's): the vehicle's model is off by more than that (inertia, mass, "
                "thrust or arm length); fit it, or the detection runs on the clamped model",
                stacklevel=2,
            )
        return res


def _vec(v, n, name):
    return inputs.rows(
        "detector", name, v, n, None, inputs.rotor_hint(np.size(v), n) if name in ("rotors", "commands") else ""
    )
