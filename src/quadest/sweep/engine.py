"""Executing many runs: in this process, on a local Dask cluster, or on an existing one
(docs/sweeps.md).

Results go to one Parquet file, one row per run, written as runs finish: every few seconds the
rows that came in are flushed as a part file beside it (``<file>.parts/``), and the parts are
folded into the file when the sweep ends. A sweep started again on the same file skips the runs
already recorded (in the file or in parts a killed sweep left), so an interrupted sweep resumes
without redoing finished runs.
Each run's row is written once: Dask may execute a task twice when a worker dies, but the
client receives each future's result once, and only the client writes.
"""

from __future__ import annotations

import hashlib
import os
import time
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from quadest.evaluation.parallel import execute
from quadest.sweep.runs import empty_row, group_runs, row_types, run_group, run_id

if TYPE_CHECKING:
    import pyarrow as pa


# -- the result store ---------------------------------------------------------------------------------
class ResultStore:
    """One Parquet file of results, one row per run. While a sweep runs, rows go to part files
    in ``<file>.parts/`` as they arrive; when it ends they are folded into the file and the
    folder is removed. A sweep that was killed leaves its parts, and the next one reads them."""

    def __init__(self, path: str | Path, flush_s: float = 2.0, flush_rows: int = 200):
        self.path = Path(path)
        if self.path.is_dir():
            raise ValueError(f"{path}: is a folder; give the results file to write (e.g. results.parquet)")
        self.parts = self.path.with_name(self.path.name + ".parts")
        self.flush_s, self.flush_rows = flush_s, flush_rows
        self._buf: list[dict] = []
        self._last = time.monotonic()
        self._session = uuid.uuid4().hex[:8]
        self._n = 0

    def check_layout(self, row_types: dict) -> None:
        """Refuse, before anything is written, a results file (or a killed sweep's parts) whose
        columns are not a sweep's (another program's Parquet file, or an older layout): appending
        to it would fail half-way and leave parts behind."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        files = ([self.path] if self.path.is_file() else []) + sorted(self.parts.glob("part-*.parquet"))
        for p in files:
            try:
                schema = pq.read_schema(p)
            except (pa.ArrowException, OSError) as exc:
                if p == self.path:
                    raise ValueError(f"{p}: not a readable results file ({exc}); give another -o") from None
                continue
            have = {f.name: str(f.type) for f in schema}
            wrong = [f"{c} ({have.get(c, 'missing')}, not {t})" for c, t in row_types.items() if have.get(c) != t]
            if wrong:
                raise ValueError(
                    f"{p}: not a results file of this quadest's sweeps (columns {', '.join(wrong[:4])}"
                    f"{' ...' if len(wrong) > 4 else ''}); give another -o, or move it away"
                )

    def _tables(self):
        import pyarrow as pa
        import pyarrow.parquet as pq

        files = ([self.path] if self.path.is_file() else []) + sorted(self.parts.glob("part-*.parquet"))
        tables = []
        for p in files:
            try:
                tables.append(pq.read_table(p))
            except (pa.ArrowException, OSError) as exc:
                if p == self.path:
                    raise ValueError(f"{p}: not a readable results file ({exc})") from None
                continue  # a part cut by a crash: its runs are simply run again
        return tables

    def raw(self) -> pa.Table | None:
        """Every row written, in order (None if none)."""
        import pyarrow as pa

        tables = self._tables()
        return pa.concat_tables(tables, promote_options="default") if tables else None

    def read(self) -> pa.Table | None:
        """The results: the latest row of each run (None if empty)."""
        t = self.raw()
        if t is None:
            return None
        ids = t.column("run_id").to_pylist()
        last = {rid: i for i, rid in enumerate(ids)}
        return t if len(last) == len(ids) else t.take(sorted(last.values()))

    def done_ids(self, retry_failed: bool = False) -> set:
        t = self.read()
        if t is None:
            return set()
        ids, status = t.column("run_id").to_pylist(), t.column("status").to_pylist()
        return {i for i, s in zip(ids, status) if s == "ok" or not retry_failed}

    def add(self, row: dict) -> None:
        self._buf.append(row)
        if len(self._buf) >= self.flush_rows or time.monotonic() - self._last > self.flush_s:
            self.flush()

    def flush(self) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._last = time.monotonic()
        if not self._buf:
            return
        self.parts.mkdir(parents=True, exist_ok=True)
        table = pa.Table.from_pylist(self._buf)
        name = self.parts / f"part-{time.strftime('%Y%m%dT%H%M%S')}-{self._session}-{self._n:05d}.parquet"
        tmp = name.with_suffix(".tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, name)  # a part appears whole or not at all
        self._n += 1
        self._buf = []

    def compact(self) -> None:
        """Fold the parts into the results file (atomically) and remove them. A failed row that
        a later row of the same run replaced (``--retry-failed``) is dropped; nothing else is."""
        import shutil

        import pyarrow.parquet as pq

        self.flush()
        if not self.parts.is_dir():
            return
        t = self.raw()
        if t is not None:
            ids, status = t.column("run_id").to_pylist(), t.column("status").to_pylist()
            last = {rid: i for i, rid in enumerate(ids)}
            keep = [i for i, (rid, st) in enumerate(zip(ids, status)) if not (st == "failed" and last[rid] != i)]
            if len(keep) != len(ids):
                t = t.take(keep)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            tmp = self.path.with_name(self.path.name + ".tmp")
            pq.write_table(t, tmp)
            os.replace(tmp, self.path)
        shutil.rmtree(self.parts, ignore_errors=True)


def run_sweep(
    runs: Sequence[dict],
    out: str | Path,
    *,
    workers: int | None = 0,
    scheduler: str | None = None,
    retry_failed: bool = False,
    progress: bool = True,
) -> dict:
    """Execute the runs not yet in ``out`` and append their rows. Returns counts and timing.
    Runs on the same flight go to one task (up to 32 runs), so each flight is simulated or
    read once; rows are still written one per run as the tasks finish."""
    store = ResultStore(out)
    store.check_layout(row_types(runs))
    done_before = store.done_ids(retry_failed)
    todo = [r for r in runs if run_id(r) not in done_before]
    ids = [run_id(r) for r in todo]
    if len(set(ids)) != len(ids):  # the same run twice in one grid
        seen = set()
        todo = [r for r, i in zip(todo, ids) if not (i in seen or seen.add(i))]
        ids = [run_id(r) for r in todo]

    groups = group_runs(todo)
    group_keys = [hashlib.sha1("".join(run_id(r) for r in g).encode()).hexdigest()[:16] for g in groups]

    def on_result(i, rows):
        if isinstance(rows, BaseException):  # the task itself was lost (e.g. its worker died 3 times)
            rows = [empty_row(spec, f"{type(rows).__name__}: {rows}") for spec in groups[i]]
        for row in rows:
            store.add(row)
            new_ok[0] += row.get("status") == "ok"

    new_ok = [0]
    t0 = time.perf_counter()
    stats: dict = {}
    try:
        execute(
            run_group,
            groups,
            keys=group_keys,
            workers=workers,
            scheduler=scheduler,
            on_result=on_result,
            progress=progress,
            desc="sweep",
            stats=stats,
            weights=[len(g) for g in groups],
        )
    finally:
        store.compact()  # also on Ctrl-C; a killed process leaves its parts for the next sweep
    wall = time.perf_counter() - t0
    compute = stats.get("compute_s", wall)
    table = store.read()
    status = table.column("status").to_pylist() if table is not None else []
    return {
        "runs": len(runs),
        "skipped": len(runs) - len(todo),
        "executed": len(todo),
        "wall_s": wall,
        "compute_s": compute,
        "runs_per_s": len(todo) / compute if compute > 0 and todo else float("nan"),
        "ok": status.count("ok"),
        "failed": status.count("failed"),
        "executed_ok": new_ok[0],
    }
