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

SRC = Path(__file__).resolve().parents[2] / "src" / "quadest"

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


def _start_copy(pkg: Path, names: str, cache_home: Path) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "QUADEST_NUMBA_CACHE_DIR")}
    env.update(PYTHONPATH=str(pkg.parent), XDG_CACHE_HOME=str(cache_home))
    return subprocess.Popen(
        [sys.executable, "-c", SCRIPT, names], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _result(proc: subprocess.Popen, pkg: Path) -> dict:
    out, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    res = json.loads(out.strip().splitlines()[-1])
    assert Path(res["file"]).resolve().is_relative_to(pkg), res["file"]  # the copy, not the repository
    return res


def _run_copy(pkg: Path, names: str, cache_home: Path) -> dict:
    return _result(_start_copy(pkg, names, cache_home), pkg)


def _edit(path: Path, old: str, new: str):
    text = path.read_text()
    assert old in text, f"{path.name} no longer contains {old!r}"
    path.write_text(text.replace(old, new, 1))


NAMED = "madgwick,afckf,valenti,roetenberg,qukf"


PARAMS_CLASSES = (
    ("madgwick", "MadgwickParams"),
    ("afckf", "AfckfParams"),
    ("valenti", "ValentiParams"),
    ("roetenberg", "RoetenbergParams"),
    ("qukf", "QukfParams"),
)


@pytest.fixture(scope="module")
def copied(tmp_path_factory):
    """A copy of the package, its cache folder and the unmodified copy's estimates; and a second
    copy whose parameter records declare their fields in reverse order, with its estimates (both
    compile from nothing, so they run side by side)."""
    tmp = tmp_path_factory.mktemp("copy")
    pkg = _copy_package(tmp)
    rev = _copy_package(tmp / "reversed")
    for module, cls in PARAMS_CLASSES:
        _reverse_fields(rev / "filters" / f"{module}.py", cls)
    procs = [_start_copy(pkg, NAMED, tmp / "cache"), _start_copy(rev, NAMED, tmp / "cache-reversed")]
    return pkg, tmp / "cache", _result(procs[0], pkg), _result(procs[1], rev)


def test_an_edit_of_a_shared_kernel_reaches_every_filter(copied):
    """numba keys its cache on each function's own file: without quadest's cache folder per
    source hash, madgwick would keep its compiled copy of the shared ``prepare``."""
    pkg, cache, first, _ = copied
    again = _run_copy(pkg, "madgwick", cache)
    assert again["cache"] == first["cache"] and again["q"]["madgwick"] == first["q"]["madgwick"]
    # the shared step start never initialises: the attitude must stay at identity
    _edit(
        pkg / "filters" / "common.py",
        "def prepare(x, acc, mag, use_mag):\n",
        "def prepare(x, acc, mag, use_mag):\n    return False\n",
    )
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
    blocks = ["".join(lines[f.lineno - 1 : f.end_lineno]) for f in fields]
    first, last = fields[0].lineno - 1, fields[-1].end_lineno
    assert all(f.end_lineno + 1 == g.lineno for f, g in zip(fields, fields[1:])), "fields must be contiguous"
    path.write_text("".join(lines[:first]) + "".join(reversed(blocks)) + "".join(lines[last:]))


def test_parameters_are_read_by_name_not_position(copied):
    """Reversing the declaration order of every parameter record changes nothing: the compiled
    steps read ``p.beta``, not ``p[3]``."""
    _, _, first, reordered = copied
    assert reordered["cache"] != first["cache"]
    for name in NAMED.split(","):
        assert reordered["q"][name] == first["q"][name], name


# -- layers --------------------------------------------------------------------------------------------
LAYERS = [  # the first four are the issue's layer 0, in the order they build on each other
    {"errors", "extras", "progress"},
    {"_jit", "conventions", "records"},
    {"rotation"},
    {"data", ""},  # "": the package itself (its __init__ exposes Recording and the version)
    {"models"},
    {"filters", "recovery", "sim", "readers", "calibration", "control", "detect"},
    {"flight"},
    {"evaluation"},
    {"sweep", "plot", "api"},
    {"cli"},
]
LAYER = {part: k for k, parts in enumerate(LAYERS) for part in parts}
LAZY_ALLOWED = {
    ("", "data"),  # quadest.Recording: numpy is loaded when first used (the command line's Ctrl-C guard first)
    ("", "_jit"),  # quadest.NUMBA_CACHE_DIR: numba is loaded only when asked
    ("", "api"),  # quadest.read / estimate / score: loaded when first used
    ("", "filters"),  # quadest.make_filter and the estimators' classes: loaded when first used
}
FACADE = {"api", "filters"}
"""What the package itself re-exports from above its layer, lazily (``quadest.estimate``): the
library's front, not a dependency of the lower layers."""


def _part(module: str) -> str:
    """``quadest.filters.afckf`` -> ``filters``; the package itself and its top-level modules
    (``quadest``, ``quadest.conventions``) are parts of their own."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _quadest_imports(path: Path):
    """(module imported, inside a function) for every import of a quadest module in a file."""
    tree = ast.parse(path.read_text())
    inside = set()
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            inside.update(id(n) for n in ast.walk(fn))
    for n in ast.walk(tree):
        names = []
        if isinstance(n, ast.ImportFrom) and n.module and n.level == 0:
            names = [n.module]
        elif isinstance(n, ast.Import):
            names = [a.name for a in n.names]
        for m in names:
            if m == "quadest" or m.startswith("quadest."):
                yield m, n.lineno, id(n) in inside


def test_packages_import_downwards_only():
    """conventions, rotation, data, models, then filters/recovery/sim/readers/calibration, then
    evaluation, then sweep/plot, then cli: a package imports only from lower layers (and from
    itself), never from a package of its own layer or above; imports of quadest modules are at
    the top of a file (the one exception: the command line, which imports the library a command
    needs when it runs, so that ``--help`` loads none of it)."""
    problems = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).with_suffix("")
        me = "" if rel.parts == ("__init__",) else rel.parts[0]
        assert me in LAYER, f"{rel}: package {me!r} has no layer; add it to LAYERS and docs/developing.md"
        for module, line, lazy in _quadest_imports(path):
            other = _part(module)
            if other == me:
                continue
            where = f"{rel}.py:{line} imports {module}"
            if other not in LAYER:
                problems.append(f"{where}: unknown package")
            elif LAYER[other] >= LAYER[me] and not (me == "" and (other == "data" or (lazy and other in FACADE))):
                problems.append(f"{where}: layer {LAYER[other]} from layer {LAYER[me]}")
            if lazy and (me, other) not in LAZY_ALLOWED and me != "cli":  # a command imports what it runs
                problems.append(f"{where}: inside a function")
    assert not problems, "\n".join(problems)


def test_the_layer_test_sees_a_violation(tmp_path):
    """The check above is not vacuous: an upward import in a copied file is reported."""
    f = tmp_path / "x.py"
    f.write_text("import numpy\nfrom quadest.sweep import run_sweep\n\ndef g():\n    from quadest.cli import main\n")
    found = list(_quadest_imports(f))
    assert found == [("quadest.sweep", 2, False), ("quadest.cli", 5, True)]
    assert LAYER[_part("quadest.sweep")] > LAYER[_part("quadest.filters.afckf")]


# -- nothing at import time ------------------------------------------------------------------------
def _python(code: str, cache_home: Path) -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "QUADEST_NUMBA_CACHE_DIR")}
    env["XDG_CACHE_HOME"] = str(cache_home)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_import_quadest_loads_no_compiler_and_touches_no_cache(tmp_path):
    """``import quadest`` (the Recording type) neither imports numba nor hashes the source nor
    makes, marks or removes a cache folder."""
    old = tmp_path / "quadest" / "numba" / "0123456789abcdef"
    old.mkdir(parents=True)
    os.utime(old, (1, 1))
    out = _python("import sys, quadest; print('numba' in sys.modules)", tmp_path)
    assert out.strip() == "False"
    assert [d.name for d in (tmp_path / "quadest" / "numba").iterdir()] == [old.name]
    assert old.stat().st_mtime == 1


def test_old_cache_folders_go_only_when_a_new_source_compiles(tmp_path):
    """Old folders are removed (beyond the kept few) when the current source's folder is made,
    which is when everything compiles anyway; a later import with the folder in place removes
    nothing."""
    root = tmp_path / "quadest" / "numba"
    for i in range(6):
        (root / f"old{i}").mkdir(parents=True)
        os.utime(root / f"old{i}", (1000 + i, 1000 + i))
    code = "import quadest.rotation.kernels as k, quadest; print(quadest.NUMBA_CACHE_DIR)"
    current = Path(_python(code, tmp_path).strip())
    assert current.parent == root and current.is_dir()
    kept = sorted(d.name for d in root.iterdir() if d != current)
    assert kept == ["old3", "old4", "old5"]  # the three most recent others: four folders in all
    for i in range(6, 9):
        (root / f"old{i}").mkdir()
    _python(code, tmp_path)
    assert len([d for d in root.iterdir() if d != current]) == 6


def test_compiled_code_is_defined_through_quadest_jit():
    """Every compiled function is decorated by ``quadest._jit``'s re-export of numba, which sets
    the cache folder first: no module imports numba's decorators itself."""
    problems = []
    for path in sorted(SRC.rglob("*.py")):
        if path.name == "_jit.py":
            continue
        for n in ast.walk(ast.parse(path.read_text())):
            if isinstance(n, ast.ImportFrom) and n.module and n.module.split(".")[0] == "numba":
                problems.append(f"{path.relative_to(SRC)}:{n.lineno} imports from {n.module}")
            elif isinstance(n, ast.Import) and any(a.name.split(".")[0] == "numba" for a in n.names):
                problems.append(f"{path.relative_to(SRC)}:{n.lineno} imports numba")
    assert not problems, "\n".join(problems)


def _estimator_private_names() -> set[str]:
    from quadest.filters.base import Estimator
    from quadest.filters.madgwick import Madgwick

    est = Madgwick()
    names = set(vars(est)) | set(vars(Estimator))
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


def test_nothing_outside_filters_reads_an_estimator_private_field():
    """A loop in compiled code takes what it needs from ``Estimator.compiled()``; nothing outside
    ``filters/`` reads an estimator's private fields or imports a private name of ``filters``."""
    private = _estimator_private_names()
    assert {"_x", "_p", "_c", "_diag"} <= private
    problems = []
    for path in sorted(SRC.rglob("*.py")):
        if "filters" in path.relative_to(SRC).parts:
            continue
        for n in ast.walk(ast.parse(path.read_text())):
            where = f"{path.relative_to(SRC)}:{getattr(n, 'lineno', 0)}"
            if isinstance(n, ast.Attribute) and n.attr in private:
                problems.append(f"{where} reads .{n.attr}")
            if isinstance(n, ast.ImportFrom) and (n.module or "").startswith("quadest.filters"):
                problems += [f"{where} imports {a.name}" for a in n.names if a.name.startswith("_")]
    assert not problems, "\n".join(problems)


def test_compiled_gives_the_live_state():
    """``compiled()`` hands out the estimator's own arrays: a step run on them is the step the
    estimator's next update continues from."""
    import numpy as np

    from quadest.filters import make_filter

    est = make_filter("robust", declination=0.2)
    c = est.compiled()
    gyr, acc, mag = np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, -9.81]), np.array([20.0, 0.0, 40.0])
    c.step(c.state, c.params, c.coefficients, gyr, acc, mag, 0.01, c.diag)
    other = make_filter("robust", declination=0.2)
    other.update(gyr, acc, mag, dt=0.01)
    np.testing.assert_array_equal(est.get_state(), other.get_state())
    np.testing.assert_allclose(c.declination_quat, [np.cos(0.1), 0.0, 0.0, np.sin(0.1)], rtol=0, atol=1e-15)


