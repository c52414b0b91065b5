"""Parameter records: frozen dataclasses whose every field states its unit, meaning and where
its value comes from (a publication, or "chosen" and why). The estimators', the recovery's and
the simulator's parameters are all declared with :func:`param`."""

from __future__ import annotations

import math
from dataclasses import field, fields

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
