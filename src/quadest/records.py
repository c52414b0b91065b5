"""Parameter records: frozen dataclasses whose every field states its unit, meaning and where
its value comes from (a publication, or "chosen" and why). The estimators', the recovery's and
the simulator's parameters are all declared with :func:`param`."""

from __future__ import annotations

import json
import math
import sys
from collections import namedtuple
from dataclasses import dataclass, field, fields, replace

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


def _declared(f) -> str:
    """A field's declared type as written (``"float"``, ``"int | None"``), with or without
    postponed annotations."""
    return f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))


def _got(v) -> str:
    """A value for a message: strings said to be strings, a huge integer by its size."""
    if isinstance(v, (str, bytes)):
        return f"the string {v!r}"[:80]
    shown = repr(v)
    if len(shown) <= 40:
        return shown
    return f"a number of {len(shown)} digits" if isinstance(v, int) else shown[:40] + "..."


def number(value, name: str, kind: str = "float", bounds: str | None = None):
    """``value`` as a plain Python number of ``kind`` (``"float"``, ``"int"`` or ``"bool"``), or
    :class:`UsageError` naming ``name`` and its ``bounds``. The one converter every parameter goes
    through, whatever its type: Python and numpy numbers are taken; strings, bools for numbers,
    NaN, infinities, numbers beyond a float (``10**400``), fractions for an ``int`` and anything
    else are refused, and so is a value outside ``bounds`` (an interval, :func:`param`)."""
    within = f" in {bounds}" if bounds else ""
    if kind == "bool":
        if isinstance(value, (bool, np.bool_)) or (_is_number(value) and value in (0, 1)):
            return bool(value)
        raise UsageError(f"{name} must be true or false (a bool), got {_got(value)}")
    if not _is_number(value):
        raise UsageError(f"{name} must be a finite number{within}, got {_got(value)}")
    try:
        v = float(value)
    except OverflowError:
        v = math.inf
    if not math.isfinite(v):
        raise UsageError(f"{name} must be a finite number{within}, got {_got(value)}")
    if kind == "int":
        if v != int(v):
            raise UsageError(f"{name} must be a whole number{within}, got {_got(value)}")
        v = int(value)
    if bounds:
        lo, hi, lo_open, hi_open = _interval(bounds)
        if (v < lo or (lo_open and v == lo)) or (v > hi or (hi_open and v == hi)):
            raise UsageError(f"{name} must be in {bounds}, got {_got(value)}")
    return v


def _is_number(value) -> bool:
    """A real number (Python's or numpy's), not a bool."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


_NUMERIC = {"float": "float", "float | None": "float", "int": "int", "int | None": "int", "bool": "bool"}


def check(record, owner: str = "") -> None:
    """Raise :class:`UsageError` naming the parameter and its bounds when a field declared a
    number (``float``, ``int``, ``bool``) does not hold one (:func:`number`), and make every such
    field a plain Python number (a ``numpy.float32`` becomes a ``float``, as JSON and the compiled
    code take it). ``None`` is taken where the type allows it."""
    who = f"{owner}: " if owner else ""
    for f in fields(record):
        declared = _declared(f)
        kind = _NUMERIC.get(declared)
        v = getattr(record, f.name)
        if kind is None or (v is None and declared.endswith("| None")):
            continue
        plain = number(v, f"{who}{f.name}", kind, f.metadata.get("bounds"))
        if type(v) is not type(plain):
            object.__setattr__(record, f.name, plain)


def describe(record_cls) -> list[dict]:
    """``[{name, default, unit, doc, source}]`` of a parameter record's fields, in order."""
    return [{"name": f.name, "default": f.default, **f.metadata} for f in fields(record_cls)]


def parse_text(text: str):
    """A value written on the command line: a number, ``true``/``false``, a list (``[0, 0, 0.01]``,
    nested lists for matrices; lists become tuples), ``inf`` or ``none``; anything else is the
    text itself (a word such as ``gnss``)."""
    word = text.strip()
    if word.lower() in ("inf", "+inf", "infinity"):
        return math.inf
    if word.lower() in ("none", "null"):
        return None
    try:
        value = json.loads(word.replace("(", "[").replace(")", "]"))
    except json.JSONDecodeError:
        return word
    return _as_tuples(value)


def _as_tuples(value):
    return tuple(_as_tuples(v) for v in value) if isinstance(value, list) else value


def with_fields(record, texts: dict, owner: str, source: str = "--set"):
    """``record`` with the fields named in ``texts`` (``{"mass_kg": "0.6"}``) set to the values
    written there (:func:`parse_text`), checked as the record checks itself (its bounds). A
    :class:`UsageError` names ``source``, the field and what to do: an unknown field lists the
    record's fields, a list given for a number or a number for a list is refused."""
    names = [f.name for f in fields(record)]
    changes = {}
    for name, text in texts.items():
        if name not in names:
            raise UsageError(f"{source}: {owner} has no parameter {name!r}; it has: {', '.join(names)}")
        changes[name] = _typed(f"{source} {owner}.{name}", getattr(record, name), parse_text(text))
    try:
        return replace(record, **changes)
    except (ValueError, TypeError) as exc:
        raise UsageError(f"{source}: {exc}") from None


def _typed(key: str, current, value):
    """``value`` where the field holds ``current``: a list for a list, a word for a word (numbers
    are checked by the record; a field that is None takes any)."""
    if current is None:
        return value
    if isinstance(current, tuple) and not isinstance(value, tuple):
        raise UsageError(f"{key}: expected a list such as [1, 2, 3], got {value!r}")
    if isinstance(current, str) and not isinstance(value, str):
        raise UsageError(f"{key}: expected a word, got {value!r}")
    if not isinstance(current, (tuple, str)) and isinstance(value, tuple):
        raise UsageError(f"{key}: expected a single value, got the list {value!r}")
    return value


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
