"""Writing a table of named columns (an estimate's attitude, for example) to CSV or Parquet."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from quadest.data.files import atomic_output


def write_table(cols: dict, path: str | Path, *, units: dict | None = None) -> Path:
    """``{name: 1-D array}`` to ``.csv`` (a plain header line, then the values) or ``.parquet``,
    atomically (:func:`quadest.data.files.atomic_output`). ``units``: ``{name: "unit (frame)"}``,
    kept in a Parquet file's schema (:func:`described`)."""
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
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq"):
        raise ValueError(f"{path}: use .csv or .parquet")
    import pyarrow as pa  # loaded when a table is written, not by `import quadest`
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    with atomic_output(path) as tmp, open(tmp, "wb") as fh:  # a file object: pyarrow takes only UTF-8 names
        writer = None
        for cols in blocks:
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
            pa.default_memory_pool().release_unused()  # a block's buffers, written: returned to the system
        if writer is None:
            raise ValueError(f"{path}: no rows to write")
        writer.close()
    return path


def use_system_allocator() -> None:
    """Give pyarrow the system's allocator: its default (mimalloc) keeps the pages it has freed
    for its own reuse, so a recording read column by column stays held twice over in part (10⁷
    rows: 0.12 GiB more at ``quadest report``'s peak). The command line calls this once; a
    library user's process keeps its own choice."""
    import pyarrow as pa

    pa.set_memory_pool(pa.system_memory_pool())
