"""Rotor failures as profiles: what a rotor delivers and how its motor behaves over time
(docs/simulator.md, *Failure modes*).

A :class:`Failure` is one record: a mode (:data:`FAILURE_MODES`), the rotor, the time it
starts and the mode's few numbers. Everything else asks the record: the flight's plant samples
it (:func:`Failure.profile`: per rotor and sample, the thrust and torque share ``eta``, the
motor's drive and the propeller's imbalance), whether it is a complete loss
(:attr:`Failure.complete`), when the rotor is lost (:attr:`Failure.lost_s`), and how it is
written out and read back (:meth:`Failure.to_dict`, :meth:`Failure.from_dict`,
:meth:`Failure.parse`, ``str``).

The motor's drive multiplies the speed its ESC aims for: 1 follows the command, 0 is an ESC
that has stopped driving it (the rotor spins down at the vehicle's motor dynamics; its
propeller, still on, pushes as it slows and its momentum turns the body about z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from quadest.errors import UsageError
from quadest.models.multirotor import MultirotorParams

FAILURE_MODES = ("propeller-off", "motor-stop", "desync", "gradual", "partial", "damaged-propeller")
"""How a rotor fails: its propeller comes off (no thrust or torque, the motor spins on at its
command), its motor stops (spins down to rest), its ESC loses sync now and then (the motor
unpowered for ``off_s`` of every ``period_s``), its thrust fades to ``efficiency`` over
``ramp_s``, it drops to ``efficiency`` at once, or its propeller is damaged (``efficiency`` and
an ``imbalance`` that shakes the sensors once per revolution)."""

MAX_IMBALANCE = 1e-3
"""The largest propeller imbalance a failure may have (kg m): 1 g at 1 m, far beyond any
propeller's; what a user meaning grams by millimetres (5 rather than 5e-6) would give."""

_EXTRA = {"gradual": ("ramp_s",), "desync": ("off_s", "period_s")}
"""The numbers a mode has besides rotor, time, efficiency and imbalance."""

FAILURE_FORMAT = (
    "[MODE:]ROTOR@TIME[:EFFICIENCY[:IMBALANCE]][,KEY=VALUE...], MODE one of "
    + ", ".join(FAILURE_MODES)
    + " (for example 0@2, 1@3:0.6, 2@1:0.9:5e-6, motor-stop:0@2, gradual:0@2:0.7,ramp_s=3, desync:3@2,off_s=0.05)"
)