MAX_LINES, MAX_PARAMS = 100, 12


def _functions(root: Path):
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield path, node


def test_functions_are_short_and_take_few_parameters():
    """No function of the package is longer than 100 lines or takes more than 12 parameters
    (related values travel as a record or a tuple: a loop's ``L``, a bank's ``(V, Qr, P, L, w)``)."""
    problems = []
    for path, fn in _functions(SRC):
        a = fn.args
        params = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
        lines = fn.end_lineno - fn.lineno + 1
        if lines > MAX_LINES or params > MAX_PARAMS:
            problems.append(f"{path.relative_to(SRC)}:{fn.lineno} {fn.name}: {lines} lines, {params} parameters")
    assert not problems, "\n".join(problems)


MAX_FILE_LINES, MAX_COMMAND_LINES = 600, 450


def test_modules_are_small():
    """No source file of the package is longer than 600 lines, and no command module (``cli/``,
    whose work belongs to the library) longer than 450."""
    problems = []
    for path in sorted(SRC.rglob("*.py")):
        lines = len(path.read_text().splitlines())
        cap = MAX_COMMAND_LINES if path.parent.name == "cli" else MAX_FILE_LINES
        if lines > cap:
            problems.append(f"{path.relative_to(SRC)}: {lines} lines (at most {cap})")
    assert not problems, "\n".join(problems)


