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
import json
import logging
import os
import time
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import TYPE_CHECKING

from quadest.data.files import atomic_output, exclusive_lock, output_target
from quadest.evaluation.parallel import execute
from quadest.sweep.runs import empty_row, group_runs, row_types, run_group, run_id

LOG = logging.getLogger(__name__)

if TYPE_CHECKING:
    import pyarrow as pa


# -- the result store ---------------------------------------------------------------------------------
CHECKSUM = "checksum"
"""The column holding each row's checksum (:func:`row_checksum`): a row that does not match it
was damaged on disk, and its run is run again."""

ROW_GROUP = 1000
"""Rows per Parquet row group of a results file: damage that makes a group unreadable costs the
runs of that group (run again), not the file."""


def row_checksum(row: dict) -> str:
    """A digest of every value of a row (but its checksum), as Arrow reads it back."""
    values = [[k, row[k]] for k in sorted(row) if k != CHECKSUM]
    return hashlib.blake2b(json.dumps(values, default=str).encode(), digest_size=8).hexdigest()


def with_checksums(table: pa.Table) -> pa.Table:
    """``table`` with a checksum for each row that has none (new rows; rows of older files)."""
    import pyarrow as pa

    rows = table.to_pylist()
    sums = [r.get(CHECKSUM) or row_checksum(r) for r in rows]
    if CHECKSUM in table.column_names:
        table = table.drop_columns([CHECKSUM])
    return table.append_column(CHECKSUM, pa.array(sums, pa.string()))


def _has_parquet_magic(path: Path) -> bool:
    """Whether a file begins or ends as Parquet does (``PAR1``): a Parquet file, if damaged."""
    with open(path, "rb") as f:
        head = f.read(4)
        f.seek(max(0, path.stat().st_size - 4))
        return b"PAR1" in (head, f.read(4))


def _layout(table: pa.Table) -> frozenset:
    return frozenset(table.column_names) - {CHECKSUM}


def _writer_gone(part: Path) -> bool:
    """Whether the process that was writing a part's temporary file (its pid is in the name) has
    ended: then the file is a leftover of a killed sweep."""
    try:
        os.kill(int(part.name.split("-")[2]), 0)
    except (IndexError, ValueError, ProcessLookupError):
        return True
    except PermissionError:  # another user's live process
        return False
    return False


