"""What every estimator shares: its parameter record, its state, streaming and batch use.

An estimator module defines (docs/developing.md, adding an estimator):

- a frozen ``Params`` dataclass (unit, default and source in each field's metadata);
- ``PARAM = Record = params_record(Params)``: the offsets by which the compiled step reads its
  parameters by name from a float64 array (``p[PARAM.beta]``; flags are 0 / 1), so the order of
  the fields never matters;
- optionally a ``Coefficients`` namedtuple, ``COEF = coefficient_offsets(Coefficients)`` and
  ``coefficients(params)``: constants derived from the parameters, computed once when the
  estimator is built, not at every step, read as ``c[COEF.r_acc]``;
- its state layout (:func:`quadest.filters.common.layout`), the names of its per-sample
  diagnostics;
- a compiled ``step(x, p, c, gyr, acc, mag, dt, diag)`` that is its single implementation, a
  compiled ``batch`` loop that calls that step for every sample, a ``stream`` function that
  calls the step on raw buffers (compiled as a C callback on first streaming use,
  :func:`stream_address`), and a subclass of :class:`Estimator`.

Streaming ``update`` calls the step once (from C where the extension ``_stream`` is built:
:data:`STREAM_C`); batch ``run`` calls the loop. (Each module has its own four-line loop and
stream function: numba cannot cache one that takes the step as an argument.)

Conventions (:mod:`quadest.conventions`): ``q_nb`` scalar first, NED/FRD, SI units. Estimators
work in the magnetic NED frame (x towards magnetic north); ``declination`` (rad, east positive)
rotates their output into the geographic frame. NaN magnetometer rows mean "no new sample":
the magnetometer correction is skipped for that step.
"""

from __future__ import annotations

import copy
import math
import numbers
from collections import namedtuple
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from quadest._jit import cfunc, types
from quadest.data.checks import GAP_FACTOR, GAP_MIN_S
from quadest.errors import UsageError
from quadest.extras import need
from quadest.filters.common import BASE, DECL, INIT, MAG, MAG_SKIPPED, Q_OUT, RESTARTS, SKIPPED, T_LAST, YAW_PENDING
from quadest.records import Params, check, field_offsets, number, pack, params_record  # noqa: F401 -- the filters take them from here
from quadest.rotation import quat_mul, quat_to_euler
from quadest.rotation.kernels import qmul

if TYPE_CHECKING:
    from quadest.data.recording import Recording


def coefficient_offsets(coefficients_cls):
    """The offsets of a ``Coefficients`` namedtuple's fields in the float64 array the compiled
    step reads them from (``c[COEF.r_acc]``)."""
    return field_offsets(coefficients_cls._fields, "CoefficientOffsets")


NoCoefficients = namedtuple("NoCoefficients", [])
"""The coefficients of an estimator that derives none."""
NO_COEFFICIENTS = NoCoefficients()


def no_coefficients(params: Params) -> NoCoefficients:
    return NO_COEFFICIENTS


@dataclass
class FilterResult:
    """Output of a batch run: time, attitude ``q_nb`` and per-sample diagnostics."""

    name: str
    t: np.ndarray
    q: np.ndarray
    diag: dict
    params: Params
    skipped: int = 0
    """Samples skipped in this run (an unusable interval or value: docs/reliability.md)."""
    restarts: tuple = ()
    """Times (s) at which the estimator started again from the sensors after a gap."""
    mag_skipped: int = 0
    """Samples whose magnetometer value was unusable (not finite, or beyond any sensor): used
    without it (docs/reliability.md); not in ``skipped``."""

    frame: str = "ned-frd"
    """The frames of ``q``: ``"ned-frd"`` (quadest's) or ``"enu-flu"`` (as the input was given)."""

    @property
    def euler(self) -> np.ndarray:
        """``[roll, pitch, yaw]`` (rad, ZYX) per sample."""
        return quat_to_euler(self.q)

    @property
    def diagnostics(self) -> dict:
        """The estimator's per-sample diagnostics by name (``diag``)."""
        return self.diag

    def to_pandas(self) -> pandas.DataFrame:  # noqa: F821 (pandas is optional: loaded when called)
        """A pandas DataFrame indexed by ``t``: ``q_w..q_z``, ``roll, pitch, yaw`` (rad) and the
        diagnostics."""
        pd = need("pandas", "FilterResult.to_pandas")
        cols = {f"q_{a}": self.q[:, i] for i, a in enumerate("wxyz")}
        cols.update(zip(("roll", "pitch", "yaw"), self.euler.T))
        cols.update({k: v for k, v in self.diag.items() if k not in cols})
        return pd.DataFrame(cols, index=pd.Index(self.t, name="t"))