def test_the_library_logs_and_warns_and_never_prints():
    """Diagnostics go through ``logging`` (the command line's ``-q`` / ``-v``) and ``warnings``;
    only the command line (``cli/``) prints."""
    hits = []
    for path in sorted(SRC.rglob("*.py")):
        if path.parent.name == "cli":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "print":
                hits.append(f"{path.relative_to(SRC)}:{node.lineno}")
    assert not hits, "print() in library code: " + ", ".join(hits)


def test_no_issue_numbers_in_code():
    """What an issue asked for is in the repository's history, not in the code (it goes stale)."""
    root = SRC.parents[1]
    hits = [
        f"{p.relative_to(root)}:{i}"
        for folder in ("src", "tests", "tools")
        for p in sorted((root / folder).rglob("*.py"))
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if "issue " + "#" in line.lower()
    ]
    assert not hits, "issue numbers in code: " + ", ".join(hits)


def test_one_closed_loop_and_one_sensor_model():
    """Every flight flies through flight/loop.py's closed_loop, and every simulation samples the
    one compiled sensor model of sim/sensors.py."""
    defs = {}
    for path, fn in _functions(SRC):
        defs.setdefault(fn.name, []).append(str(path.relative_to(SRC)))
    assert defs["closed_loop"] == ["flight/loop.py"]
    assert defs["sample_imu"] == ["sim/sensors.py"] and defs["sample_mag"] == ["sim/sensors.py"]
    # a controller runs only through the registry's command, the vehicle flies a controller's
    # commands only in the loop (multirotor's own open-loop integration takes given commands)
    calls = {}
    for path, fn in _functions(SRC):
        for node in ast.walk(fn):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                calls.setdefault(node.func.id, set()).add(f"{path.relative_to(SRC)}:{fn.name}")
    assert calls["rk4_ws"] <= {
        "flight/loop.py:advance",
        "models/multirotor.py:rk4",
        "models/multirotor.py:fly_open_loop",
    }
    assert calls["ftc_command"] == {"control/registry.py:command"}


