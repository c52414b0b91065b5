"""quadest's small JSON files (calibrations, aerodynamic models): a ``format`` tag says what a
file is, so a wrong or damaged file is refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

from quadest.data.inputs import check_regular


def read_tagged_json(path, tag: str, what: str) -> dict:
    """The dict in ``path`` if it is readable JSON carrying ``"format": tag``; otherwise a
    ValueError naming the file and ``what`` was expected."""
    path = Path(path)
    check_regular(path)
    try:
        d = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable {what} ({exc})") from None
    if not isinstance(d, dict) or d.get("format") != tag:
        raise ValueError(f"{path}: not a quadest {what} (expected format {tag!r})")
    return d
