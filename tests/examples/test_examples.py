"""Every script in examples/ runs as a user would run it (``python examples/NAME.py`` from the
repository) and prints its figures."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from quadest._jit import COMPILING

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.py"))


def test_there_are_examples():
    assert len(EXAMPLES) >= 5


def _said(stderr: str) -> str:
    """What a script wrote on stderr but the line before a first compile (quadest._jit)."""
    return "\n".join(line for line in stderr.splitlines() if not line.startswith(COMPILING)).strip()


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.stem)
def test_example_runs(script):
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert _said(done.stderr) == "", done.stderr[-2000:]  # no warning, no note
    assert re.search(r"\d+\.\d+", done.stdout), done.stdout  # it printed its figures


README = Path(__file__).resolve().parents[2] / "README.md"
TESTS = Path(__file__).resolve().parents[1]


def test_the_readme_python_section_runs(tmp_path):
    """The README's Python section, run as written, on a ULog ``flight.ulg`` written beside it
    (tests/logwriters.py: PX4's format, with a declination parameter and its own start time)."""
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "README.md has no Python section"
    prepare = (
        f"import sys; sys.path.insert(0, {str(TESTS)!r})\n"
        "from logwriters import write_ulog\nfrom quadest.sim import simulate\n"
        "write_ulog('flight.ulg', simulate('nominal', 'bebop2', seed=2, duration=5.0), "
        "params={'EKF2_MAG_DECL': 3.0}, t0_us=20_330_000)\n"
    )
    done = subprocess.run([sys.executable, "-c", prepare], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    for code in blocks:
        done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        assert _said(done.stderr) == "", done.stderr[-2000:]
        assert "roll" in done.stdout, done.stdout


def test_the_readme_install_lines_name_real_extras():
    """Every extra the README's install lines and extras list name is one pyproject.toml defines."""
    import tomllib

    extras = set(tomllib.loads((README.parent / "pyproject.toml").read_text())["project"]["optional-dependencies"])
    text = README.read_text()
    named = set(re.findall(r"'\.\[([a-z,]+)\]'", text))
    named = {e for group in named for e in group.split(",")}
    listed = set(re.findall(r"`([a-z]+)` \(", text[text.index("## Install") : text.index("## Two commands")]))
    assert named and listed and (named | listed) <= extras, (named | listed) - extras
