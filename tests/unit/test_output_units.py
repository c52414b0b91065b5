"""An estimate's file says what it holds: each column's unit and frame in a Parquet file's schema
or beside a CSV in its CSV-on-the-Web metadata (docs/reliability.md, *Nothing silent*), the
values as before."""

import json
import os
import threading

import numpy as np
import pyarrow.parquet as pq

from quadest.cli.recordings import ATTITUDE_UNITS, attitude_blocks
from quadest.data import write_blocks


def _estimate(n=1000):
    rng = np.random.default_rng(0)
    q = rng.normal(size=(n, 4))
    return np.arange(n) / 200.0, q / np.linalg.norm(q, axis=1, keepdims=True)


def test_an_estimates_parquet_schema_holds_units_and_frames(tmp_path):
    """Before: no metadata at all (radians were said only on stdout)."""
    t, q = _estimate()
    p = write_blocks(attitude_blocks(t, q, rows=300), tmp_path / "e.parquet", units=ATTITUDE_UNITS)
    schema = pq.read_schema(p)
    assert schema.field("yaw").metadata[b"unit"].decode().startswith("rad (ZYX")
    assert b"NED" in schema.field("q_w").metadata[b"unit"] and schema.field("t").metadata[b"unit"].startswith(b"s")
    assert json.loads(schema.metadata[b"quadest_units"]) == ATTITUDE_UNITS
    table = pq.read_table(p)  # the values are those written, in four blocks
    assert table.num_rows == len(t) and np.array_equal(table.column("q_x").to_numpy(), q[:, 1])


def test_a_csv_estimate_keeps_its_plain_header_and_states_its_units_beside_it(tmp_path):
    """Before: a CSV estimate's units were said only on stdout."""
    import pandas as pd

    t, q = _estimate(10)
    p = write_blocks(attitude_blocks(t, q), tmp_path / "e.csv", units=ATTITUDE_UNITS)
    assert p.read_text().splitlines()[0] == "t,q_w,q_x,q_y,q_z,roll,pitch,yaw"
    side = json.loads((tmp_path / "e.csv-metadata.json").read_text())
    assert side["url"] == "e.csv" and side["quadest"]["rows"] == 10
    columns = side["tableSchema"]["columns"]
    assert [c["name"] for c in columns] == list(pd.read_csv(p).columns)
    assert {c["name"]: c["dc:description"] for c in columns} == ATTITUDE_UNITS


def test_a_csv_written_to_a_stream_has_nothing_beside_it(tmp_path):
    fifo = tmp_path / "e.csv"
    os.mkfifo(fifo)
    got = {}
    reader = threading.Thread(target=lambda: got.setdefault("text", fifo.read_text()))
    reader.start()
    write_blocks(attitude_blocks(*_estimate(5)), fifo, units=ATTITUDE_UNITS)
    reader.join(10)
    assert got["text"].startswith("t,q_w") and not (tmp_path / "e.csv-metadata.json").exists()
