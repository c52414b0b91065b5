"""Any CSV with a header row: the user says which columns are what, in which units and frames.

``columns`` maps quadest fields to the file's column names::

    {"t": "timestamp", "gyr": ["gx", "gy", "gz"], "acc": ["ax", "ay", "az"],
     "mag": ["mx", "my", "mz"], "true_q": ["qw", "qx", "qy", "qz"]}

and the rotors' channels, one column per rotor in quadest's order (``"rotor_speed": ["w1", "w2",
"w3", "w4"]``, ``"motor_command": [...]``, docs/recordings.md).

``units``: ``{"t": "ms", "gyr": "deg/s", "acc": "g", "mag": "gauss", "rotor_speed": "rpm",
"motor_command": "%"}`` (defaults SI, µT and commands from 0 to 1);
``frame``: ``"ned-frd"`` (default) or ``"enu-flu"``; ``quat_order``: ``"wxyz"`` or ``"xyzw"``.
From the command line: ``--format csv --map t=timestamp --map gyr=gx,gy,gz ... --units gyr=deg/s
--frame enu-flu`` (docs/readers.md)."""

from __future__ import annotations

import numpy as np

from quadest.data.recording import numeric_column
from quadest.readers.common import ReaderError, make_recording, unit_factor
from quadest.readers.rotors import RPM, rotor_meta
from quadest.rotation.frames import quat_enu_flu_to_ned_frd, vec_enu_to_ned, vec_flu_to_frd

FIELDS = {"t": 1, "gyr": 3, "acc": 3, "mag": 3, "true_q": 4, "true_pos": 3, "true_vel": 3}
ROTOR_MAPS = ("rotor_speed", "motor_command")  # one column per rotor, any count
UNITS = {"rotor_speed": {"rad/s": 1.0, "rpm": RPM}, "motor_command": {"1": 1.0, "%": 0.01}}


def parse_columns(items) -> dict:
    """``["t=time", "gyr=gx,gy,gz"]`` -> ``{"t": "time", "gyr": ["gx", "gy", "gz"]}``."""
    out = {}
    for item in items or []:
        key, sep, val = item.partition("=")
        key = key.strip()
        if not sep or key not in (*FIELDS, *ROTOR_MAPS):
            known = ", ".join((*FIELDS, *ROTOR_MAPS))
            raise ReaderError(f"--map {item!r}: expected FIELD=COLUMN[,COLUMN...] with FIELD one of {known}")
        cols = [c.strip() for c in val.split(",")]
        if key in ROTOR_MAPS:
            out[key] = cols  # one per rotor
            continue
        if len(cols) != FIELDS[key]:
            raise ReaderError(f"--map {item!r}: {key} needs {FIELDS[key]} column(s), got {len(cols)}")
        out[key] = cols[0] if key == "t" else cols
    return out


def parse_units(items) -> dict:
    out = {}
    for item in items or []:
        key, sep, val = item.partition("=")
        if not sep or key.strip() not in ("t", "gyr", "acc", "mag", *UNITS):
            raise ReaderError(
                f"--units {item!r}: expected t=s|ms|us|ns, gyr=rad/s|deg/s, acc=m/s^2|g|mg, mag=uT|nT|T|gauss|mgauss, "
                "rotor_speed=rad/s|rpm or motor_command=1|%"
            )
        _factor(key.strip(), val.strip())  # validates
        out[key.strip()] = val.strip()
    return out


def _factor(kind: str, unit: str) -> float:
    """The factor of ``unit`` to quadest's (a rotor channel's, or :func:`unit_factor`'s)."""
    if kind not in UNITS:
        return unit_factor(kind, unit)
    if unit not in UNITS[kind]:
        raise ReaderError(f"unknown {kind} unit {unit!r}; known: {', '.join(UNITS[kind])}")
    return UNITS[kind][unit]


def _rotor_channels(vec, columns, units) -> tuple[dict, dict | None]:
    """The mapped rotor channels in quadest's units and their ``meta['rotors']``."""
    out = {k: vec(k) * _factor(k, units.get(k, next(iter(UNITS[k])))) for k in ROTOR_MAPS if k in columns}
    if not out:
        return {}, None
    counts = {len(columns[k]) for k in out}
    if len(counts) > 1:
        raise ReaderError(f"--map: rotor_speed and motor_command name different numbers of columns ({sorted(counts)})")
    sources = {k: f"columns {', '.join(columns[k])}" for k in out}
    return out, rotor_meta(counts.pop(), numbering="the mapped columns' order", sources=sources)


