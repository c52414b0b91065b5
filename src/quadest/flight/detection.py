"""A rotor loss noticed in flight: the detector of :mod:`quadest.detect` in the closed loop.

Each sample, after the estimate and before the controller, the detector reads the gyroscope,
the accelerometer and either the rotor speeds (ESC telemetry: the true speeds with a relative
noise per reading) or the commands sent over the interval just ended. When it finds a rotor
lost, a flight with a fault-tolerant controller switches to it from that sample, giving that
rotor up. ``oracle`` mode keeps the former behaviour, labelled as an oracle: the loss is
known ``detect_delay_s`` after it happens and the lost rotor's command is zeroed from the
failure on (docs/detection.md).
"""

from __future__ import annotations

from quadest._jit import njit
from quadest.detect.effectiveness import detect_step
from quadest.detect.filter import note_commands
from quadest.detect.layout import STAT, STATE, STATISTICS
from quadest.flight.phases import FAULT, FLYING
from quadest.records import compiled_record

DETECTION_MODES = ("oracle", "rotor-speeds", "commands")
"""How a flight learns of a rotor loss: told (an oracle), or found by the detector from the
measured rotor speeds or from the commands."""
ORACLE, ROTOR_SPEEDS, COMMANDS = 0, 1, 2

Detection = compiled_record(
    "Detection",
    "The detector in the loop: its mode (DETECTION_MODES' index), its state, parameter and model "
    "arrays, the rotors' effectiveness it estimates, the speed readings' relative noise per "
    "sample, the reading of the sample, the rotor found lost (sample, rotor; -1 none), the "
    "effectiveness and the tests' statistics (detect.layout.DIAGNOSTICS) per sample.",
    mode="i8",
    x="f8[:]",
    p="f8[:]",
    c="f8[:]",
    diag="f8[:]",
    noise="f8[:, :]",
    reading="f8[:]",
    found="i8[:]",
    eta="f8[:, :]",
    statistics="f8[:, :]",
)


@njit(cache=True, inline="always")
def notice_failure(k, x, loop):
    """The detector's step at sample ``k``; a rotor found lost switches a flight that has a
    fault-tolerant controller to it (``control.fault``)."""
    det = loop.detection
    if det.mode == ORACLE:
        return
    n = det.reading.shape[0]
    for i in range(n):
        if det.mode == ROTOR_SPEEDS:
            det.reading[i] = x[13 + i] * (1.0 + det.noise[k, i])
        else:
            det.reading[i] = loop.control.cmd[i]  # the command over the interval just ended
    if det.mode == ROTOR_SPEEDS:  # the autopilot knows what it commands, the speeds read or not
        note_commands(det.x, det.p, det.c, loop.control.cmd)
    sensing = loop.sensing
    lost = detect_step(det.x, det.p, det.c, sensing.gyr, sensing.acc, det.reading, sensing.dt, det.diag)
    for i in range(n):
        det.eta[k, i] = det.diag[i]
    for j in range(STATISTICS):
        det.statistics[k, j] = det.diag[STAT + j]
    if lost >= 0 and det.found[0] < 0:
        det.found[0], det.found[1] = k, lost
        control = loop.control
        if control.by_phase[FAULT] != control.by_phase[FLYING] and control.fault[0] < 0:
            control.fault[0], control.fault[1] = k, lost


def found_damaged(detection) -> tuple[int, float, float] | None:
    """The rotor the detector found damaged in a flight, the time it did (s from the start of
    the detector) and the effectiveness left; None when none."""
    x = detection.x
    if x[STATE.damaged] < 0:
        return None
    return int(x[STATE.damaged]), float(x[STATE.damaged_t]), float(x[STATE.damaged_eta])