def test_a_complete_loss_is_decided_in_one_place():
    """Whether a failure is a complete loss is asked of its record (sim/faults.py:
    ``Failure.complete``), never re-derived from its efficiency elsewhere."""
    derived = re.compile(r"efficiency[\"'\]]*\s*(==|>|<=|!=)\s*0")
    found = [
        f"{path.relative_to(SRC)}:{i}"
        for path in sorted(SRC.rglob("*.py"))
        if path.relative_to(SRC).as_posix() != "sim/faults.py"
        for i, line in enumerate(path.read_text().splitlines(), 1)
        if derived.search(line)
    ]
    assert not found, found


def test_results_do_not_depend_on_what_compiled_first(tmp_path):
    """numba compiles a kernel that states no ``fastmath`` with its first caller's: madgwick's
    start (the shared ``prepare``, ``tilt_from_acc``, ``mag_heading``) first compiled from the
    Kalman filter's ``fastmath`` step gave other bits than compiled from madgwick's. quadest's
    ``njit`` states it, so each fresh cache gives the same madgwick whatever ran before."""
    after_kalman = _start_copy(SRC, "roetenberg,madgwick", tmp_path / "a")
    alone = _start_copy(SRC, "madgwick", tmp_path / "b")
    qa, qb = _result(after_kalman, SRC)["q"]["madgwick"], _result(alone, SRC)["q"]["madgwick"]
    assert qa == qb


