"""A :class:`~quadest.data.recording.Recording` as a file: CSV or Parquet by the extension, a
lossless round trip (docs/recordings.md).

A CSV is plain, its fixed header then the rows, so that pandas, PlotJuggler and spreadsheets read
it as it is; its metadata, its row count and the checksum of its values stand beside it in
``NAME.csv-metadata.json`` (W3C CSV on the Web, with each column's unit and frame), so that a
file cut short or changed is refused instead of read as another recording (line ends and
blank lines at the end, an editor's, change no value). CSVs of earlier
versions (the metadata in ``#`` lines at the top) are still read. A Parquet file holds its
metadata in its schema."""

from __future__ import annotations

import hashlib
import io
import json
import re
from pathlib import Path

import numpy as np

from quadest.data.files import DESCRIPTORS, atomic_output
from quadest.data.recording import (
    ROTOR_FIELDS,
    SENSOR_FIELDS,
    TRUTH_FIELDS,
    Recording,
    columns_of,
    numeric_column,
)
from quadest.data.tables import check_csv_metadata_target, described, read_csv_metadata, write_csv_metadata

FORMAT_TAG = "quadest recording v3"
"""v3: a plain CSV, its metadata beside it (module docstring); Parquet as in v2."""
LEGACY_TAGS = ("quadest recording v1", "quadest recording v2")
"""Earlier CSVs: metadata in ``# key: <json>`` lines above the header; v2 also states its row
count (``# rows: N``) and ends with ``# end: N rows``."""
END_MARK = "# end: "

_SENSOR_UNITS = {
    "t": "s (the recording's time)",
    "gyr": "rad/s, body FRD",
    "acc": "m/s², specific force, body FRD",
}
_ROTOR_UNITS = {"rotor_speed": "rad/s", "motor_command": "1 (normalised: 0 off, 1 full)"}


def column_units(rec: Recording) -> dict:
    """Each column of ``rec``'s files with its unit and frame (docs/conventions.md)."""
    units = {"t": _SENSOR_UNITS["t"]}
    stated = rec.meta.get("units")
    mag_unit = stated.get("mag", "as meta.units.mag states") if isinstance(stated, dict) else "as meta.units.mag states"
    fields = {"gyr": _SENSOR_UNITS["gyr"], "acc": _SENSOR_UNITS["acc"], "mag": f"{mag_unit}, body FRD"}
    fields.update({name: desc for name, (_, desc) in TRUTH_FIELDS.items()})
    for name, desc in fields.items():
        units.update({c: desc for c in columns_of(name)})
    for name, desc in _ROTOR_UNITS.items():
        units.update({c: desc for c in columns_of(name, rec.rotors)})
    return units


def _kind(path: Path) -> str:
    if str(path) in DESCRIPTORS and not path.suffix:
        return "csv"
    ext = path.suffix.lower()
    if ext == ".csv":
        return "csv"
    if ext in (".parquet", ".pq"):
        return "parquet"
    raise ValueError(f"{path}: unknown recording extension {ext!r}; use .csv or .parquet")


def save_recording(rec: Recording, path: str | Path) -> Path:
    """Write a recording as CSV or Parquet (by extension); the round trip is lossless."""
    import pyarrow as pa

    path = Path(path)
    kind = _kind(path)
    table = pa.table(rec.columns())
    if kind == "parquet":
        import pyarrow.parquet as pq

        schema = described(table.schema, column_units(rec))
        head = json.dumps({"format": FORMAT_TAG, "meta": rec.meta, "rows": len(rec)}).encode()
        table = table.cast(schema.with_metadata({**schema.metadata, b"quadest": head}))
        with atomic_output(path) as tmp, open(tmp, "wb") as fh:  # a file object: pyarrow takes only UTF-8 names
            pq.write_table(table, fh)
        return path
    import pyarrow.csv as pcsv

    check_csv_metadata_target(path)
    with atomic_output(path, suffix=".csv") as tmp, open(tmp, "wb") as f:
        f.write((",".join(table.column_names) + "\n").encode())
        pcsv.write_csv(table, f, pcsv.WriteOptions(include_header=False, quoting_style="none"))
    head = {"format": FORMAT_TAG, "rows": len(rec), "values_sha256": values_sha256(rec), "meta": rec.meta}
    write_csv_metadata(path, table.column_names, column_units(rec), head)
    return path


