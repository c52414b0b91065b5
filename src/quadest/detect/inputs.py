"""The detector's inputs checked before its compiled code reads them (which checks nothing: three
speed columns for a four-rotor model would be read past their end): shapes, the rotor count of
the model, and rotor speeds in units that cannot be the ones expected (rpm, or 10⁴ rpm, where
rad/s is expected). Each refusal is one ValueError naming the argument and what to do. The
gyroscope is not judged here: a tumble after a loss turns faster than any rate a unit check
could bound (192 rad/s in a simulated one), and a NaN reading is a bad sample the step skips."""

from __future__ import annotations

import numpy as np

from quadest.conventions import GRAVITY
from quadest.detect.layout import MAX_ROTORS, MODEL

RPM_FACTOR = 3.0
"""Speeds beyond this many times the model's largest (``omega_max``) are not rad/s (rpm are 9.55
times as large)."""
SLOW_FACTOR = 0.1
"""Speeds whose 99th percentile is below this share of the model's hover speed, yet not zero, are
not rad/s either (10⁴ rpm, or normalised commands): the rotors would carry 1 % of the weight."""


def model_rotors(c, who: str) -> int:
    """The rotor count of a packed model ``c`` (:func:`~quadest.detect.model.model_coefficients`)."""
    c = np.asarray(c)
    n = int(c[MODEL.rotors]) if c.ndim == 1 and len(c) == MODEL.end and np.isfinite(c[MODEL.rotors]) else 0
    if not 2 <= n <= MAX_ROTORS or c.dtype != np.float64:
        raise ValueError(
            f"{who}: c is not a detector model (a float64 array of {MODEL.end} from model_coefficients(vehicle)); "
            "build it from the vehicle"
        )
    return n


def state_arrays(who: str, **arrays) -> None:
    """Arrays the compiled code writes into or reads by offset (``x``, ``p``, ``diag``): float64,
    contiguous, of the size given with each (``name=(array, size)``)."""
    for name, (a, size) in arrays.items():
        ok = isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous
        if not ok or a.shape[-1:] != (size,):
            shape = getattr(a, "shape", type(a).__name__)
            raise ValueError(
                f"{who}: {name} must be a contiguous float64 array of {size} per row, got {shape}; "
                "take it from Detector(...).compiled() or RatePredictor(...).compiled()"
            )


def rows(who: str, name: str, a, n: int, width: int | None, hint: str = "") -> np.ndarray:
    """``a`` as a contiguous float64 array of ``n`` rows of ``width`` values (``width`` None: one
    value per row), or a ValueError naming it."""
    try:
        out = np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{who}: {name} is not a numeric array") from None
    shape = (n,) if width is None else (n, width)
    if out.shape != shape:
        raise ValueError(f"{who}: {name} has shape {out.shape}, expected {shape}{hint}")
    return out


def rotor_hint(width, n) -> str:
    return f": one column per rotor of the model ({n} rotors), in the model's order" if width != n else ""


def rotor_speeds(who: str, name: str, rotors: np.ndarray, c, *, run: bool = True) -> None:
    """Refuse rotor speeds (or commanded speeds), rad/s, that cannot be: non-finite or negative,
    beyond ``RPM_FACTOR`` times the model's ``omega_max`` (rpm), or (over a run) far below its hover
    speed (another unit: 10⁴ rpm, or commands normalised to 0..1)."""
    if not np.isfinite(rotors).all():
        i = int(np.flatnonzero(~np.isfinite(rotors).reshape(len(rotors), -1).all(axis=1))[0]) if rotors.ndim > 1 else 0
        raise ValueError(
            f"{who}: {name} has a non-finite value (row {i}): every sample needs each rotor's speed; hold the last "
            "reading over a gap or cut those rows out"
        )
    if (rotors < 0).any():
        raise ValueError(f"{who}: {name} has a negative value: give each rotor's speed as a magnitude (rad/s)")
    if not rotors.size:
        return
    c = np.asarray(c)
    omega_max = float(c[MODEL.omega_max])
    top = float(np.percentile(rotors, 99)) if run and rotors.size > 100 else float(rotors.max())
    if top > RPM_FACTOR * omega_max:
        raise ValueError(
            f"{who}: {name} reach {top:.6g}, more than {RPM_FACTOR:g} times the model's largest speed "
            f"({omega_max:g} rad/s): rpm? give rad/s (rpm times pi/30)"
        )
    hover = float(np.sqrt(c[MODEL.mass] * GRAVITY / (int(c[MODEL.rotors]) * c[MODEL.k_f])))
    if run and 0.0 < top < SLOW_FACTOR * hover:
        raise ValueError(
            f"{who}: {name} stay below {top:.4g}, under {SLOW_FACTOR:.0%} of the model's hover speed ({hover:.0f} "
            "rad/s): not rad/s? (10⁴ rpm, or commands normalised to 0..1: convert them to rad/s)"
        )
