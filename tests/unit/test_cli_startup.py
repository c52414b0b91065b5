"""The command line starts at once: ``--help`` loads none of the library's heavy packages, and the
names its options offer (``quadest.cli.choices``) are the library's own."""

import subprocess
import sys
from types import SimpleNamespace

import pytest

from quadest.cli import choices

HEAVY = ("numpy", "numba", "scipy", "pyarrow", "matplotlib")
"""Packages whose import alone takes a quarter of a second or more."""

SHOW_LOADED = """
import atexit, runpy, sys
atexit.register(lambda: print("loaded:" + ",".join(m for m in {heavy!r} if m in sys.modules), file=sys.stderr))
sys.argv = ["quadest", *{argv!r}]
try:  # the program ends after its exit functions (quadest.cli.main.end): the line is printed by one
    runpy.run_module("quadest.cli.main", run_name="__main__")
except SystemExit:
    pass
"""


def _heavy_loaded(argv: list) -> list:
    """The heavy packages ``quadest ARGV`` has imported when it ends."""
    code = SHOW_LOADED.format(argv=argv, heavy=HEAVY)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "usage: quadest" in out.stdout, out.stderr
    return _loaded(out.stderr)


def _loaded(stderr: str) -> list:
    return [m for m in stderr.strip().splitlines()[-1].removeprefix("loaded:").split(",") if m]


def _commands() -> list:
    from quadest.cli.main import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    return sorted(sub.choices)


def test_quadest_help_loads_no_heavy_package():
    """``quadest --help`` (what ``quadest`` runs) imports neither numpy nor the compiler, scipy,
    pyarrow or matplotlib."""
    assert _heavy_loaded(["--help"]) == []


@pytest.mark.parametrize("command", _commands())
def test_every_command_help_loads_no_heavy_package(command):
    assert _heavy_loaded([command, "--help"]) == []


def test_the_help_test_sees_a_heavy_import():
    """The check above is not vacuous: a command that runs (not ``--help``) loads numpy."""
    code = SHOW_LOADED.format(argv=["data", "list"], heavy=HEAVY).replace('"usage: quadest"', "")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert "numpy" in _loaded(out.stderr)


def _library_choices() -> dict:
    """Each name of :mod:`quadest.cli.choices` as the library defines it."""
    import inspect

    from quadest.calibration.identify import identify
    from quadest.evaluation.diagnose import DiagnoseParams
    from quadest.filters import ESTIMATORS, FILTERS, PEERS
    from quadest.flight import CONTROLLERS, FLIGHT_SCENARIOS
    from quadest.flight.common import COLLISIONS
    from quadest.flight.detection import DETECTION_MODES
    from quadest.models import VEHICLE_PRESETS
    from quadest.models.truth import TRUTH_SPREADS
    from quadest.readers import FORMATS
    from quadest.readers.logs import IMU_SOURCES
    from quadest.recovery import RecoveryParams
    from quadest.recovery.divergence import CHECKS
    from quadest.sim import FAILURE_MODES, PRESCRIBED_SCENARIOS, PRESETS
    from quadest.sweep.campaign import DETECTIONS
    from quadest.sweep.campaign import FAILURE_MODES as CAMPAIGN_FAILURE_MODES

    recovery = RecoveryParams()
    return {
        "ESTIMATORS": {n: choices.Kind(c.peer, c.streaming, c.acausal) for n, c in ESTIMATORS.items()},
        "FILTERS": tuple(FILTERS),
        "PEERS": tuple(PEERS),
        "FORMATS": tuple(FORMATS),
        "IMU_SOURCES": tuple(IMU_SOURCES),
        "PRESETS": tuple(PRESETS),
        "PRESCRIBED_SCENARIOS": tuple(PRESCRIBED_SCENARIOS),
        "FLIGHT_SCENARIOS": tuple(FLIGHT_SCENARIOS),
        "CONTROLLERS": tuple(CONTROLLERS),
        "VEHICLE_PRESETS": tuple(VEHICLE_PRESETS),
        "DETECTION_MODES": tuple(DETECTION_MODES),
        "FAILURE_MODES": tuple(FAILURE_MODES),
        "COLLISIONS": tuple(COLLISIONS),
        "CHECKS": tuple(CHECKS),
        "DETECTIONS": tuple(DETECTIONS),
        "CAMPAIGN_FAILURE_MODES": tuple(CAMPAIGN_FAILURE_MODES),
        "TRUTH_SPREADS": tuple(TRUTH_SPREADS),
        "RECOVERY_DEFAULTS": SimpleNamespace(
            n_hypotheses=recovery.n_hypotheses, beta1=recovery.beta1, beta2=recovery.beta2
        ),
        "DIAGNOSE_DEFAULTS": SimpleNamespace(
            moment_gain=DiagnoseParams.moment_gain, excess_threshold=DiagnoseParams.excess_threshold
        ),
        "IDENTIFY_DEFAULTS": SimpleNamespace(
            **{k: inspect.signature(identify).parameters[k].default for k in ("mass_kg", "arm_m")}
        ),
    }


@pytest.mark.parametrize("name", sorted(_library_choices()))
def test_the_command_line_offers_the_library_names(name):
    """A new estimator, preset, scenario or default in the library is offered by the command line
    too: the message is the line to write in src/quadest/cli/choices.py."""
    library = _library_choices()[name]
    assert getattr(choices, name) == library, f"src/quadest/cli/choices.py: {name} = {library!r}"


def test_filter_name_is_the_library_s():
    """The argparse type notes a former name and gives the current one, as the library does."""
    with pytest.warns(FutureWarning, match="now called 'valenti'"):
        assert choices.filter_name("complementary") == "valenti"
    assert choices.filter_name("robust") == "robust"
