"""Executing many runs: in this process, on a local Dask cluster, or on an existing one
(docs/sweeps.md).

Results go to a Parquet dataset (a folder of part files, readable as one table by
``pyarrow.parquet.read_table(folder)``), written as runs finish: every few seconds the rows
that came in are flushed as a new part. A sweep started again on the same folder skips the
runs already recorded there, so an interrupted sweep resumes without redoing finished runs.
Each run's row is written once: Dask may execute a task twice when a worker dies, but the
client receives each future's result once, and only the client writes.
"""
from __future__ import annotations

import hashlib
import os
import time
import uuid
from contextlib import contextmanager
from pathlib import Path

import numpy as np


# -- the result store ---------------------------------------------------------------------------------
class ResultStore:
    """A Parquet dataset folder; rows are appended as part files."""

    def __init__(self, path, flush_s: float = 2.0, flush_rows: int = 200):
        self.path = Path(path)
        if self.path.exists() and not self.path.is_dir():
            raise ValueError(f"{path}: exists and is not a results folder (sweeps write a Parquet folder)")
        self.path.mkdir(parents=True, exist_ok=True)
        self.flush_s, self.flush_rows = flush_s, flush_rows
        self._buf: list[dict] = []
        self._last = time.monotonic()
        self._session = uuid.uuid4().hex[:8]
        self._n = 0

    def read(self):
        """All rows so far as a pyarrow Table, the latest row per run_id (None if empty)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        parts = sorted(self.path.glob("part-*.parquet"))
        if not parts:
            return None
        tables = []
        for p in parts:
            try:
                tables.append(pq.read_table(p))
            except (pa.ArrowException, OSError):  # a part cut by a crash: its runs are redone
                continue
        if not tables:
            return None
        t = pa.concat_tables(tables, promote_options="default")
        ids = t.column("run_id").to_pylist()
        last = {rid: i for i, rid in enumerate(ids)}
        if len(last) != len(ids):
            t = t.take(sorted(last.values()))
        return t

    def done_ids(self, retry_failed: bool = False) -> set:
        t = self.read()
        if t is None:
            return set()
        ids, status = t.column("run_id").to_pylist(), t.column("status").to_pylist()
        return {i for i, s in zip(ids, status) if s == "ok" or not retry_failed}

    def add(self, row: dict):
        self._buf.append(row)
        if len(self._buf) >= self.flush_rows or time.monotonic() - self._last > self.flush_s:
            self.flush()

    def flush(self):
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._last = time.monotonic()
        if not self._buf:
            return
        table = pa.Table.from_pylist(self._buf)
        name = self.path / f"part-{time.strftime('%Y%m%dT%H%M%S')}-{self._session}-{self._n:05d}.parquet"
        tmp = name.with_suffix(".tmp")
        pq.write_table(table, tmp)
        os.replace(tmp, name)  # a part appears whole or not at all
        self._n += 1
        self._buf = []


# -- execution -------------------------------------------------------------------------------------------
@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None):
    """A client on ``scheduler`` (tcp://host:port), or on a local cluster of ``workers``
    single-threaded worker processes (default: one per core)."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except OSError as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
        try:
            yield client
        finally:
            client.close()
        return
    import dask

    n = workers or os.cpu_count() or 1
    # Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in its workers, which switches off glibc's
    # adaptive mmap threshold: every array above 128 KiB is then mapped and unmapped anew, and
    # the simulator and filters ran 1.9x slower per run than in this process (measured). The
    # workers here keep glibc's defaults (docs/sweeps.md says how for a cluster of your own).
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}), \
            LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                         silence_logs=40) as cluster, Client(cluster) as client:
        yield client


