"""Writing a table of named columns (an estimate's attitude, for example) to CSV or Parquet, each
column's unit and frame kept with it: in a Parquet file's schema, beside a CSV in its
CSV-on-the-Web metadata file (``NAME.csv-metadata.json``, :func:`write_csv_metadata`), so that
the CSV itself stays plain for any reader."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path

from quadest.data.files import DESCRIPTORS, atomic_output, dumps_json, output_target, write_bytes

CSV_METADATA_SUFFIX = "-metadata.json"
"""W3C CSV on the Web's name for a CSV's metadata file: ``NAME.csv-metadata.json`` beside it."""
CSVW_CONTEXT = "http://www.w3.org/ns/csvw"


def csv_metadata_path(path) -> Path:
    """The metadata file of the CSV ``path`` (:data:`CSV_METADATA_SUFFIX`), beside the file the
    name leads to (a link's target)."""
    path = Path(path)
    real = Path(os.path.realpath(path)) if path.is_symlink() else path
    return real.with_name(real.name + CSV_METADATA_SUFFIX)


def check_csv_metadata_target(path) -> None:
    """Before a CSV is written: refuse (ValueError, one line) a metadata file that could not be
    written beside it, so that the CSV is not replaced and then left without its metadata."""
    if str(path) in DESCRIPTORS or output_target(path).stream:
        return
    output_target(csv_metadata_path(path))


def write_csv_metadata(path, names, units: dict | None, quadest: dict) -> Path | None:
    """Beside the CSV ``path`` (written), its CSV-on-the-Web metadata: each column's name and
    unit (``dc:description``), and under ``quadest`` what quadest reads back (``quadest``:
    the rows' count, a recording's metadata and checksum). None for a CSV written to a stream
    (a FIFO, a descriptor): there is nothing beside it."""
    if output_target(path).stream:
        return None
    units = units or {}
    columns = [{"name": n, "titles": n, "datatype": "double", "dc:description": units.get(n, "")} for n in names]
    doc = {
        "@context": CSVW_CONTEXT,
        "url": Path(path).name,
        "dialect": {"header": True, "delimiter": ","},
        "tableSchema": {"columns": columns},
        "quadest": quadest,
    }
    return write_bytes(csv_metadata_path(path), (dumps_json(doc) + "\n").encode())


def read_csv_metadata(path) -> dict | None:
    """The ``quadest`` part of the CSV ``path``'s metadata file, None when it has none;
    ValueError (one line, naming the file) when it is damaged."""
    side = csv_metadata_path(path)
    if not side.is_file():
        return None
    try:
        part = json.loads(side.read_bytes())["quadest"]
    except (ValueError, KeyError, TypeError, UnicodeDecodeError, RecursionError):
        part = None
    rows = part.get("rows") if isinstance(part, dict) else None
    if not isinstance(part, dict) or not (isinstance(rows, int) and not isinstance(rows, bool) and 0 <= rows < 2**63):
        raise ValueError(
            f"{side}: damaged metadata of {Path(path).name}; repair it, or delete it to read the CSV plain"
        )
    return part


def write_table(cols: dict, path: str | Path, *, units: dict | None = None) -> Path:
    """``{name: 1-D array}`` to ``.csv`` (a plain header line, then the values) or ``.parquet``,
    atomically (:func:`quadest.data.files.atomic_output`). ``units``: ``{name: "unit (frame)"}``,
    kept in a Parquet file's schema (:func:`described`) or a CSV's metadata file
    (:func:`write_csv_metadata`)."""
    return write_blocks([cols], path, units=units)


def described(schema, units: dict | None):
    """``schema`` with each named column's unit (and frame) in its field's metadata
    (``b"unit"``) and all of them, as JSON, in the schema's (``b"quadest_units"``): what a
    Parquet reader (pyarrow, pandas, polars) shows beside the values."""
    if not units:
        return schema
    import json

    import pyarrow as pa

    fields = [f.with_metadata({"unit": units[f.name]}) if f.name in units else f for f in schema]
    held = {name: unit for name, unit in units.items() if name in schema.names}
    return pa.schema(fields, metadata={"quadest_units": json.dumps(held)})


def write_blocks(blocks: Iterable[dict], path: str | Path, *, units: dict | None = None) -> Path:
    """Consecutive blocks of rows, each ``{name: 1-D array}`` with the same names, written as
    :func:`write_table` writes one: a long table is never held whole."""
    path = Path(path)
    suffix = ".csv" if str(path) in DESCRIPTORS and not path.suffix else path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq"):
        raise ValueError(f"{path}: use .csv or .parquet")
    import pyarrow as pa  # loaded when a table is written, not by `import quadest`
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    rows, names = 0, []
    if suffix == ".csv" and units:
        check_csv_metadata_target(path)
    with (
        atomic_output(path, suffix=suffix) as tmp,
        open(tmp, "wb") as fh,
    ):  # a file object: pyarrow takes only UTF-8 names
        writer = None
        for cols in blocks:
            names = list(cols)
            table = pa.table(cols)
            if suffix == ".csv":
                if writer is None:  # pyarrow quotes header names; write a plain header ourselves
                    fh.write((",".join(cols) + "\n").encode())
                    writer = pcsv.CSVWriter(
                        fh, table.schema, write_options=pcsv.WriteOptions(include_header=False, quoting_style="none")
                    )
            elif writer is None:
                writer = pq.ParquetWriter(fh, described(table.schema, units))
            if suffix != ".csv":
                table = table.replace_schema_metadata(None).cast(writer.schema)
            writer.write_table(table)
            rows += table.num_rows
            pa.default_memory_pool().release_unused()  # a block's buffers, written: returned to the system
        if writer is None:
            raise ValueError(f"{path}: no rows to write")
        writer.close()
    if suffix == ".csv" and units:
        write_csv_metadata(path, names, units, {"rows": rows})
    return path


def use_system_allocator() -> None:
    """Give pyarrow the system's allocator: its default (mimalloc) keeps the pages it has freed
    for its own reuse, so a recording read column by column stays held twice over in part (10⁷
    rows: 0.12 GiB more at ``quadest report``'s peak). The command line calls this once; a
    library user's process keeps its own choice."""
    import pyarrow as pa

    pa.set_memory_pool(pa.system_memory_pool())
