"""The first compile of a process is said in one line on stderr, whether a terminal or a log, and
only when numba's cache does not hold the code already (quadest._jit.say_compiling)."""

import os
import subprocess
import sys

from quadest._jit import COMPILING

ESTIMATE = """
import numpy as np, quadest
n = 200
gyr = np.zeros((n, 3)); acc = np.tile([0.0, 0.0, -9.81], (n, 1))
quadest.estimate(gyr, acc, rate=100.0, check=False)
quadest.estimate(gyr, acc, rate=100.0, method="madgwick", check=False)
print("done")
"""


def _said(cache_dir) -> list:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "QUADEST_NUMBA_"))}
    env["NUMBA_CACHE_DIR"] = str(cache_dir)
    out = subprocess.run([sys.executable, "-c", ESTIMATE], env=env, capture_output=True, text=True, timeout=1200)
    assert out.returncode == 0 and "done" in out.stdout, out.stderr[-2000:]
    return [line for line in out.stderr.splitlines() if line.startswith(COMPILING)]


def test_the_first_compile_is_said_once_and_a_cached_run_says_nothing(tmp_path):
    first = _said(tmp_path)
    assert len(first) == 1 and "the robust estimator" in first[0] and "about 20 s" in first[0], first
    assert _said(tmp_path) == []  # everything now comes from the cache