def unit_quaternion(q, name: str) -> np.ndarray:
    """``q`` (four finite numbers, not all zero) normalised, or :class:`UsageError` naming it."""
    try:
        a = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError):
        raise UsageError(f"{name} must be a quaternion [w, x, y, z], got {q!r}") from None
    if a.shape != (4,) or not np.isfinite(a).all():
        raise UsageError(f"{name} must be a quaternion [w, x, y, z] of four finite numbers, got {q!r}")
    norm = float(np.linalg.norm(a))
    if not 1e-6 < norm < 1e150:
        raise UsageError(f"{name} must be a quaternion [w, x, y, z] of norm about 1, got {q!r} (norm {norm:.3g})")
    return a / norm


COUNT_LIMIT = 2.0**53
"""A state's counters are whole numbers from 0 to this (a float holds every whole number up to it)."""


def checked_state(x, size: int, who: str, none_yet: tuple = ()) -> np.ndarray:
    """A copy of ``x`` as a state of ``size`` values, refused (:class:`UsageError`) unless it can
    be one: finite (the last time, the last magnetometer sample and the estimator's own
    ``none_yet`` slots may be NaN: none yet), a unit attitude, the flags
    0 or 1, the counters whole numbers from 0 to :data:`COUNT_LIMIT`, the declination's half-angle
    cosine and sine on the unit circle."""
    try:
        x = np.array(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise UsageError(f"{who}: a state must be an array of {size} numbers") from None
    if x.shape != (size,):
        raise UsageError(f"{who}: state must have shape ({size},), got {x.shape}")
    finite = np.isfinite(x)
    nan_ok = [T_LAST, MAG, MAG + 1, MAG + 2, *none_yet]
    finite[nan_ok] = ~np.isinf(x[nan_ok])  # NaN: none yet
    if not finite.all():
        raise UsageError(f"{who}: state value {int(np.flatnonzero(~finite)[0])} is not finite")
    problems = {
        "the attitude x[0:4] is not a unit quaternion": abs(np.linalg.norm(x[0:4]) - 1.0) > 1e-6,
        "a flag (initialised, heading pending) is not 0 or 1": not set(x[[INIT, YAW_PENDING]]) <= {0.0, 1.0},
        f"a counter (skipped, restarts, magnetometer skipped) is not a whole number in [0, {COUNT_LIMIT:.0f}]": any(
            not (0.0 <= v <= COUNT_LIMIT and v == int(v)) for v in x[[SKIPPED, RESTARTS, MAG_SKIPPED]]
        ),
        "the declination's cosine and sine are not on the unit circle": abs(np.hypot(x[DECL], x[DECL + 1]) - 1.0)
        > 1e-6,
    }
    for what, bad in problems.items():
        if bad:
            raise UsageError(f"{who}: not a state of this estimator: {what}")
    return x


def declination_quat(declination: float) -> np.ndarray:
    """``[cos δ/2, 0, 0, sin δ/2]``: the rotation about down that takes the magnetic frame's
    attitude into the geographic frame (``q_geo = dq ⊗ q_mag``), δ the declination (rad)."""
    return np.array([math.cos(0.5 * declination), 0.0, 0.0, math.sin(0.5 * declination)])


class CompiledEstimator(NamedTuple):
    """What a compiled loop needs to run an estimator's step (:meth:`Estimator.compiled`)."""

    step: object
    """The compiled step ``step(state, params, coefficients, gyr, acc, mag, dt, diag)``: the
    function the batch run and streaming call."""
    state: np.ndarray
    """The estimator's own state, written in place: the estimator goes on from where a loop
    leaves it (its attitude in the magnetic frame at ``state[0:4]``)."""
    params: np.ndarray
    coefficients: np.ndarray
    diag: np.ndarray
    """Written by each step: the estimator's diagnostics (``diag_names``)."""
    declination_quat: np.ndarray
    """:func:`declination_quat` of the estimator's declination."""


class Estimator:
    """Base class: subclasses set ``name``, ``Params``, ``Record``, ``state_size``,
    ``diag_names``, ``step`` and ``batch`` (compiled functions), ``stream`` (the step on raw
    buffers, for the C call; without it streaming runs through Python), optionally
    ``coefficients``, and may override :meth:`_init_state`. The peers
    (:class:`quadest.filters.peers.Peer`) are subclasses too, without a compiled step."""

    name = "estimator"
    peer = False
    """True for another package's estimator run through quadest (:mod:`quadest.filters.peers`)."""
    streaming = True
    """Whether it has a per-sample :meth:`update` (so it can fly in the closed loop)."""
    none_yet: tuple = ()
    """Slots of its own state that hold NaN until a sample fills them (a state may have them so)."""
    acausal = False
    """True for an offline estimator: each estimate uses the whole recording, later samples too
    (``quadest estimate --offline``)."""
    Params = Params
    Record = None
    coefficients = staticmethod(no_coefficients)
    state_size = BASE
    diag_names: tuple = ()
    step = None
    batch = None
    stream = None

    def __init__(
        self,
        params: Params | None = None,
        *,
        q0: ArrayLike | None = None,
        declination: float = 0.0,
        max_gap_s: float | None = None,
        **overrides,
    ):
        self.params = self._checked(params, overrides)
        self._s = np.array([0.01, STREAM_GAP_S])  # streaming: the last interval, the longest (C reads both)
        self.max_gap_s = max_gap_s
        self.declination = declination
        self._call_step = self._first_step
        self._q0 = None if q0 is None else unit_quaternion(q0, f"{self.name}: q0")
        self._diag = np.zeros(max(1, len(self.diag_names)))
        self.reset()

    @property
    def params(self) -> Params:
        """The parameter record; a new one (of the estimator's ``Params``) is checked and takes
        effect from the next sample, the state kept."""
        return self._params

    @params.setter
    def params(self, params: Params) -> None:
        params = self._checked(params, {})
        self._params = params
        if self.Record is None:  # a peer: its package takes the record itself
            return
        values = params.values()
        p = pack(values[f] for f in self.Record._fields)  # read by name in compiled code
        c = pack(type(self).coefficients(replace(params, **values)))  # derived once, not every step
        if hasattr(self, "_p"):  # written in place: the C call and compiled() hold these arrays
            self._p[:], self._c[:] = p, c
        else:
            self._p, self._c = p, c

    @property
    def declination(self) -> float:
        """The magnetic declination (rad, east positive) that turns the estimate to true north;
        a new value is checked and applies at once."""
        return self._declination

    @declination.setter
    def declination(self, value: float) -> None:
        self._declination = number(value, f"{self.name}: declination")
        if hasattr(self, "_x"):
            self._set_declination(self._x)

    def _checked(self, params, overrides) -> Params:
        """The parameter record with ``overrides`` applied, checked."""
        params = params if params is not None else self.Params()
        if not isinstance(params, self.Params):
            raise UsageError(f"{self.name}: params must be a {self.Params.__name__}, got {type(params).__name__}")
        if overrides:
            names = {f.name for f in fields(params)}
            bad = sorted(set(overrides) - names)
            if bad:
                raise TypeError(
                    f"{self.name}: unknown parameter(s) {', '.join(bad)}; parameters: {', '.join(sorted(names))}"
                )
            params = replace(params, **overrides)
        check(params, self.name)
        return params

    @classmethod
    def available(cls) -> bool:
        """Whether it can run here (a peer needs its package)."""
        return True

    # -- state ----------------------------------------------------------------------------
    def compiled(self) -> CompiledEstimator:
        """The compiled step and the live arrays it works on, for a loop in compiled code (the
        closed loop of :mod:`quadest.flight`): nothing outside ``filters`` reads a private field.
        A new state (:meth:`reset`, :meth:`set_state`) makes new arrays: call it again after."""
        return CompiledEstimator(
            type(self).step, self._x, self._p, self._c, self._diag, declination_quat(self.declination)
        )

    def _init_state(self, x: np.ndarray) -> None:
        """Estimator-specific initial values of ``x[BASE:]`` (zeros by default)."""

    def reset(self, q0: ArrayLike | None = None) -> None:
        """Back to the initial state (attitude from ``q0`` or from the first samples)."""
        if q0 is not None:
            self._q0 = unit_quaternion(q0, f"{self.name}: q0")
        x = np.zeros(self.state_size)
        x[0] = 1.0
        x[T_LAST] = np.nan
        if self._q0 is not None:
            # the estimator's frame is magnetic; q0 is given in the geographic frame
            x[0:4] = quat_mul(declination_quat(-self.declination), self._q0)
            x[INIT] = 1.0
        self._init_state(x)
        self._set_declination(x)
        self._x = x
        self._qv = x[Q_OUT : Q_OUT + 4]  # a view of the published attitude (the streaming output copies it)
        self.__dict__.pop("update", None)  # the C call held the old state: made again at the next update

    def _set_declination(self, x):
        """The declination's half-angle cosine and sine, and the published attitude from them."""
        x[DECL], x[DECL + 1] = math.cos(0.5 * self.declination), math.sin(0.5 * self.declination)
        x[Q_OUT : Q_OUT + 4] = qmul(np.array([x[DECL], 0.0, 0.0, x[DECL + 1]]), x[0:4])

    def _restart(self):
        """Start again from the next samples (after a gap): the attitude is initialised from the
        accelerometer and magnetometer as at the start; the counters are kept."""
        x = np.zeros(self.state_size)
        x[0] = 1.0
        self._init_state(x)
        self._set_declination(x)
        x[SKIPPED], x[RESTARTS], x[T_LAST] = self._x[SKIPPED], self._x[RESTARTS] + 1.0, self._x[T_LAST]
        x[MAG_SKIPPED] = self._x[MAG_SKIPPED]
        self._x[:] = x

    @property
    def skipped(self) -> int:
        """Samples skipped since the start (unusable interval or value)."""
        return int(self._x[SKIPPED])

    @property
    def restarts(self) -> int:
        """How often the estimator started again from the sensors after a gap."""
        return int(self._x[RESTARTS])

    @property
    def mag_skipped(self) -> int:
        """Samples used without their magnetometer value, which was unusable (not finite, or
        beyond any sensor); these are not in :attr:`skipped`."""
        return int(self._x[MAG_SKIPPED])

    def get_state(self) -> np.ndarray:
        """A copy of the whole state (attitude, flags and estimator-specific parts)."""
        return self._x.copy()

    def set_state(self, x: ArrayLike) -> None:
        """Continue from a state taken by :meth:`get_state` (of an estimator of this kind); one
        that cannot be such a state is refused (:func:`checked_state`)."""
        self._x = checked_state(x, self.state_size, self.name, self.none_yet)
        self._qv = self._x[Q_OUT : Q_OUT + 4]
        self.__dict__.pop("update", None)  # the C call held the old state: made again at the next update

    @property
    def max_gap_s(self) -> float | None:
        """Streaming: an interval longer than this (s) is a gap after which the estimator starts
        again from the sensors; None: :data:`STREAM_GAP_S`. In batch use, None means ten nominal
        intervals and at least :data:`GAP_MIN_S`."""
        return self._max_gap_s

    @max_gap_s.setter
    def max_gap_s(self, value):
        if value is not None:
            value = number(value, f"{self.name}: max_gap_s", bounds="(0, 1e9]")
        self._max_gap_s = value
        self._s[1] = value or STREAM_GAP_S

    @property
    def q(self) -> np.ndarray:
        """Current attitude ``q_nb`` in the geographic NED frame."""
        return self._qv.copy()

    # -- use ------------------------------------------------------------------------------
    def update(self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None, *, dt: float) -> np.ndarray:
        """One sample: gyroscope (rad/s), accelerometer (m/s²), magnetometer (any unit or None),
        time since the previous sample (s). Returns the attitude ``q_nb``. An unusable sample
        (non-finite or absurd value, ``dt`` not positive) is skipped and counted
        (:attr:`skipped`); after a gap longer than ``max_gap_s`` (default
        ``STREAM_GAP_S``) the estimator starts again from the sensors (:attr:`restarts`).

        This method is the rules; after the first call, the object's ``update`` is the C call
        of the extension ``_stream`` (where it is built, :data:`STREAM_C`), which does the
        common case (a float interval within the gap, three contiguous native float64 vectors,
        the magnetometer's may be None) itself and hands every other call to this method with
        the same arguments. Each check below is what a wrong input would otherwise turn into
        wrong memory reads in compiled code."""
        if type(dt) is not float:
            dt = _interval(dt, self.name)
        s = self._s
        if not 0.0 < dt <= s[1]:
            if 0.0 < dt < math.inf:  # a gap: start again; the first sample after it spans a nominal interval
                self._restart()
                dt = s[0]
            dt = float(dt)  # refuses what is not a number; NaN and ≤ 0 are skipped by the step
        else:
            s[0] = dt
        if not (type(gyr) is _ND and gyr.dtype is _F8 and gyr.strides == _ST and len(gyr) == 3):
            gyr = _vec3(gyr)
        if not (type(acc) is _ND and acc.dtype is _F8 and acc.strides == _ST and len(acc) == 3):
            acc = _vec3(acc)
        if mag is None:
            mag = _NAN3
        elif not (type(mag) is _ND and mag.dtype is _F8 and mag.strides == _ST and len(mag) == 3):
            mag = _vec3(mag)
        self._call_step(self._x, self._p, self._c, gyr, acc, mag, dt, self._diag)
        if "update" not in self.__dict__ and STREAM_C:
            self._stream_from_c()
        return self._qv.copy()  # the step published it in the geographic frame

    def _stream_from_c(self):
        """Make the object's ``update`` the C call on this state (:mod:`._stream`); the class's
        ``update`` stays its fallback for every call out of the common case."""
        address = stream_address(type(self))
        if address:
            self.update = _Stream(
                address, self._x, self._p, self._c, self._diag, self._s, Q_OUT, type(self).update.__get__(self)
            )

    def __getstate__(self):  # the compiled entry point and the C call are made again after unpickling
        state = dict(self.__dict__)
        state["_call_step"] = None
        state.pop("_qv", None)  # a view of _x, made again after unpickling
        state.pop("update", None)
        return state

    def __copy__(self):
        """A copy is a whole estimator: its state, parameter and coefficient arrays its own (a
        shallow copy shared them, and the compiled step writes them in place)."""
        return copy.deepcopy(self)

    def __setstate__(self, state):
        self.__dict__.update(state)
        # a state of another layout (an older version's) is refused, as set_state refuses it
        self._x = checked_state(self._x, self.state_size, self.name, self.none_yet)
        self._call_step = self._first_step
        self._qv = self._x[Q_OUT : Q_OUT + 4]

    def _first_step(self, *args):
        """The first streaming call goes through numba's dispatcher (which compiles or loads the
        step); later calls go to the compiled entry point of that signature directly, which
        skips the dispatcher's type resolution (about 2 µs per call for namedtuple arguments).
        The arguments' types cannot change: the records are this object's, the vectors are
        checked by :func:`_vec3`, ``dt`` is a float."""
        step = type(self).step
        step(*args)
        sig = tuple(step.typeof_pyval(a) for a in args)
        self._call_step = step.overloads[sig].entry_point

    @property
    def diagnostics(self) -> dict:
        """Diagnostics of the last streaming step, by name."""
        return {n: float(self._diag[i]) for i, n in enumerate(self.diag_names)}

    def run(
        self,
        rec: Recording | None = None,
        *,
        t: ArrayLike | None = None,
        gyr: ArrayLike | None = None,
        acc: ArrayLike | None = None,
        mag: ArrayLike | None = None,
        rate: float | None = None,
    ) -> FilterResult:
        """Run over a whole recording (or arrays) in compiled code, continuing from the current
        state. Returns the attitude per sample and the diagnostics. Arrays are timed by ``t``
        (s) or, evenly, by ``rate`` (Hz)."""
        if rec is not None:
            t, gyr, acc, mag = rec.t, rec.gyr, rec.acc, rec.mag
        t = sample_times(t, rate, gyr, self.name)
        n = len(t)
        gyr = np.ascontiguousarray(gyr, dtype=np.float64)
        acc = np.ascontiguousarray(acc, dtype=np.float64)
        mag = np.full((n, 3), np.nan) if mag is None else np.ascontiguousarray(mag, dtype=np.float64)
        for name, a in (("gyr", gyr), ("acc", acc), ("mag", mag)):
            if a.shape != (n, 3):
                raise ValueError(f"{self.name}: {name} must have shape ({n}, 3), got {a.shape}")
        dt = sample_intervals(t)
        if n and np.isfinite(self._x[T_LAST]):  # resuming: the real interval to the last sample
            dt[0] = t[0] - self._x[T_LAST]
        # gaps: the estimator starts again from the sensors after each (docs/reliability.md)
        nominal = dt[0] if n and not np.isfinite(self._x[T_LAST]) else _nominal_interval(dt)
        gap = self.max_gap_s or max(GAP_FACTOR * nominal, GAP_MIN_S)
        starts = np.flatnonzero(dt > gap)
        q = np.empty((n, 4))
        diag = np.zeros((n, max(1, len(self.diag_names))))
        skipped0, mag_skipped0 = self._x[SKIPPED], self._x[MAG_SKIPPED]
        restarts = []
        bounds = [0, *[int(k) for k in starts if k > 0], n]
        if len(starts) and starts[0] == 0:  # resuming after a gap
            self._restart()
            restarts.append(float(t[0]))
            dt[0] = nominal
        for a, b in zip(bounds[:-1], bounds[1:]):
            if a > 0:
                self._restart()
                restarts.append(float(t[a]))
                dt[a] = nominal  # the first sample after a gap spans a nominal interval
            type(self).batch(self._x, self._p, self._c, dt[a:b], gyr[a:b], acc[a:b], mag[a:b], q[a:b], diag[a:b])
        finite_t = t[np.isfinite(t)]
        if len(finite_t):
            self._x[T_LAST] = finite_t[-1]
        return FilterResult(
            self.name,
            t,
            q,
            {nm: diag[:, i] for i, nm in enumerate(self.diag_names)},
            self.params,
            int(self._x[SKIPPED] - skipped0),
            tuple(restarts),
            mag_skipped=int(self._x[MAG_SKIPPED] - mag_skipped0),
        )


try:
    from quadest.filters._stream import Stream as _Stream
except ImportError:  # built without a C compiler: streaming runs through Estimator.update
    _Stream = None
STREAM_C = _Stream is not None
"""Whether streaming ``update`` runs through the C extension ``_stream`` (built at install time
where a C compiler is found; else the Python path, about a microsecond slower per call)."""

_F8P = types.CPointer(types.float64)
STREAM_SIGNATURE = types.int64(
    _F8P, types.intp, _F8P, types.intp, _F8P, types.intp, _F8P, _F8P, _F8P, types.float64, _F8P, types.intp
)
"""``stream(x, nx, p, np, c, nc, gyr, acc, mag, dt, diag, nd) -> status``: an estimator's step
on raw buffers with their lengths (the vectors have three values), as the C call invokes it;
status 1 if the step raised (a C callback cannot pass an exception on: the C call raises)."""
_STREAM_CFUNCS: dict = {}  # class -> its compiled stream function (kept: its machine code must outlive the C calls)


def stream_address(cls) -> int:
    """The address of ``cls.stream`` compiled as a C callback (numba ``cfunc``, cached on disk
    like every compiled function); 0 for a class without one. Compiled once per class."""
    if cls not in _STREAM_CFUNCS:
        fn = cls.stream  # a plain function (a staticmethod seen through the class)
        _STREAM_CFUNCS[cls] = None if fn is None else cfunc(STREAM_SIGNATURE, cache=True)(fn)
    compiled = _STREAM_CFUNCS[cls]
    return 0 if compiled is None else compiled.address


_NAN3 = np.full(3, np.nan)
_F8 = np.dtype(np.float64)
_ND = np.ndarray
_ST = (8,)  # the strides of a contiguous vector of float64 (a 1-D one: with len 3, shape (3,))


def _vec3(v):
    """A contiguous float64 vector of three, without copying one that already is (the streaming
    hot path); anything else is converted, or refused."""
    if type(v) is np.ndarray and v.dtype is _F8 and v.size == 3 and v.ndim == 1 and v.flags.c_contiguous:
        return v
    a = np.ascontiguousarray(v, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"expected a vector of 3 values, got shape {a.shape}")
    return a


STREAM_GAP_S = 0.5
"""Streaming: an interval longer than this is a gap (no median is known there); set
``max_gap_s`` to choose."""


def _nominal_interval(dt) -> float:
    """The median of the usable (positive, finite) intervals; 0 when there is none."""
    ok = dt[np.isfinite(dt) & (dt > 0)]
    return float(np.median(ok)) if len(ok) else 0.0


def _interval(dt, name: str) -> float:
    """A streaming ``dt`` as a float: a real number (Python's, numpy's, a Fraction); anything
    else (a Decimal, a string, a bool, an array) refused in one line."""
    if isinstance(dt, bool) or not isinstance(dt, (numbers.Real, np.floating, np.integer)):
        raise UsageError(f"{name}: dt must be a real number of seconds, got {type(dt).__name__} {dt!r}")
    return float(dt)


RATE_TOLERANCE = 0.05
"""A rate given with the times may differ from their median interval's by this share at most."""


def sample_times(t, rate, gyr, who: str) -> np.ndarray:
    """``t`` as float64, or ``k / rate`` for the rows of ``gyr``; given both, the rate must agree
    with the times' median interval (:data:`RATE_TOLERANCE`) and the times are used."""
    if t is None and rate is None:
        raise UsageError(f"{who}: give the sample times t (s) or the sample rate rate (Hz)")
    if rate is not None and (
        isinstance(rate, bool) or not (isinstance(rate, (int, float, np.number)) and math.isfinite(rate) and rate > 0)
    ):
        raise UsageError(f"{who}: rate must be a positive number of samples per second, got {rate!r}")
    if t is None:
        return np.arange(len(np.asarray(gyr))) / float(rate)
    t = np.asarray(t, dtype=np.float64)
    if rate is not None and t.ndim == 1 and len(t) >= 2:
        _check_rate_against_times(t, float(rate), who)
    return t


def _check_rate_against_times(t, rate: float, who: str) -> None:
    """Refuse a stated rate that the times contradict (their median interval's rate)."""
    with np.errstate(invalid="ignore"):
        dt = np.diff(t)
    dt = dt[np.isfinite(dt) & (dt > 0)]
    if not len(dt):
        return
    of_times = 1.0 / float(np.median(dt))
    if abs(of_times / rate - 1.0) > RATE_TOLERANCE:
        raise UsageError(
            f"{who}: rate={rate:g} Hz, but the times t step {1 / of_times:.3g} s (median), {of_times:.4g} Hz: "
            "they disagree; give the times in seconds and the rate in Hz, or only one of them"
        )


def sample_intervals(t) -> np.ndarray:
    """``dt[k] = t[k] − t[j]`` with ``t[j]`` the latest earlier time that was usable (finite, and
    later than every time before it); the first interval is the median of the usable ones (0 for
    one sample). A non-finite time or one that goes backwards gives an unusable interval (NaN or ≤ 0):
    the filters skip that sample, and the next one is measured from the last good time."""
    t = np.asarray(t, dtype=np.float64)
    if len(t) < 2:
        return np.zeros(len(t))
    latest = np.maximum.accumulate(np.where(np.isfinite(t), t, -np.inf))
    prev = np.concatenate([[-np.inf], latest[:-1]])
    with np.errstate(invalid="ignore"):  # inf − inf: NaN, as wanted
        dt = t - prev
        nominal = _nominal_interval(np.diff(t))
    dt[~np.isfinite(prev) & np.isfinite(t)] = nominal  # the first usable sample
    dt[~np.isfinite(t)] = np.nan  # a NaN or infinite time: skipped and counted, never a gap
    return dt
