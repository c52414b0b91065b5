"""Parameter records: frozen dataclasses whose every field states its unit, meaning and where
its value comes from (a publication, or "chosen" and why). The estimators', the recovery's and
the simulator's parameters are all declared with :func:`param`."""

from __future__ import annotations

import math
import sys
from collections import namedtuple
from dataclasses import dataclass, field, fields

import numpy as np

from quadest.errors import UsageError

CHOSEN = "chosen (no published value)"


def param(default, unit: str, doc: str, source: str = CHOSEN, bounds: str | None = None):
    """A parameter field: default, unit, one-line meaning, the source of the default, and the
    values it may take (``bounds`` as an interval, ``"(0, 1]"``; numbers must be finite in any
    case). :func:`check` refuses a record with a value outside."""
    meta = {"unit": unit, "doc": doc, "source": source}
    if bounds is not None:
        _interval(bounds)  # a malformed interval fails at import, not at use
        meta["bounds"] = bounds
    return field(default=default, metadata=meta)


def _interval(text: str):
    lo_open, hi_open = text[0] == "(", text[-1] == ")"
    if text[0] not in "([" or text[-1] not in ")]":
        raise ValueError(f"bounds {text!r}: write an interval like (0, 1]")
    lo, hi = (float(v) for v in text[1:-1].split(","))
    return lo, hi, lo_open, hi_open


def check_triples(record, owner: str, *names) -> None:
    """Raise ValueError unless each named field holds three finite non-negative numbers."""
    for name in names:
        v = np.asarray(getattr(record, name), float)
        if v.shape != (3,) or not np.isfinite(v).all() or (v < 0).any():
            raise ValueError(f"{owner}: {name} must be three non-negative numbers, got {getattr(record, name)!r}")


def check(record, owner: str = "") -> None:
    """Raise :class:`UsageError` naming the parameter when a value is not a finite number or
    lies outside its bounds."""
    who = f"{owner}: " if owner else ""
    for f in fields(record):
        v = getattr(record, f.name)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            continue
        if not math.isfinite(v):
            raise UsageError(f"{who}{f.name} must be a finite number, got {v!r}")
        b = f.metadata.get("bounds")
        if b:
            lo, hi, lo_open, hi_open = _interval(b)
            if (v < lo or (lo_open and v == lo)) or (v > hi or (hi_open and v == hi)):
                raise UsageError(f"{who}{f.name} must be in {b}, got {v!r}")


def describe(record_cls) -> list[dict]:
    """``[{name, default, unit, doc, source}]`` of a parameter record's fields, in order."""
    return [{"name": f.name, "default": f.default, **f.metadata} for f in fields(record_cls)]


_KINDS = {"f8": float, "i8": int, "b1": bool}


def compiled_record(name: str, doc: str, **spec):
    """A record that compiled code reads by field name (a namedtuple, which numba passes by
    value at no cost), made only through ``make(**fields)``, which checks every field: each
    named once, scalars of their kind (``"f8"``, ``"i8"``, ``"b1"``), arrays (``"f8[:]"``,
    ``"i8[:]"``, ``"f8[:, :]"`` ...) of their dtype and dimensions and C-contiguous (they are
    written in place, never copied), anything else (``"any"``) as given."""
    # the caller's module: numba's cache pickles the record's class by where it is defined
    cls = namedtuple(name, list(spec), module=sys._getframe(1).f_globals["__name__"])
    cls.__doc__ = doc

    def make(**fields):
        missing, unknown = sorted(set(spec) - set(fields)), sorted(set(fields) - set(spec))
        if missing or unknown:
            raise TypeError(f"{name}: missing fields {missing}, unknown fields {unknown}")
        return cls(**{k: _checked(name, k, fields[k], kind) for k, kind in spec.items()})

    cls.make = staticmethod(make)
    return cls


def _checked(record: str, field_name: str, value, kind: str):
    if kind == "any":
        return value
    if kind in _KINDS:
        if isinstance(value, np.ndarray):
            raise TypeError(f"{record}.{field_name}: a scalar ({kind}), got an array")
        return _KINDS[kind](value)
    dtype, ndim = kind[:2], kind.count(":")
    if not isinstance(value, np.ndarray) or value.dtype != np.dtype(dtype) or value.ndim != ndim:
        got = f"{value.dtype}, {value.ndim} dimensions" if isinstance(value, np.ndarray) else type(value).__name__
        raise TypeError(f"{record}.{field_name}: an array of {dtype} in {ndim} dimensions, got {got}")
    if not value.flags.c_contiguous:
        raise TypeError(f"{record}.{field_name}: the array must be C-contiguous")
    return value


@dataclass(frozen=True)
class Params:
    """Base of the parameter records; fields are floats or bools."""

    @classmethod
    def describe(cls) -> list[dict]:
        return describe(cls)

    def values(self) -> dict:
        """``{name: value}`` with floats as ``float`` and flags as ``bool`` (the types the
        compiled step was compiled for)."""
        return {
            f.name: (bool(getattr(self, f.name)) if f.type in (bool, "bool") else float(getattr(self, f.name)))
            for f in fields(self)
        }


def field_offsets(names, typename: str = "Offsets"):
    """``{name: index}`` as a namedtuple instance: the offsets of named values in a float64
    array, read as constants by compiled code (``p[PARAM.beta]``), like a state layout."""
    return namedtuple(typename, list(names))(*range(len(names)))


def params_record(params_cls):
    """The offsets of a parameter record's fields in the float64 array the compiled step reads
    them from by name (``p[PARAM.beta]``, so the order of the fields never matters). Assign it at
    module level (``PARAM = Record = params_record(MyParams)``).

    An array, not a namedtuple, because a streaming call unboxes every argument: a namedtuple
    of 35 floats costs about 0.3 µs a call, an array about 0.04 µs."""
    return field_offsets([f.name for f in fields(params_cls)], "Record")


def pack(values) -> np.ndarray:
    """Floats (flags as 0 / 1) in order, as the float64 array compiled code reads; at least one
    element (an estimator without coefficients gets ``[0.0]``)."""
    a = np.array([float(v) for v in values], dtype=np.float64)
    return a if len(a) else np.zeros(1)


def layout(*slots, start: int = 0):
    """Offsets of the named slots of a state vector, declared once:
    ``layout(("P", 16), ("bias", 3), start=BASE)`` gives ``.P == BASE``, ``.bias == BASE + 16``
    and ``.end`` (one past the last slot: the state size). Compiled code reads the offsets as
    constants (``x[STATE.bias]``)."""
    names, offsets = [], []
    at = start
    for name, size in slots:
        if size < 1:
            raise ValueError(f"slot {name!r}: size must be at least 1, got {size}")
        names.append(name)
        offsets.append(at)
        at += size
    return namedtuple("Layout", names + ["end"])(*offsets, at)
