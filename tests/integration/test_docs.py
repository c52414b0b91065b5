"""docs/ stays true to the code: generated tables are current, commands in the README exist."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_generated_tables_are_current():
    r = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "update_docs.py"), "--check"], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stdout + r.stderr


def test_every_simulator_parameter_is_documented():
    from quadest.sim import build_config, param_table

    doc = (ROOT / "docs" / "simulator.md").read_text()
    missing = [r["key"] for r in param_table(build_config("bebop2")) if f"`{r['key']}`" not in doc]
    assert not missing
