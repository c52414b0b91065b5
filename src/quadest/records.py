"""Parameter records: frozen dataclasses whose every field states its unit, meaning and where
its value comes from (a publication, or "chosen" and why). The estimators', the recovery's and
the simulator's parameters are all declared with :func:`param`."""
from __future__ import annotations

from dataclasses import field, fields

CHOSEN = "chosen (no published value)"


def param(default, unit: str, doc: str, source: str = CHOSEN):
    """A parameter field: default, unit, one-line meaning and the source of the default."""
    return field(default=default, metadata={"unit": unit, "doc": doc, "source": source})


def describe(record_cls) -> list[dict]:
    """``[{name, default, unit, doc, source}]`` of a parameter record's fields, in order."""
    return [{"name": f.name, "default": f.default, **f.metadata} for f in fields(record_cls)]
