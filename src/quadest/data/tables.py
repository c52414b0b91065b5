"""Writing a table of named columns (an estimate's attitude, for example) to CSV or Parquet."""

from __future__ import annotations

from pathlib import Path

from quadest.data.files import atomic_output


def write_table(cols: dict, path: str | Path) -> Path:
    """``{name: 1-D array}`` to ``.csv`` (a plain header line, then the values) or ``.parquet``,
    atomically (:func:`quadest.data.files.atomic_output`)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".parquet", ".pq"):
        raise ValueError(f"{path}: use .csv or .parquet")
    import pyarrow as pa  # loaded when a table is written, not by `import quadest`
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    table = pa.table(cols)
    with atomic_output(path) as tmp:
        if suffix == ".csv":
            with open(tmp, "wb") as fh:  # pyarrow quotes header names; write a plain header ourselves
                fh.write((",".join(cols) + "\n").encode())
                pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))
        else:
            with open(tmp, "wb") as fh:  # a file object: pyarrow takes only UTF-8 names
                pq.write_table(table, fh)
    return path