class ResultStore:
    """One Parquet file of results, one row per run, each row with its checksum. While a sweep
    runs it holds the file's lock (:meth:`writing`; a second sweep on the same file waits), rows
    go to part files in ``<file>.parts/`` (named by process) as they arrive, and when it ends the
    parts are folded into the file and removed. A sweep that was killed leaves its parts, and the
    next one reads them. A damaged row (its checksum does not match), row group or part is left
    out, counted in :attr:`damaged`, and its run is run again."""

    def __init__(self, path: str | Path, flush_s: float = 2.0, flush_rows: int = 200):
        self.path = Path(path)
        if self.path.is_dir():
            raise ValueError(f"{path}: is a folder; give the results file to write (e.g. results.parquet)")
        self.parts = self.path.with_name(self.path.name + ".parts")
        self.lock = self.path.with_name(self.path.name + ".lock")
        self.flush_s, self.flush_rows = flush_s, flush_rows
        self._buf: list[dict] = []
        self._last = time.monotonic()
        self._session = f"{os.getpid()}-{uuid.uuid4().hex[:8]}"
        self._n = 0
        self.damaged = 0
        """Rows (or parts) found damaged by the last read: left out, their runs to be run again."""

    @contextmanager
    def writing(self) -> Iterator[ResultStore]:
        """Hold the results file's lock for the block: one sweep writes a results file at a time;
        another waits (saying so on stderr) until this one has folded its parts in."""

        def say_waiting(pid):
            LOG.warning(
                f"quadest: {self.path} is being written by another sweep (process {pid}); "
                "waiting for it to end (Ctrl-C to stop)"
            )

        output_target(self.path)  # a results file that cannot be written is refused before the wait
        with exclusive_lock(self.lock, on_wait=say_waiting):
            yield self

    def _files(self) -> list[Path]:
        return ([self.path] if self.path.is_file() else []) + sorted(self.parts.glob("part-*.parquet"))

    def check_layout(self, row_types: dict) -> None:
        """Before anything is written: refuse a results file whose columns are not a sweep's
        (another program's Parquet file, or an older layout: appending to it would fail half-way
        and leave parts behind). A results file damaged beyond reading (its footer, or a few of its
        column names) is moved aside to ``<file>.damaged``, said on stderr, and its runs are run
        again. A part with other columns is damaged, and left out when read."""
        problem = self._layout_problem(row_types)
        if problem is None:
            return
        damaged, what = problem
        if not damaged:
            raise ValueError(f"{self.path}: {what}; give another -o, or move it away")
        aside = self.path.with_name(self.path.name + ".damaged")
        n = 1
        while aside.exists():
            aside, n = self.path.with_name(f"{self.path.name}.damaged-{n}"), n + 1
        os.replace(self.path, aside)
        self.damaged += 1
        LOG.warning(f"quadest: warning: {self.path}: {what}; moved to {aside.name}, and its runs are run again")

    def _layout_problem(self, row_types: dict) -> tuple[bool, str] | None:
        """``(damaged, what)`` when the results file cannot be appended to, else None."""
        import pyarrow.parquet as pq

        if not self.path.is_file():
            return None
        try:
            schema = pq.read_schema(self.path)
        except Exception as exc:  # noqa: BLE001 (whatever a damaged footer raises)
            return _has_parquet_magic(self.path), f"not a readable results file ({str(exc).strip()[:80]})"
        have = {f.name: str(f.type) for f in schema}
        older = len(have) == len(row_types) and CHECKSUM not in have  # written before rows had checksums
        want = row_types if older else {**row_types, CHECKSUM: "string"}
        wrong = [f"{c} ({have.get(c, 'missing')}, not {t})" for c, t in want.items() if have.get(c) != t]
        if not wrong:
            return None
        missing = [c for c in want if c not in have]
        if len(wrong) == len(missing) and set(have) <= set(want):  # columns added since: nothing is wrong in it
            return False, f"written by an earlier quadest, without {', '.join(missing)} (quadest report reads it)"
        damaged = len(have) == len(want) and len(wrong) <= 2  # a sweep's file, a few names or types changed
        what = "columns damaged" if damaged else "not a results file of this quadest's sweeps"
        return damaged, f"{what} ({', '.join(wrong[:4])}{' ...' if len(wrong) > 4 else ''})"

    def _verified(self, table: pa.Table) -> pa.Table:
        """The rows whose checksum matches (all of a file written before checksums)."""
        if CHECKSUM not in table.column_names:
            return table
        rows = table.to_pylist()
        keep = [i for i, r in enumerate(rows) if r[CHECKSUM] == row_checksum(r)]
        self.damaged += len(rows) - len(keep)
        return table if len(keep) == len(rows) else table.take(keep)

    def _read_file(self, p: Path) -> list:
        """A file's verified row groups; a row group that cannot be read counts as damaged. A
        results file whose footer cannot be read is refused; such a part is damaged."""
        import pyarrow.parquet as pq

        try:
            f = pq.ParquetFile(p)
            n = f.num_row_groups
        except Exception as exc:  # noqa: BLE001 (whatever a damaged footer raises)
            if p == self.path:
                raise ValueError(
                    f"{p}: not a readable results file ({exc}); give another -o, or move it away"
                ) from None
            self.damaged += 1
            return []
        tables = []
        for i in range(n):
            try:
                tables.append(self._verified(f.read_row_group(i)))
            except Exception:  # noqa: BLE001 (a damaged page: pyarrow raises several kinds)
                self.damaged += max(1, f.metadata.row_group(i).num_rows)
        return tables

    def _tables(self, files=None):
        self.damaged = 0
        tables = [t for p in (self._files() if files is None else files) for t in self._read_file(p)]
        layouts = [_layout(t) for t in tables]
        if len(set(layouts)) > 1:  # a table of another layout than most (a damaged footer's names) is damaged
            most = max(set(layouts), key=layouts.count)
            self.damaged += sum(t.num_rows for t, lay in zip(tables, layouts) if lay != most)
            tables = [t for t, lay in zip(tables, layouts) if lay == most]
        return tables

    def raw(self) -> pa.Table | None:
        """Every undamaged row written, in order (None if none)."""
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
        """Write the rows that came in as a new part file (``part-TIME-PID-RANDOM-N``: this
        process's own), with their checksums; it appears whole or not at all."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._last = time.monotonic()
        if not self._buf:
            return
        self.parts.mkdir(exist_ok=True)
        table = with_checksums(pa.Table.from_pylist(self._buf))
        name = self.parts / f"part-{time.strftime('%Y%m%dT%H%M%S')}-{self._session}-{self._n:05d}.parquet"
        tmp = name.with_suffix(".tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, name)
        self._n += 1
        self._buf = []

    def compact(self) -> None:
        """Fold the parts into the results file (atomically) and remove the parts read, and
        nothing else (call it holding the lock, :meth:`writing`). A failed row that a later row
        of the same run replaced (``--retry-failed``) is dropped, as are damaged rows."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        self.flush()
        if not self.parts.is_dir():
            return
        files = self._files()
        tables = self._tables(files)
        if tables:
            t = pa.concat_tables(tables, promote_options="default")
            ids, status = t.column("run_id").to_pylist(), t.column("status").to_pylist()
            last = {rid: i for i, rid in enumerate(ids)}
            keep = [i for i, (rid, st) in enumerate(zip(ids, status)) if not (st == "failed" and last[rid] != i)]
            t = with_checksums(t if len(keep) == len(ids) else t.take(keep))
            with atomic_output(self.path) as tmp:
                pq.write_table(t, tmp, row_group_size=ROW_GROUP)
        for p in files + [t for t in self.parts.glob("part-*.tmp") if _writer_gone(t)]:
            if p != self.path:
                p.unlink(missing_ok=True)
        with suppress(OSError):  # left when a part of another writer (or anything else) is in it
            self.parts.rmdir()


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
    with store.writing():
        return _run_locked(store, runs, workers, scheduler, retry_failed, progress)


def _run_locked(store: ResultStore, runs, workers, scheduler, retry_failed: bool, progress: bool) -> dict:
    """:func:`run_sweep` once it holds the results file's lock."""
    store.check_layout(row_types(runs))
    done_before = store.done_ids(retry_failed)
    damaged = store.damaged  # rows or parts found damaged: their runs are not done, and run again
    if damaged:
        LOG.warning(
            f"quadest: warning: {store.path}: {damaged} damaged row(s) or part(s) found (checksum or format); "
            "their runs are run again"
        )
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
        "damaged": damaged,
    }
