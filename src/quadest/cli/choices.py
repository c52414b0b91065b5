"""The names and defaults the command line's options offer, known without loading the library.

``quadest --help`` and every command's ``--help`` build their parsers from these, so that asking
for help loads neither numpy nor the compiler (a command imports the library when it runs).
Each is the library's own list or default, written out: ``tests/unit/test_cli_choices.py`` holds
every one to the library and, when one differs (a new estimator, preset or scenario), prints the
line to write here.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple


class Kind(NamedTuple):
    """What the parsers need to know of a registered estimator (``quadest.filters.ESTIMATORS``)."""

    peer: bool
    streaming: bool
    acausal: bool


_OWN, _OFFLINE = Kind(False, True, False), Kind(False, False, True)
_PEER, _PEER_BATCH, _PEER_OFFLINE = Kind(True, True, False), Kind(True, False, False), Kind(True, False, True)

ESTIMATORS = {
    "robust": _OWN,
    "robust-offline": _OFFLINE,
    "afckf": _OWN,
    "qukf": _OWN,
    "ekf": _OWN,
    "madgwick": _OWN,
    "mahony": _OWN,
    "valenti": _OWN,
    "roetenberg": _OWN,
    "vqf": _PEER,
    "vqf-offline": _PEER_OFFLINE,
    "imufusion": _PEER,
    "ahrs-madgwick": _PEER_BATCH,
    "ahrs-mahony": _PEER_BATCH,
    "ahrs-ekf": _PEER_BATCH,
    "ahrs-aqua": _PEER_BATCH,
}
"""``quadest.filters.ESTIMATORS``: each registered name and its kind."""
FILTERS = tuple(name for name, kind in ESTIMATORS.items() if not kind.peer)
"""``quadest.filters.FILTERS``' names: quadest's own estimators."""
PEERS = tuple(name for name, kind in ESTIMATORS.items() if kind.peer)
"""``quadest.filters.PEERS``' names: other packages' estimators."""

FORMATS = ("quadest", "csv", "ulog", "dataflash", "rosbag", "broad", "dido", "blackbird", "repoimu", "asl")
"""``quadest.readers.FORMATS``: the readers."""
IMU_SOURCES = ("logged", "fifo")
"""``quadest.readers.logs.IMU_SOURCES``: an autopilot log's IMU streams."""

PRESETS = ("bebop2", "lowcost-20hz", "fma")
"""``quadest.sim.PRESETS``' names: the simulator's sensor presets."""
PRESCRIBED_SCENARIOS = ("hover", "nominal", "damaged-rotor", "throw", "rest", "six-position", "figure-eight")
"""``quadest.sim.PRESCRIBED_SCENARIOS``: the simulator's prescribed motions."""

FLIGHT_SCENARIOS = ("hover", "trajectory", "aggressive", "rotor-loss", "throw")
"""``quadest.flight.FLIGHT_SCENARIOS``: the flights of the vehicle model."""
CONTROLLERS = ("se3", "ftc")
"""``quadest.flight.CONTROLLERS``: the controllers a user may fly by name."""
VEHICLE_PRESETS = ("recovery", "bebop2", "hummingbird")
"""``quadest.models.VEHICLE_PRESETS``' names: the vehicle models."""
DETECTION_MODES = ("oracle", "rotor-speeds", "commands")
"""``quadest.flight.detection.DETECTION_MODES``: how a rotor loss is learnt in flight."""
FAILURE_MODES = ("propeller-off", "motor-stop", "desync", "gradual", "partial", "damaged-propeller")
"""``quadest.sim.FAILURE_MODES``: how a rotor fails."""
COLLISIONS = ("none", "drawn", "reset", "left")
"""``quadest.flight.common.COLLISIONS``: a collision in flight."""
CHECKS = ("impact", "rate", "innovation", "nonfinite")
"""``quadest.recovery.divergence.CHECKS``' names: the checks that start a recovery in flight."""
DETECTIONS = ("rotor-speeds", "commands", "oracle")
"""``quadest.sweep.campaign.DETECTIONS``: a campaign's detection modes."""
CAMPAIGN_FAILURE_MODES = ("propeller-off", "motor-stop")
"""``quadest.sweep.campaign.FAILURE_MODES``: how a campaign's complete losses happen."""
TRUTH_SPREADS = ("none", "default")
"""``quadest.models.truth.TRUTH_SPREADS``: the spreads a truth apart from the model is drawn from."""

RECOVERY_DEFAULTS = SimpleNamespace(n_hypotheses=40, beta1=7.0, beta2=0.06)
"""``quadest.recovery.RecoveryParams``' defaults that ``quadest recover`` offers as options."""
DIAGNOSE_DEFAULTS = SimpleNamespace(moment_gain=10.0, excess_threshold=0.15)
"""``quadest.evaluation.diagnose.DiagnoseParams``' defaults that ``quadest diagnose`` offers."""
IDENTIFY_DEFAULTS = SimpleNamespace(mass_kg=1.0, arm_m=1.0)
"""``quadest.calibration.identify.identify``'s reference mass (kg) and arm (m) that ``quadest identify`` offers."""


def filter_name(name: str) -> str:
    """An argparse type: ``quadest.filters.filter_name`` (a former name noted and replaced),
    loaded when the option is parsed."""
    from quadest import filters

    return filters.filter_name(name)
