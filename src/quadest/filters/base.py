"""What every estimator shares: its parameter record, its state, streaming and batch use.

An estimator module defines a frozen ``Params`` dataclass (unit, default and source in each
field's metadata), the size of its state, the names of its per-sample diagnostics, a compiled
``step(x, p, gyr, acc, mag, dt, diag)`` that is its single implementation, a compiled
``batch`` loop that calls that step for every sample, and a subclass of :class:`Estimator`.
Streaming ``update`` calls the step once; batch ``run`` calls the loop. (Each module has its own
four-line loop: numba cannot cache one loop that takes the step as an argument.)

Conventions (:mod:`quadest.conventions`): ``q_nb`` scalar first, NED/FRD, SI units. Estimators
work in the magnetic NED frame (x towards magnetic north); ``declination`` (rad, east positive)
rotates their output into the geographic frame. NaN magnetometer rows mean "no new sample":
the magnetometer correction is skipped for that step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from quadest.filters.common import BASE, INIT, T_LAST
from quadest.rotation import quat_mul, quat_to_euler
from quadest.rotation.kernels import qmul


def P(default, unit: str, doc: str, source: str):
    """A parameter: default, unit, meaning and where the default comes from."""
    return field(default=default, metadata={"unit": unit, "doc": doc, "source": source})


@dataclass(frozen=True)
class Params:
    """Base of the parameter records; fields are floats (or bools), packed in order."""

    def as_array(self) -> np.ndarray:
        out = []
        for f in fields(self):
            v = getattr(self, f.name)
            out.extend(np.atleast_1d(np.asarray(v, dtype=float)).ravel().tolist())
        return np.array(out, dtype=np.float64)

    @classmethod
    def describe(cls) -> list[dict]:
        return [{"name": f.name, "default": f.default, **f.metadata} for f in fields(cls)]


@dataclass
class FilterResult:
    """Output of a batch run: time, attitude ``q_nb`` and per-sample diagnostics."""

    name: str
    t: np.ndarray
    q: np.ndarray
    diag: dict
    params: Params

    @property
    def euler(self) -> np.ndarray:
        """``[roll, pitch, yaw]`` (rad, ZYX) per sample."""
        return quat_to_euler(self.q)


def _declination_quat(declination):
    return np.array([math.cos(0.5 * declination), 0.0, 0.0, math.sin(0.5 * declination)])


class Estimator:
    """Base class: subclasses set ``name``, ``Params``, ``state_size``, ``diag_names``,
    ``step`` (a compiled function) and may override :meth:`_init_state`."""

    name = "estimator"
    Params = Params
    state_size = BASE
    diag_names: tuple = ()
    uses_mag = True
    step = None
    batch = None

    def __init__(self, params: Params | None = None, *, q0=None, declination: float = 0.0,
                 **overrides):
        params = params if params is not None else self.Params()
        if overrides:
            names = {f.name for f in fields(params)}
            bad = sorted(set(overrides) - names)
            if bad:
                raise TypeError(f"{self.name}: unknown parameter(s) {', '.join(bad)}; "
                                f"parameters: {', '.join(sorted(names))}")
            params = replace(params, **overrides)
        self.params = params
        self._p = params.as_array()
        self.declination = float(declination)
        self._dq = _declination_quat(self.declination) if self.declination != 0.0 else None
        self._step = type(self).step
        self._q0 = None if q0 is None else np.asarray(q0, float) / np.linalg.norm(q0)
        self._diag = np.zeros(max(1, len(self.diag_names)))
        self.reset()

    # -- state ----------------------------------------------------------------------------
    def _init_state(self, x: np.ndarray) -> None:
        """Estimator-specific initial values of ``x[BASE:]`` (zeros by default)."""

    def reset(self, q0=None):
        """Back to the initial state (attitude from ``q0`` or from the first samples)."""
        if q0 is not None:
            self._q0 = np.asarray(q0, float) / np.linalg.norm(q0)
        x = np.zeros(self.state_size)
        x[0] = 1.0
        x[T_LAST] = np.nan
        if self._q0 is not None:
            # the estimator's frame is magnetic; q0 is given in the geographic frame
            x[0:4] = quat_mul(_declination_quat(-self.declination), self._q0)
            x[INIT] = 1.0
        self._init_state(x)
        self._x = x

    def get_state(self) -> np.ndarray:
        """A copy of the whole state (attitude, flags and estimator-specific parts)."""
        return self._x.copy()

    def set_state(self, x) -> None:
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (self.state_size,):
            raise ValueError(f"{self.name}: state must have shape ({self.state_size},), got {x.shape}")
        self._x = x.copy()

    @property
    def q(self) -> np.ndarray:
        """Current attitude ``q_nb`` in the geographic NED frame."""
        return self._out(self._x[0:4])

    def _out(self, q):
        if self._dq is None:
            return q.copy()
        return qmul(self._dq, q)

    # -- use ------------------------------------------------------------------------------
    def update(self, gyr, acc, mag=None, *, dt: float) -> np.ndarray:
        """One sample: gyroscope (rad/s), accelerometer (m/s²), magnetometer (any unit or None),
        time since the previous sample (s). Returns the attitude ``q_nb``."""
        self._step(self._x, self._p, _f64(gyr), _f64(acc), _NAN3 if mag is None else _f64(mag),
                   float(dt), self._diag)
        return self._out(self._x[:4])

    @property
    def diagnostics(self) -> dict:
        """Diagnostics of the last streaming step, by name."""
        return {n: float(self._diag[i]) for i, n in enumerate(self.diag_names)}

    def run(self, rec=None, *, t=None, gyr=None, acc=None, mag=None) -> FilterResult:
        """Run over a whole recording (or arrays) in compiled code, continuing from the current
        state. Returns the attitude per sample and the diagnostics."""
        if rec is not None:
            t, gyr, acc, mag = rec.t, rec.gyr, rec.acc, rec.mag
        t = np.asarray(t, dtype=np.float64)
        n = len(t)
        gyr = np.ascontiguousarray(gyr, dtype=np.float64)
        acc = np.ascontiguousarray(acc, dtype=np.float64)
        mag = (np.full((n, 3), np.nan) if mag is None or not self.uses_mag
               else np.ascontiguousarray(mag, dtype=np.float64))
        for name, a in (("gyr", gyr), ("acc", acc), ("mag", mag)):
            if a.shape != (n, 3):
                raise ValueError(f"{self.name}: {name} must have shape ({n}, 3), got {a.shape}")
        dt = sample_intervals(t)
        if n and np.isfinite(self._x[T_LAST]):  # resuming: the real interval to the last sample
            dt[0] = t[0] - self._x[T_LAST]
        q = np.empty((n, 4))
        diag = np.zeros((n, max(1, len(self.diag_names))))
        type(self).batch(self._x, self._p, dt, gyr, acc, mag, q, diag)
        if n:
            self._x[T_LAST] = t[-1]
        if self.declination != 0.0:
            q = quat_mul(_declination_quat(self.declination), q)
        return FilterResult(self.name, t, q, {nm: diag[:, i] for i, nm in enumerate(self.diag_names)},
                            self.params)


_NAN3 = np.full(3, np.nan)
_F8 = np.dtype(np.float64)


def _f64(v):
    """A float64 array without copying one that already is (the streaming hot path)."""
    return v if type(v) is np.ndarray and v.dtype is _F8 else np.asarray(v, dtype=np.float64)


def sample_intervals(t) -> np.ndarray:
    """``dt[k] = t[k] − t[k−1]``; the first interval is the median one (0 for one sample)."""
    t = np.asarray(t, dtype=np.float64)
    if len(t) < 2:
        return np.zeros(len(t))
    d = np.diff(t)
    return np.concatenate([[np.median(d)], d])
