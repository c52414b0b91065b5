"""The controllers the closed loop can fly, by name, and the one compiled function that runs
the one chosen by value. Adding a controller: its own module (a compiled ``*_command`` writing
rotor speeds into ``cmd``), an entry in :data:`CONTROLLERS`, a branch in :func:`command`, and,
if it needs gains or state, a field of :data:`Control` (docs/developing.md shows it). Nothing
else changes: ``fly(controller=...)`` and the command line take the new name from here."""

from __future__ import annotations

from dataclasses import dataclass

from quadest._jit import njit
from quadest.control.ftc import ftc_command
from quadest.control.se3 import se3_command
from quadest.control.upright import recovery_command
from quadest.errors import UsageError
from quadest.records import compiled_record

IDLE, SE3, FTC, RECOVERY = 0, 1, 2, 3


@dataclass(frozen=True)
class Controller:
    """A controller of the registry: its value in compiled code, what it does, and, for one a
    user may fly by name, the controller of each flight phase it flies (``flying``, and
    ``fault`` once a rotor loss is known); the others are a throw's (its idle rotors, its
    recovery), selected by the throw's phases."""

    id: int
    doc: str
    phases: tuple[tuple[str, str], ...] = ()

    @property
    def selectable(self) -> bool:
        return bool(self.phases)


CONTROLLERS = {
    "se3": Controller(SE3, "geometric tracking on SE(3) (Lee, Leok & McClamroch 2010)", (("flying", "se3"),)),
    "ftc": Controller(
        FTC,
        "SE(3), then the fault-tolerant controller once a complete rotor loss is known",
        (("flying", "se3"), ("fault", "ftc")),
    ),
    "idle": Controller(IDLE, "the rotors keep their speed (a throw, until the recovery hands over)"),
    "recovery": Controller(RECOVERY, "upright from any attitude, then SE(3) holds velocity and height"),
}


def controller_id(name: str) -> int:
    """The compiled value of the controller ``name``; a one-line error for an unknown one."""
    if name not in CONTROLLERS:
        raise UsageError(f"unknown controller {name!r}; controllers: {', '.join(CONTROLLERS)}")
    return CONTROLLERS[name].id


Control = compiled_record(
    "Control",
    "What the controllers read and carry: the controller of each flight phase, the SE(3) and "
    "fault-tolerant gains (one set for each rotor that may be lost), the reference per sample, "
    "the fault (the sample from which the fault-tolerant controller flies, -1: never; the rotor "
    "it gives up), the recovery's thresholds, and the sample from which the SE(3) controller's "
    "thrust keeps within an autopilot's limits (se3.limited_thrust; -1: never).",
    by_phase="i8[:]",
    gains="any",
    ftc="any",
    p_d="f8[:, :]",
    v_d="f8[:, :]",
    a_d="f8[:, :]",
    yaw_d="f8[:]",
    fault="i8[:]",
    integral="f8[:]",
    cmd="f8[:]",
    beta3="f8",
    upright_rad="f8",
    limited_k="i8",
)


@njit(cache=True, inline="always")
def command(kind, k, xh, control, vehicle, dt):
    """Run controller ``kind`` (a value of :data:`CONTROLLERS`) at sample ``k`` on the estimated
    state ``xh`` into ``control.cmd``; returns whether the attitude control error allows the
    accelerometer update (always, but for the recovery: :func:`recovery_command`)."""
    if kind == SE3:
        limited = 0 <= control.limited_k <= k
        se3_command(
            xh, control.p_d[k], control.v_d[k], control.a_d[k], control.yaw_d[k], control.gains, vehicle, control.cmd,
            limited,
        )  # fmt: skip
    elif kind == FTC:
        ftc_command(
            xh,
            control.p_d[k],
            control.v_d[k],
            control.a_d[k],
            control.ftc[control.fault[1]],
            vehicle,
            dt,
            control.integral,
            control.cmd,
        )
    elif kind == RECOVERY:
        return recovery_command(
            xh,
            control.p_d[k],
            control.v_d[k],
            control.a_d[k],
            control.yaw_d[k],
            control.gains,
            vehicle,
            control.beta3,
            control.upright_rad,
            control.cmd,
        )
    return True