def _stacked(get, cols, n) -> np.ndarray:
    """The columns ``cols`` side by side, each read by ``get`` into its place (one column's
    copy at a time: a long recording is never held twice)."""
    out = np.empty((n, len(cols)))
    for j, c in enumerate(cols):
        out[:, j] = get(c)
    return out


def _rotor_columns(names, field_name, source) -> list[str]:
    """A rotor field's columns, ``NAME_0`` on without a gap (or none)."""
    found = [c for c in names if re.fullmatch(rf"{field_name}_\d+", c)]
    expected = columns_of(field_name, len(found))
    if sorted(found) != sorted(expected):
        raise ValueError(
            f"{source}: {field_name} needs the columns {', '.join(expected)} (numbered from 0), got {', '.join(found)}"
        )
    return expected


def _from_columns(names, get, meta, source, check_units=True) -> Recording:
    names = list(names)
    base = ["t"] + [c for f in SENSOR_FIELDS for c in columns_of(f)]
    missing = [c for c in base if c not in names]
    if missing:
        raise ValueError(f"{source}: missing column(s) {', '.join(missing)}")
    known = set(base)
    kw = {"t": np.array(get("t"), dtype=np.float64)}  # its own, writable (a column may be a view of pyarrow's)
    for f in SENSOR_FIELDS:
        kw[f] = _stacked(get, columns_of(f), len(kw["t"]))
    for f in TRUTH_FIELDS:
        cols = columns_of(f)
        present = [c for c in cols if c in names]
        if present and len(present) != len(cols):
            raise ValueError(f"{source}: truth field {f} needs all of {', '.join(cols)}")
        if present:
            kw[f] = _stacked(get, cols, len(kw["t"]))
            known.update(cols)
    for f in ROTOR_FIELDS:
        cols = _rotor_columns(names, f, source)
        if cols:
            kw[f] = _stacked(get, cols, len(kw["t"]))
            known.update(cols)
    extra = [c for c in names if c not in known]
    if extra:
        raise ValueError(
            f"{source}: unexpected column(s) {', '.join(extra)} "
            "(the recording header is documented in docs/recordings.md)"
        )
    try:
        return Recording(**kw, meta=meta, check_units=check_units, _adopt=True)  # checked like any other file
    except (ValueError, TypeError) as exc:  # TypeError: a metadata value of the wrong kind
        raise ValueError(f"{source}: {exc}") from None


def _load_parquet(path, fh, pa, pq, check_units) -> Recording:
    """A quadest Parquet recording read column by column from the open file ``fh``."""
    try:
        pf = pq.ParquetFile(fh)
        names, rows_held = pf.schema_arrow.names, pf.metadata.num_rows
        raw = (pf.schema_arrow.metadata or {}).get(b"quadest")
    except (pa.ArrowException, OSError) as exc:
        raise ValueError(f"{path}: not a readable Parquet file ({str(exc).strip().splitlines()[0]})") from None
    try:
        head = json.loads(raw) if raw else {}
        meta = head.get("meta", {}) if isinstance(head, dict) else None
    except (ValueError, UnicodeDecodeError):
        meta = None
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: the quadest metadata of this Parquet file is damaged")
    rows = head.get("rows")
    if rows is not None and rows != rows_held:
        raise ValueError(f"{path}: holds {rows_held} rows but states {rows}: the file is damaged")

    def column(name):
        pa.default_memory_pool().release_unused()  # the columns read before, copied out: returned to the system
        try:
            col = pf.read(columns=[name]).column(0)
        except (pa.ArrowException, OSError) as exc:
            raise ValueError(f"{path}: not a readable Parquet file ({str(exc).strip().splitlines()[0]})") from None
        return numeric_column(path, name, col)

    return _from_columns(names, column, meta, path, check_units)


def values_sha256(rec: Recording) -> str:
    """The SHA-256 of ``rec``'s values, column by column in file order (each column's name,
    then its float64 values, every NaN as one NaN): what a CSV of it reads back as, whatever
    its line ends."""
    h = hashlib.sha256()
    for name, col in rec.columns().items():
        h.update(name.encode() + b"\0")
        col = np.asarray(col, dtype=np.float64)
        h.update(np.where(np.isnan(col), np.nan, col).tobytes())
    return h.hexdigest()


