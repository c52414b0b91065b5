"""The package as a user installs it (`make wheel-check`, run by CI): build the sdist and the
wheel, install the wheel into a new virtual environment without extras, check what came with it
and that the library and the command line work; then add the [logs] extra and read a ULog in its
own time with its declination. Prints each step; exits 1 at the first that fails."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NOT_IN_CORE = ("dask", "distributed", "bokeh", "pymavlink", "rosbags", "h5py", "matplotlib", "pooch", "pyulog")

SMOKE = """
import importlib.util, sys
import numpy as np
import quadest
assert "site-packages" in quadest.__file__, quadest.__file__
present = [m for m in sys.argv[1].split(",") if importlib.util.find_spec(m)]
assert not present, f"installed without extras, yet present: {present}"
rng = np.random.default_rng(0)
n = 2000
gyr = 0.01 * rng.standard_normal((n, 3))
acc = np.array([0.0, 0.0, -9.81]) + 0.05 * rng.standard_normal((n, 3))
est = quadest.estimate(gyr, acc, rate=200.0)
assert est.q.shape == (n, 4) and abs(est.t[-1] - (n - 1) / 200.0) < 1e-12
assert np.degrees(np.abs(est.euler[-1, :2])).max() < 1.0, est.euler[-1]
print("  estimate on arrays given only rate=: ok; C streaming:", quadest.filters.base.STREAM_C)
from pathlib import Path
assert (Path(quadest.__file__).parent / "py.typed").is_file(), "py.typed (PEP 561) is not in the installed wheel"
print("  py.typed in the installed package: ok")
"""

LOGS = """
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from logwriters import write_ulog
import quadest
from quadest.sim import simulate
flight = simulate("nominal", "bebop2", seed=1, duration=3.0)
write_ulog("flight.ulg", flight, params={"EKF2_MAG_DECL": 10.5}, t0_us=20_330_000)
rec = quadest.read("flight.ulg")
assert abs(rec.t[0] - 20.33) < 1e-9, rec.t[0]
assert abs(np.degrees(rec.declination) - 10.5) < 1e-5, rec.declination
est = quadest.estimate(rec)
assert est.t[0] == rec.t[0]
print("  [logs]: a ULog read from t = 20.33 s with its declination (EKF2_MAG_DECL 10.5 deg): ok")
"""


def run(cmd, cwd=None, **kw) -> subprocess.CompletedProcess:
    out = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, **kw)
    if out.returncode != 0:
        sys.exit(f"failed: {' '.join(map(str, cmd))}\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}")
    return out


def build(dist: Path) -> Path:
    print("==> building the sdist and, from it, the wheel (python -m build)")
    run([sys.executable, "-m", "build", "--outdir", str(dist), str(ROOT)])
    (wheel,) = dist.glob("quadest-*.whl")
    (sdist,) = dist.glob("quadest-*.tar.gz")
    print(f"  {sdist.name}, {wheel.name}")
    return wheel


def check_core(env: Path, wheel: Path, work: Path) -> Path:
    print("==> a new virtual environment; the wheel without extras")
    venv.create(env, with_pip=True)
    py = env / "bin" / "python"
    run([py, "-m", "pip", "install", "--quiet", str(wheel)])
    print(run([py, "-c", SMOKE, ",".join(NOT_IN_CORE)], cwd=work).stdout, end="")
    for args in (["--help"], ["estimate", "--help"], ["--version"]):
        run([env / "bin" / "quadest", *args], cwd=work)
    print("  quadest --help, estimate --help, --version: ok")
    (work / "x.ulg").write_bytes(b"ULog\x01\x12\x35\x01" + bytes(8))
    out = subprocess.run([env / "bin" / "quadest", "info", "x.ulg"], cwd=work, capture_output=True, text=True)
    if out.returncode != 1 or "pip install 'quadest[logs]'" not in out.stderr:
        sys.exit(f"failed: a ULog without the [logs] extra should say which extra:\n{out.stderr}")
    print(f"  without [logs]: {out.stderr.strip()}")
    return py


def check_logs(py: Path, wheel: Path, work: Path) -> None:
    print("==> the [logs] extra")
    run([py, "-m", "pip", "install", "--quiet", f"{wheel}[logs]"])
    print(run([py, "-c", LOGS, str(ROOT / "tests")], cwd=work).stdout, end="")


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="quadest-wheel-") as tmp:
        tmp = Path(tmp)
        (tmp / "work").mkdir()
        wheel = build(tmp / "dist")
        py = check_core(tmp / "env", wheel, tmp / "work")
        check_logs(py, wheel, tmp / "work")
    print("==> the wheel works")
    return 0


if __name__ == "__main__":
    sys.exit(main())
