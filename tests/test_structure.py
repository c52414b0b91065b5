"""The shape of the code: numba's cache follows the source, compiled parameters are read by
name, and the packages import in one direction (docs/developing.md)."""
import ast
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "quadest"

# -- numba's cache ---------------------------------------------------------------------------------
SCRIPT = """
import json, sys
import numpy as np
import quadest
from quadest.filters import make_filter
rng = np.random.default_rng(0)
n = 400
t = np.arange(n) * 0.01
gyr = 0.3 * rng.standard_normal((n, 3))
acc = np.array([0.5, -0.3, -9.7]) + 0.2 * rng.standard_normal((n, 3))
mag = np.array([20.0, 2.0, 40.0]) + 0.5 * rng.standard_normal((n, 3))
q = {name: make_filter(name).run(t=t, gyr=gyr, acc=acc, mag=mag).q.tolist() for name in sys.argv[1].split(",")}
print(json.dumps({"file": quadest.__file__, "cache": quadest.NUMBA_CACHE_DIR, "q": q}))
"""


def _copy_package(tmp_path) -> Path:
    dst = tmp_path / "src" / "quadest"
    shutil.copytree(SRC, dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def _run_copy(pkg: Path, names: str, cache_home: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "QUADEST_NUMBA_CACHE_DIR")}
    env.update(PYTHONPATH=str(pkg.parent), XDG_CACHE_HOME=str(cache_home))
    out = subprocess.run([sys.executable, "-c", SCRIPT, names], env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert Path(res["file"]).resolve().is_relative_to(pkg), res["file"]  # the copy, not the repository
    return res


def _edit(path: Path, old: str, new: str):
    text = path.read_text()
    assert old in text, f"{path.name} no longer contains {old!r}"
    path.write_text(text.replace(old, new, 1))


NAMED = "madgwick,afckf,complementary,kalman,qukf"


@pytest.fixture(scope="module")
def copied(tmp_path_factory):
    """A copy of the package, its cache folder and the unmodified copy's estimates."""
    tmp = tmp_path_factory.mktemp("copy")
    pkg = _copy_package(tmp)
    cache = tmp / "cache"
    return pkg, cache, _run_copy(pkg, NAMED, cache)


def test_an_edit_of_a_shared_kernel_reaches_every_filter(copied):
    """numba keys its cache on each function's own file: without quadest's cache folder per
    source hash, madgwick would keep its compiled copy of the shared ``prepare``."""
    pkg, cache, first = copied
    again = _run_copy(pkg, "madgwick", cache)
    assert again["cache"] == first["cache"] and again["q"]["madgwick"] == first["q"]["madgwick"]
    # the shared step start never initialises: the attitude must stay at identity
    _edit(pkg / "filters" / "common.py", "def prepare(x, acc, mag, use_mag):\n",
          "def prepare(x, acc, mag, use_mag):\n    return False\n")
    edited = _run_copy(pkg, "madgwick", cache)
    assert edited["cache"] != first["cache"]
    assert edited["q"]["madgwick"] != first["q"]["madgwick"]
    assert all(row == [1.0, 0.0, 0.0, 0.0] for row in edited["q"]["madgwick"])
    # old folders beyond the kept few are removed; the current one stays
    assert Path(edited["cache"]).is_dir()


def _reverse_fields(path: Path, class_name: str):
    """Reverse the order of a dataclass's field declarations in a source file."""
    text = path.read_text()
    lines = text.splitlines(keepends=True)
    cls = next(n for n in ast.parse(text).body if isinstance(n, ast.ClassDef) and n.name == class_name)
    fields = [n for n in cls.body if isinstance(n, ast.AnnAssign)]
    assert len(fields) > 2
    blocks = ["".join(lines[f.lineno - 1:f.end_lineno]) for f in fields]
    first, last = fields[0].lineno - 1, fields[-1].end_lineno
    assert all(f.end_lineno + 1 == g.lineno for f, g in zip(fields, fields[1:])), "fields must be contiguous"
    path.write_text("".join(lines[:first]) + "".join(reversed(blocks)) + "".join(lines[last:]))


def test_parameters_are_read_by_name_not_position(copied, tmp_path):
    """Reversing the declaration order of every parameter record changes nothing: the compiled
    steps read ``p.beta``, not ``p[3]``."""
    _, _, first = copied
    pkg = _copy_package(tmp_path)
    for module, cls in (("madgwick", "MadgwickParams"), ("afckf", "AfckfParams"),
                        ("complementary", "ComplementaryParams"), ("kalman", "KalmanParams"),
                        ("qukf", "QukfParams")):
        _reverse_fields(pkg / "filters" / f"{module}.py", cls)
    reordered = _run_copy(pkg, NAMED, tmp_path / "cache")
    assert reordered["cache"] != first["cache"]
    for name in NAMED.split(","):
        assert reordered["q"][name] == first["q"][name], name