def _unannotated(obj) -> list[str]:
    """The parameters (and ``return``) of a Python function that carry no annotation."""
    import inspect

    sig = inspect.signature(obj)
    skip = (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD)
    out = [n for n, p in sig.parameters.items() if n not in ("self", "cls") and p.kind not in skip]
    out = [n for n in out if sig.parameters[n].annotation is inspect.Parameter.empty]
    if sig.return_annotation is inspect.Signature.empty and obj.__name__ != "__init__":
        out.append("return")
    return out


def test_the_public_api_has_type_hints():
    """Every function a package exports (``__all__``), and every public method of an exported
    class, is annotated; compiled steps (numba) are not Python functions a user calls."""
    import importlib
    import inspect
    import pkgutil

    import quadest

    names = ["quadest"] + [f"quadest.{m.name}" for m in pkgutil.iter_modules(quadest.__path__) if m.ispkg]
    missing = []
    for modname in names:
        mod = importlib.import_module(modname)
        for name in getattr(mod, "__all__", []):
            obj = getattr(mod, name)
            members = [(name, obj)] if inspect.isfunction(obj) else []
            if inspect.isclass(obj):
                for attr, value in vars(obj).items():
                    value = getattr(value, "__func__", value)
                    if inspect.isfunction(value) and (attr == "__init__" or not attr.startswith("_")):
                        if attr not in ("step", "batch", "stream"):
                            members.append((f"{name}.{attr}", value))
            missing += [f"{modname}.{n}: {_unannotated(f)}" for n, f in members if _unannotated(f)]
    assert not missing, "\n".join(missing)


# -- Python 3.10 -----------------------------------------------------------------------------------
def test_the_source_needs_nothing_newer_than_python_310():
    """requires-python says 3.10; only 3.11 runs here, so vermin reads every source file for
    syntax and standard-library names newer than that (annotations included)."""
    vermin = shutil.which("vermin", path=str(Path(sys.executable).parent)) or shutil.which("vermin")
    if vermin is None:
        pytest.skip("vermin is not installed (it is in the test extra)")
    out = subprocess.run(
        [vermin, "-t=3.10-", "--no-tips", "--violations", "--eval-annotations", "--no-parse-comments", str(SRC)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]


def test_a_users_cache_folder_gets_a_subfolder_per_source(tmp_path):
    """With ``NUMBA_CACHE_DIR`` set, quadest's code goes to ``quadest-<hash>`` inside it (an
    upgrade cannot run stale compiled code); housekeeping removes only quadest's own old
    subfolders, never the user's other folders; a child process keeps the same folder."""
    user = tmp_path / "mine"
    for i in range(5):
        (user / f"quadest-old{i}").mkdir(parents=True)
        os.utime(user / f"quadest-old{i}", (1000 + i, 1000 + i))
    (user / "other-project").mkdir()
    os.utime(user / "other-project", (1, 1))
    code = (
        "import subprocess, sys, quadest.rotation.kernels, quadest; print(quadest.NUMBA_CACHE_DIR); "
        "print(subprocess.run([sys.executable, '-c', 'import quadest.rotation.kernels, quadest; "
        "print(quadest.NUMBA_CACHE_DIR)'], capture_output=True, text=True).stdout.strip())"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("QUADEST_NUMBA_CACHE_DIR", "QUADEST_NUMBA_USER_DIR")}
    env["NUMBA_CACHE_DIR"] = str(user)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    mine, child = (Path(line) for line in out.stdout.split())
    assert mine.parent == user and mine.name.startswith("quadest-") and mine.is_dir()
    assert child == mine
    left = sorted(d.name for d in user.iterdir() if d != mine)
    assert left == ["other-project", "quadest-old2", "quadest-old3", "quadest-old4"]
