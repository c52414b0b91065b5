"""Regenerate the generated tables in docs/ from the code (run after changing parameters).

Sections between ``<!-- generated:NAME -->`` and ``<!-- /generated -->`` are replaced:
``simulator-params`` (every simulator parameter of the bebop2 preset) and ``estimator-params``
(every estimator's parameter record). tests/test_docs.py fails when docs/ is out of date.
"""
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def simulator_params() -> str:
    from quadest.sim import build_config, param_table
    rows = ["| parameter | value | unit | meaning | source |", "|---|---|---|---|---|"]
    for r in param_table(build_config("bebop2"), "bebop2"):
        rows.append(f"| `{r['key']}` | {json.dumps(r['value'], default=str)} | {r['unit']} | "
                    f"{r['doc']} | {r['source']} |")
    return "\n".join(rows)


def estimator_params() -> str:
    from quadest.filters import FILTERS
    out = []
    for name, cls in FILTERS.items():
        out.append(f"**`{name}`**\n\n| parameter | default | unit | meaning | source |\n|---|---|---|---|---|")
        for d in cls.Params.describe():
            out.append(f"| `{d['name']}` | {json.dumps(d['default'], default=float)} | {d['unit']} | "
                       f"{d['doc']} | {d['source']} |")
        out.append("")
    return "\n".join(out).rstrip()


def recovery_params() -> str:
    from quadest.recovery.logic import param_rows
    rows = ["| parameter | default | unit | meaning | source |", "|---|---|---|---|---|"]
    for d in param_rows():
        rows.append(f"| `{d['name']}` | {d['default']} | {d['unit']} | {d['doc']} | {d['source']} |")
    return "\n".join(rows)


GENERATORS = {"simulator-params": simulator_params, "estimator-params": estimator_params,
              "recovery-params": recovery_params}
PATTERN = re.compile(r"(<!-- generated:([a-z-]+) -->\n)(.*?)(<!-- /generated -->)", re.S)


def render(text: str) -> str:
    return PATTERN.sub(lambda m: m.group(1) + GENERATORS[m.group(2)]() + "\n" + m.group(4), text)


def main(check: bool = False) -> int:
    stale = []
    for path in sorted((ROOT / "docs").glob("*.md")):
        text = path.read_text()
        new = render(text)
        if new != text:
            stale.append(path.name)
            if not check:
                path.write_text(new)
    if check and stale:
        print("out of date: " + ", ".join(stale) + " (run python tools/update_docs.py)")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(check="--check" in sys.argv))