def read_csv_mapped(
    path, *, columns=None, units=None, frame: str = "ned-frd", quat_order: str = "wxyz", delimiter=None
):
    import pyarrow as pa
    import pyarrow.csv as pcsv

    columns = dict(columns or {})
    units = dict(units or {})
    missing = [k for k in ("t", "gyr", "acc") if k not in columns]
    if missing:
        raise ReaderError(
            f"{path}: a generic CSV needs the column mapping for {', '.join(missing)} "
            "(--map t=COL --map gyr=X,Y,Z --map acc=X,Y,Z)"
        )
    if frame not in ("ned-frd", "enu-flu"):
        raise ReaderError(f"unknown frame {frame!r}; ned-frd or enu-flu")
    parse = pcsv.ParseOptions(delimiter=delimiter) if delimiter else pcsv.ParseOptions()
    try:
        with open(path, "rb") as fh:  # a file object: pyarrow takes only UTF-8 names
            table = pcsv.read_csv(fh, parse_options=parse, read_options=pcsv.ReadOptions(skip_rows=0))
    except (pa.ArrowException, OSError) as exc:
        raise ReaderError(f"{path}: malformed CSV ({str(exc).splitlines()[0]})") from None
    names = [c.strip() for c in table.column_names]
    dup = sorted({c for c in names if names.count(c) > 1})
    if dup:
        raise ReaderError(f"{path}: column(s) {', '.join(map(repr, dup))} appear more than once; name each column once")
    table = table.rename_columns(names)

    def col(name):
        if name not in names:
            raise ReaderError(f"{path}: no column {name!r}; columns: {', '.join(names)}")
        try:  # a time may be a large integer (ns since 1970): only the measurements must be exact
            return numeric_column(path, repr(name), table.column(name), exact=name != columns["t"])
        except ValueError as exc:
            raise ReaderError(str(exc)) from None

    def vec(key):
        return np.column_stack([col(c) for c in columns[key]]) if key in columns else None

    t = col(columns["t"]) * unit_factor("t", units.get("t", "s"))
    gyr = vec("gyr") * unit_factor("gyr", units.get("gyr", "rad/s"))
    acc = vec("acc") * unit_factor("acc", units.get("acc", "m/s^2"))
    mag = vec("mag")
    if mag is not None:
        mag = mag * unit_factor("mag", units.get("mag", "uT"))
    truth = {}
    q = vec("true_q")
    if q is not None:
        if quat_order == "xyzw":
            q = q[:, [3, 0, 1, 2]]
        elif quat_order != "wxyz":
            raise ReaderError(f"unknown quaternion order {quat_order!r}; wxyz or xyzw")
        truth["true_q"] = q
    for k in ("true_pos", "true_vel"):
        if k in columns:
            truth[k] = vec(k)
    rotor_channels, rotors = _rotor_channels(vec, columns, units)
    if frame == "enu-flu":
        gyr, acc = vec_flu_to_frd(gyr), vec_flu_to_frd(acc)
        mag = vec_flu_to_frd(mag) if mag is not None else None
        if "true_q" in truth:
            truth["true_q"] = quat_enu_flu_to_ned_frd(truth["true_q"])
        for k in ("true_pos", "true_vel"):
            if k in truth:
                truth[k] = vec_enu_to_ned(truth[k])
    if "true_q" in truth:
        n = np.linalg.norm(truth["true_q"], axis=1, keepdims=True)
        truth["true_q"] = np.where(n > 0.5, truth["true_q"] / np.where(n > 0, n, 1), np.nan)
    meta = {
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT" if mag is not None else "unknown"},
        "column_map": columns,
        "units_in_file": units,
        "frames": f"{frame} -> NED/FRD",
        **({"rotors": rotors} if rotors else {}),
    }
    return make_recording(path, "csv", t, gyr, acc, mag, meta, **truth, **rotor_channels)