def _stated_meta(path: Path, beside: dict) -> dict:
    meta = beside.get("meta", {})
    if (
        not isinstance(meta, dict)
        or beside.get("format") != FORMAT_TAG
        or not isinstance(beside.get("values_sha256"), str)
    ):
        raise ValueError(f"{path}-metadata.json: damaged metadata; repair it, or delete it to read the CSV plain")
    return meta


def _check_values(path: Path, rec: Recording, beside: dict) -> Recording:
    """``rec`` once its values are those the CSV's metadata file states (a CSV cut short or
    changed since it was written is refused: its metadata may no longer hold)."""
    if beside.get("values_sha256") != values_sha256(rec):
        raise _not_as_written(path, beside)
    return rec


def _not_as_written(path: Path, beside: dict, held: int | None = None) -> ValueError:
    rows = beside.get("rows")
    holds = f"holds {held} rows, " if held is not None else ""
    return ValueError(
        f"{path}: not the file its metadata (.csv-metadata.json) describes ({holds}it states {rows} rows: cut "
        "short or changed since); read a complete copy, or delete the metadata file to read the rows as they are"
    )


def _commented(path: Path, data: bytes) -> tuple[dict, int | None, bytes]:
    """An earlier version's CSV (:data:`LEGACY_TAGS`): the metadata of its ``#`` lines, the rows
    it states and its body (a v2 file without its end line is cut short)."""
    meta, pos, tag = {}, 0, None
    while data.startswith(b"#", pos):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        line = data[pos + 1 : end].decode("utf-8", "replace").strip()
        pos = end + 1
        if line.startswith("quadest recording"):
            tag = line
            continue
        if ":" not in line:
            continue
        key, _, value = line.partition(":")
        try:
            meta[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            meta[key.strip()] = value.strip()
    if pos >= len(data):
        raise ValueError(f"{path}: no CSV header after the metadata lines")
    rows = meta.pop("rows", None)
    body = data[pos:]
    if tag is not None and tag != LEGACY_TAGS[0]:
        # v2: the file must end with its end line (then at most blank lines, and any line ends:
        # CRLF from an editor); a file cut anywhere lacks it
        end_at = body.rfind(b"\n" + END_MARK.encode())
        if end_at < 0 or not re.search(rb" rows\r?\n\s*\Z", body[end_at:]):
            raise ValueError(
                f"{path}: the file is cut short (its end line is missing"
                + (f"; it states {rows} rows)" if rows is not None else ")")
            )
        body = body[: end_at + 1]
    return meta, rows, body


def load_recording(path: str | Path, *, check_units: bool = True) -> Recording:
    """Read a recording written by :func:`save_recording` (CSV or Parquet, by extension). Its
    values are checked for unit mistakes like any other file's (``check_units=False`` reads
    what was written, whatever it holds)."""
    import pyarrow as pa

    path = Path(path)
    kind = _kind(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    if kind == "parquet":
        import pyarrow.parquet as pq

        with open(path, "rb") as fh:
            return _load_parquet(path, fh, pa, pq, check_units)
    import pyarrow.csv as pcsv

    data = path.read_bytes()
    beside = read_csv_metadata(path)
    if data.startswith(b"#"):
        beside = None  # an earlier version's: its metadata stands in it
    if beside is not None:
        meta, rows, body = (
            _stated_meta(path, beside),
            beside.get("rows"),
            data.rstrip() + b"\n",
        )  # an editor's blank end
    else:
        meta, rows, body = _commented(path, data)
    try:
        table = pcsv.read_csv(
            io.BytesIO(body), convert_options=pcsv.ConvertOptions(column_types={}, strings_can_be_null=True)
        )
    except pa.ArrowException as exc:
        if beside is not None:
            raise _not_as_written(path, beside) from None
        raise ValueError(f"{path}: malformed CSV ({str(exc).splitlines()[0]})") from None
    if rows is not None and rows != table.num_rows:
        if beside is not None:
            raise _not_as_written(path, beside, table.num_rows)
        raise ValueError(f"{path}: holds {table.num_rows} rows but states {rows}: the file is cut short or damaged")
    names = [c.strip() for c in table.column_names]
    if len(set(names)) != len(names):
        dup = sorted({c for c in names if names.count(c) > 1})
        raise ValueError(f"{path}: column(s) {', '.join(dup)} appear more than once")
    table = table.rename_columns(names)

    rec = _from_columns(names, lambda c: numeric_column(path, c, table.column(c)), meta, path, check_units)
    return rec if beside is None else _check_values(path, rec, beside)