def execute(fn, items, *, keys=None, workers: int | None = 0, scheduler: str | None = None, on_result=None,
            progress: bool = False, desc: str = "runs", max_inflight: int | None = None, stats: dict | None = None,
            weights=None):
    """Apply ``fn`` to every item; ``workers=0`` (and no scheduler) runs in this process,
    otherwise on Dask (``workers=None``: a local cluster with one worker per core). ``on_result(item_index, result_or_exception)`` is called as results
    arrive (in completion order); returns the results in item order. Exceptions from a task
    (a lost worker, a failing function) are passed on as values, never raised. ``stats`` gets
    ``compute_s``: the time from the first task to the last result, without the cluster's
    start-up. ``weights``: how many runs each item holds (for the progress bar)."""
    from tqdm.auto import tqdm

    items = list(items)
    results: list = [None] * len(items)
    failed = 0
    bar = tqdm(total=sum(weights) if weights else len(items), unit="run", desc=desc, disable=not progress,
               smoothing=0.1)

    def done(i, r):
        nonlocal failed
        results[i] = r
        n = weights[i] if weights else 1
        if isinstance(r, BaseException):
            failed += n
        elif isinstance(r, dict):
            failed += r.get("status") == "failed"
        elif isinstance(r, list):
            failed += sum(isinstance(x, dict) and x.get("status") == "failed" for x in r)
        if on_result is not None:
            on_result(i, r)
        bar.set_postfix(done=bar.n + n - failed, failed=failed, refresh=False)
        bar.update(n)

    stats = stats if stats is not None else {}
    try:
        if not items:
            stats["compute_s"] = 0.0
            return results
        if not scheduler and workers == 0:
            t0 = time.perf_counter()
            for i, item in enumerate(items):
                try:
                    r = fn(item)
                except Exception as exc:
                    r = exc
                done(i, r)
            stats["compute_s"] = time.perf_counter() - t0
            return results
        from dask.distributed import as_completed

        with dask_client(workers, scheduler) as client:
            nthreads = sum(client.nthreads().values()) or 1
            limit = max_inflight or max(16, 8 * nthreads)
            index = {}
            pending = iter(range(len(items)))
            ac = as_completed()
            t0 = time.perf_counter()

            def submit_next():
                i = next(pending, None)
                if i is None:
                    return False
                key = f"quadest-{keys[i]}" if keys else None
                fut = client.submit(fn, items[i], key=key, pure=False) if key else client.submit(fn, items[i], pure=False)
                index[fut.key] = i
                ac.add(fut)
                return True

            for _ in range(limit):
                if not submit_next():
                    break
            for fut in ac:
                i = index.pop(fut.key)
                try:
                    r = fut.result()
                except Exception as exc:  # KilledWorker, CancelledError, the function's own error
                    r = exc
                fut.release()
                done(i, r)
                submit_next()
            stats["compute_s"] = time.perf_counter() - t0
        return results
    finally:
        bar.close()


def run_sweep(runs, out, *, workers: int | None = 0, scheduler: str | None = None, retry_failed: bool = False,
              progress: bool = True) -> dict:
    """Execute the runs not yet in ``out`` and append their rows. Returns counts and timing.
    Runs on the same flight go to one task (up to 32 runs), so each flight is simulated or
    read once; rows are still written one per run as the tasks finish."""
    from quadest.sweep.runs import group_runs, run_group, run_id

    store = ResultStore(out)
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
            from quadest.sweep.runs import METRICS, source_label

            rows = [{"run_id": run_id(spec), "filter": spec["filter"], "params": _json(spec["params"]),
                     "source": source_label(spec["source"]), "seed": spec["source"].get("seed", -1),
                     "spec": _json(spec), "status": "failed", "error": f"{type(rows).__name__}: {rows}",
                     **{k: np.nan for k in METRICS}, "samples": 0, "seconds": np.nan} for spec in groups[i]]
        for row in rows:
            store.add(row)

    t0 = time.perf_counter()
    stats: dict = {}
    try:
        execute(run_group, groups, keys=group_keys, workers=workers, scheduler=scheduler, on_result=on_result,
                progress=progress, desc="sweep", stats=stats, weights=[len(g) for g in groups])
    finally:
        store.flush()
    wall = time.perf_counter() - t0
    compute = stats.get("compute_s", wall)
    table = store.read()
    status = table.column("status").to_pylist() if table is not None else []
    return {"runs": len(runs), "skipped": len(runs) - len(todo), "executed": len(todo), "wall_s": wall,
            "compute_s": compute, "runs_per_s": len(todo) / compute if compute > 0 and todo else float("nan"),
            "ok": status.count("ok"), "failed": status.count("failed")}


def _json(x):
    import json

    return json.dumps(x, sort_keys=True)
