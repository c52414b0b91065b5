"""The vehicle file (docs/vehicle.md, *Your own vehicle*): a :class:`MultirotorParams` as TOML,
one table per field with its value, unit and source (and, where measured, its uncertainty)::

    format = "quadest vehicle 1"
    name = "bebop2"

    [mass_kg]
    value = 0.375
    unit = "kg"
    source = "Sun et al., T-RO 2021: controlParams.m"

An optional ``[identified]`` table holds what an identification measured in the forms it is
measured (per mass, per inertia), each again a table of value, unit and source. A field left out
keeps :class:`MultirotorParams`' default; anything else the file holds is refused in one line
naming the file and the key."""

from __future__ import annotations

import json
import math
import sys
from dataclasses import fields
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10
    import tomli as tomllib

from quadest.data.files import write_bytes
from quadest.data.inputs import check_regular
from quadest.errors import UsageError
from quadest.models.multirotor import VEHICLE_PRESETS, MultirotorParams

FORMAT = "quadest vehicle 1"
"""The first line of every vehicle file: the format and its version."""
ENTRY_KEYS = ("value", "unit", "source", "uncertainty")
"""What a field's table may hold (``uncertainty`` optional, in the field's unit)."""
_FIELDS = {f.name: f for f in fields(MultirotorParams)}


def toml_value(v) -> str:
    """A number, string or (nested) sequence written as TOML (floats by ``repr``: they read back
    bit for bit)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):  # numpy's too: written as Python's float
        v = float(v)
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # JSON's escapes are TOML basic string's
    if hasattr(v, "tolist"):
        return toml_value(v.tolist())
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def _table(name: str, entry: dict) -> list[str]:
    lines = [f"[{name}]"]
    lines += [f"{k} = {toml_value(entry[k])}" for k in ENTRY_KEYS if entry.get(k) is not None]
    return lines + [""]


def vehicle_toml(vehicle: MultirotorParams, sources: dict | None = None, *, name: str = "",
                 uncertainty: dict | None = None, identified: dict | None = None) -> str:  # fmt: skip
    """The vehicle file's text: every field of ``vehicle`` with its unit and its source
    (``sources[field]``, else the field's documented default source), ``uncertainty[field]``
    where given, and the ``identified`` quantities (``{key: {value, unit, source[, uncertainty]}}``)."""
    sources, uncertainty = sources or {}, uncertainty or {}
    lines = ["# quadest vehicle file: every value with its unit and source (docs/vehicle.md)"]
    lines += [f"format = {toml_value(FORMAT)}", f"name = {toml_value(name)}", ""]
    for f in fields(MultirotorParams):
        entry = {
            "value": getattr(vehicle, f.name),
            "unit": f.metadata["unit"],
            "source": sources.get(f.name, f.metadata["source"]),
            "uncertainty": uncertainty.get(f.name),
        }
        lines += _table(f.name, entry)
    for key, entry in (identified or {}).items():
        lines += _table(f"identified.{key}", entry)
    return "\n".join(lines)


def write_vehicle(path, vehicle: MultirotorParams, sources: dict | None = None, **kw) -> Path:
    """:func:`vehicle_toml` written to ``path`` atomically."""
    return write_bytes(path, vehicle_toml(vehicle, sources, **kw).encode())


def preset_toml(name: str) -> str:
    """A preset of :data:`VEHICLE_PRESETS` as a vehicle file, with its sources."""
    values, sources = VEHICLE_PRESETS[name]
    return vehicle_toml(MultirotorParams(**values), sources, name=name)


def _plain_unit(unit: str) -> str:
    """A unit as compared: ``^2`` and ``²`` alike, spaces and ``*`` between factors alike."""
    return " ".join(unit.replace("^2", "²").replace("**2", "²").replace("*", " ").split())


def _as_value(v):
    return tuple(_as_value(x) for x in v) if isinstance(v, list) else v


def _entry(path, key: str, table) -> tuple:
    """A field's table checked: its value (lists as tuples), unit and source."""
    if not isinstance(table, dict):
        raise UsageError(f"{path}: {key} must be a table [{key}] with value, unit and source")
    extra = sorted(set(table) - set(ENTRY_KEYS))
    if extra:
        raise UsageError(f"{path}: [{key}] has {extra[0]!r}; a value's table holds {', '.join(ENTRY_KEYS)}")
    for k in ("value", "unit", "source"):
        if k not in table:
            raise UsageError(f"{path}: [{key}] has no {k}: write {k} = ... (value, unit and source are required)")
    if not isinstance(table["unit"], str) or not isinstance(table["source"], str):
        raise UsageError(f"{path}: [{key}] unit and source must be strings")
    return _as_value(table["value"]), table["unit"], table["source"]


def parse_vehicle(data: dict, path="vehicle file") -> tuple[MultirotorParams, dict, dict]:
    """A vehicle file's tables (as :mod:`tomllib` reads them) checked: the vehicle, each field's
    source, and the ``identified`` quantities."""
    if data.get("format") != FORMAT:
        raise UsageError(f"{path}: format must be {FORMAT!r} (got {data.get('format')!r}): not a quadest vehicle file")
    values, sources = {}, {}
    for key, table in data.items():
        if key in ("format", "name", "identified"):
            continue
        if key not in _FIELDS:
            raise UsageError(f"{path}: unknown key {key!r}; a vehicle's keys: {', '.join(_FIELDS)}")
        value, unit, source = _entry(path, key, table)
        expected = _FIELDS[key].metadata["unit"]
        if _plain_unit(unit) != _plain_unit(expected):
            raise UsageError(f"{path}: [{key}] unit {unit!r}, but {key} is in {expected!r}: convert the value")
        values[key], sources[key] = value, source
    identified = data.get("identified", {})
    if not isinstance(identified, dict):
        raise UsageError(f"{path}: identified must be a table of [identified.NAME] tables")
    for key, table in identified.items():
        _entry(path, f"identified.{key}", table)
    try:
        vehicle = MultirotorParams(**values)
    except (TypeError, ValueError) as exc:
        raise UsageError(f"{path}: {str(exc).removeprefix('vehicle: ')}") from None
    return vehicle, sources, identified


def read_vehicle(path) -> MultirotorParams:
    """The vehicle of a vehicle file (module doc); a bad file is a :class:`UsageError` naming
    the file and the key."""
    return read_vehicle_file(path)[0]


def read_vehicle_file(path) -> tuple[MultirotorParams, dict, dict]:
    """A vehicle file read: the vehicle, each field's source and the ``identified`` quantities."""
    path = Path(path)
    check_regular(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{path}: cannot read the vehicle file ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{path}: not TOML ({exc})") from None
    return parse_vehicle(data, path)