@dataclass(frozen=True)
class Failure:
    """A failure of rotor ``rotor`` (0-based, the vehicle's order) from ``time_s`` on.

    Parameters
    ----------
    rotor : int
        The rotor that fails.
    time_s : float
        When the failure starts, s from the start of the flight.
    efficiency : float
        The share of its thrust and torque the rotor delivers once the failure is complete
        (0: none). ``propeller-off`` and ``motor-stop`` deliver none; ``desync`` full thrust
        between its stutters.
    imbalance : float
        A damaged propeller's imbalance, kg m (the missing mass times its radius: 5e-6 is a
        0.1 g chip at 5 cm), whose once-per-revolution force shakes the sensors.
    mode : str or None
        One of :data:`FAILURE_MODES`; None infers it from the numbers as the first failures
        were given: an imbalance is ``damaged-propeller``, efficiency 0 ``propeller-off``,
        else ``partial``.
    ramp_s : float
        ``gradual``: seconds over which the thrust fades linearly to ``efficiency``.
    off_s, period_s : float
        ``desync``: the motor is unpowered for ``off_s`` at the start of every ``period_s``.
    """

    rotor: int
    time_s: float
    efficiency: float = 0.0
    imbalance: float = 0.0
    mode: str | None = None
    ramp_s: float = 3.0
    off_s: float = 0.05
    period_s: float = 0.5

    def __post_init__(self):
        if self.mode is None:  # frozen: set once, here
            object.__setattr__(self, "mode", self._implied_mode())

    def _implied_mode(self) -> str:
        """The mode the numbers alone imply (as failures were given before the modes)."""
        if self.imbalance:
            return "damaged-propeller"
        return "propeller-off" if self.efficiency == 0.0 else "partial"

    @property
    def complete(self) -> bool:
        """Whether the rotor ends with no thrust or torque: the one place a complete loss is decided."""
        return self.mode == "motor-stop" or (self.mode != "desync" and self.efficiency == 0.0)

    @property
    def lost_s(self) -> float:
        """When the failure is complete (s): at its start, or at the end of a gradual fade."""
        return self.time_s + (self.ramp_s if self.mode == "gradual" else 0.0)

    def check(self, vehicle: MultirotorParams, duration_s: float) -> None:
        """Refuse, in one line, a failure the vehicle and a run of ``duration_s`` cannot have."""
        if self.mode not in FAILURE_MODES:
            raise UsageError(f"failure: unknown mode {self.mode!r}; modes: {', '.join(FAILURE_MODES)}")
        if not 0 <= self.rotor < vehicle.rotors:
            raise UsageError(
                f"failure: rotor {self.rotor} does not exist (the vehicle has rotors 0 to {vehicle.rotors - 1})"
            )
        if not 0.0 <= self.time_s < duration_s:
            raise UsageError(f"failure: time {self.time_s} s lies outside the run (0 to {duration_s:g} s)")
        if not (math.isfinite(self.imbalance) and 0.0 <= self.imbalance <= MAX_IMBALANCE):
            raise UsageError(f"failure: imbalance must be between 0 and {MAX_IMBALANCE:g} kg m, got {self.imbalance}")
        self._check_mode()

    def _check_mode(self) -> None:
        """The numbers each mode may have."""
        m, e = self.mode, self.efficiency
        if m in ("propeller-off", "motor-stop", "desync") and (e != 0.0 or self.imbalance):
            raise UsageError(f"failure: {m} has no efficiency or imbalance to give (got {e:g}, {self.imbalance:g})")
        if m in ("partial", "gradual") and not 0.0 <= e < 1.0:
            raise UsageError(f"failure: {m} needs an efficiency in [0, 1), got {e}")
        if m == "damaged-propeller" and not (0.0 <= e <= 1.0 and self.imbalance > 0.0):
            raise UsageError(
                f"failure: a damaged propeller needs an efficiency in [0, 1] and an imbalance > 0 kg m, got {e}, "
                f"{self.imbalance}"
            )
        if m == "gradual" and not (math.isfinite(self.ramp_s) and 0.0 < self.ramp_s <= 600.0):
            raise UsageError(f"failure: ramp_s must be in (0, 600] s, got {self.ramp_s}")
        if m == "desync" and not (0.0 < self.off_s < self.period_s <= 60.0):
            raise UsageError(f"failure: desync needs 0 < off_s < period_s <= 60 s, got {self.off_s}, {self.period_s}")

    def profile(self, rate_hz: float, n: int, rotors: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """The failure sampled at ``rate_hz`` over a flight of ``n`` samples: its first sample
        ``k0`` and, from ``k0`` on, one row per sample of every rotor's ``eta`` (thrust and torque
        share), ``drive`` (the motor's, 0-1) and ``imbalance`` (kg m), until the profile stops
        changing (its last row holds from there on; at least one row)."""
        k0 = int(round(self.time_s * rate_hz))
        t = np.arange(self._rows(rate_hz, n - k0)) / rate_hz  # s since the failure started
        eta, drive, imb = (np.tile(v, (len(t), rotors)) for v in (1.0, 1.0, 0.0))
        eta[:, self.rotor] = self._eta(t)
        drive[:, self.rotor] = self._drive(t)
        imb[:, self.rotor] = self.imbalance
        return k0, eta, drive, imb

    def _rows(self, rate_hz: float, left: int) -> int:
        """How many samples the profile changes over (at least one, at most ``left``)."""
        if self.mode == "gradual":
            return max(1, min(left, int(math.ceil(self.ramp_s * rate_hz)) + 1))
        return max(1, left) if self.mode == "desync" else 1

    def _eta(self, t: np.ndarray) -> np.ndarray:
        """The failed rotor's thrust and torque share ``t`` s after the failure started."""
        if self.mode == "motor-stop" or self.mode == "desync":
            return np.ones_like(t)  # the propeller is on: it pushes at whatever speed it turns
        if self.mode == "gradual":
            return 1.0 + (self.efficiency - 1.0) * np.minimum(t / self.ramp_s, 1.0)
        return np.full_like(t, self.efficiency)

    def _drive(self, t: np.ndarray) -> np.ndarray:
        """The failed rotor's motor drive ``t`` s after the failure started."""
        if self.mode == "motor-stop":
            return np.zeros_like(t)
        if self.mode == "desync":
            return (np.mod(t + 1e-12, self.period_s) >= self.off_s).astype(float)
        return np.ones_like(t)

    def to_dict(self) -> dict:
        """The failure as a results file keeps it: rotor, time and efficiency, then only what
        differs from what those imply (so that files written before the modes keep their keys)."""
        out = {"rotor": self.rotor, "time_s": self.time_s, "efficiency": self.efficiency}
        if self.imbalance:
            out["imbalance"] = self.imbalance
        if self.mode != self._implied_mode():
            out["mode"] = self.mode
        out.update({k: getattr(self, k) for k in _EXTRA.get(self.mode, ())})
        return out

    @classmethod
    def from_dict(cls, d: dict) -> Failure:
        """The failure :meth:`to_dict` wrote (an unknown key is a one-line error)."""
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise UsageError(f"failure: unknown field(s) {', '.join(sorted(unknown))}; fields: {', '.join(known)}")
        return cls(**d)

    @classmethod
    def parse(cls, text: str) -> Failure:
        """``[MODE:]ROTOR@TIME[:EFFICIENCY[:IMBALANCE]][,KEY=VALUE...]`` (:data:`FAILURE_FORMAT`)."""
        head, *pairs = text.split(",")
        mode, sep, rest = head.partition(":")
        if not sep or mode not in FAILURE_MODES:
            mode, rest = None, head
        rotor, at, when = rest.partition("@")
        parts = when.split(":")
        try:
            if not at or len(parts) > 3:
                raise ValueError
            kw = dict(pair.split("=", 1) for pair in pairs)
            if not set(kw) <= {"efficiency", "imbalance", *_EXTRA.get(mode, ())}:
                raise ValueError
            numbers = dict(zip(("efficiency", "imbalance"), map(float, parts[1:])))
            numbers.update({k: float(v) for k, v in kw.items()})
            return cls(int(rotor), float(parts[0]), mode=mode, **numbers)
        except (ValueError, TypeError):
            raise UsageError(f"--failure expects {FAILURE_FORMAT}, got {text!r}") from None

    def __str__(self) -> str:
        """The failure in the form :meth:`parse` reads."""
        d = self.to_dict()
        text = f"{self.mode}:{self.rotor}@{self.time_s:g}"
        if self.efficiency or self.imbalance:
            text += f":{self.efficiency:g}" + (f":{self.imbalance:g}" if self.imbalance else "")
        return text + "".join(f",{k}={d[k]:g}" for k in _EXTRA.get(self.mode, ()))
