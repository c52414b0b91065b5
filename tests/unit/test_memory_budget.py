"""A simulation's memory is bounded before it runs: a duration past the budget, and parameters
whose work grows without a bound, are refused in one line (docs/reliability.md, *Bounded*)."""

import subprocess
import sys

import pytest

from quadest.sim import build_config, simulate
from quadest.sim.simulator import BYTES_PER_SAMPLE, MAX_SAMPLES, MEMORY_BUDGET_BYTES


def test_a_simulation_past_the_budget_is_refused_before_it_runs():
    duration = 1.01 * MAX_SAMPLES / 500.0  # bebop2's IMU at 500 Hz
    with pytest.raises(ValueError, match=r"GiB in memory, past one simulation's budget of 4 GiB") as exc:
        simulate("hover", "bebop2", duration=duration)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize(
    ("key", "value", "said"),
    [("hover.components", 1_000_000, "at most 100 sinusoids"), ("mag.latency_s", 2e5, "at most 10 s")],
)
def test_parameters_whose_work_grows_are_bounded(key, value, said):
    with pytest.raises(ValueError, match=said):
        build_config("bebop2", {key: value}).validate()


def _peak_rss_bytes(duration: float) -> int:
    """The peak resident memory of a process while it simulates ``duration`` s of hover, once a
    first short simulation has compiled (or loaded) the simulator: Linux's high-water mark is
    reset between the two (``/proc/self/clear_refs``), so compiling's own peak is not counted."""
    code = (
        "import gc\nfrom quadest.sim import simulate\n"
        "simulate('hover', 'bebop2', seed=1, duration=2.0)\ngc.collect()\n"
        "open('/proc/self/clear_refs', 'w').write('5')\n"
        f"simulate('hover', 'bebop2', seed=1, duration={duration})\n"
        "print(next(line for line in open('/proc/self/status') if line.startswith('VmHWM')).split()[1])"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr
    return int(r.stdout.split()[-1]) * 1024  # VmHWM in kB


def test_the_stated_bytes_per_sample_hold():
    """The budget's arithmetic: a simulation's peak memory grows by less than
    BYTES_PER_SAMPLE per IMU sample (measured from a 20 s and a 200 s hover at 500 Hz)."""
    grown = _peak_rss_bytes(200.0) - _peak_rss_bytes(20.0)
    per_sample = grown / (180.0 * 500.0)
    assert 0 < per_sample < BYTES_PER_SAMPLE, per_sample
    assert MAX_SAMPLES * BYTES_PER_SAMPLE == pytest.approx(MEMORY_BUDGET_BYTES)
