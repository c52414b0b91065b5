"""Running many independent tasks: in this process, on a local Dask cluster, or on an existing
one (docs/sweeps.md). Used by the paper reproductions and by sweeps; the tasks carry their
seeds, so results do not depend on where they run."""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from contextlib import contextmanager
from typing import Any

from quadest.extras import need
from quadest.progress import bar as progress_bar


def _connect(scheduler: str, timeout_s: float):
    """A client on ``scheduler``, within ``timeout_s`` for the whole handshake: Dask's own
    connect timeout covers only the TCP connection, and a server that accepts it but is not a
    Dask scheduler (a web server, a listener that never answers) would hang the client for good.
    The client is made in a daemon thread, so a hung handshake cannot keep the process alive."""
    import threading

    Client = need("distributed", "a Dask cluster (workers or a scheduler)").Client

    box: dict = {}

    def make():
        try:
            box["client"] = Client(scheduler, timeout=f"{timeout_s}s")
        except BaseException as exc:  # noqa: BLE001 (passed to the caller)
            box["error"] = exc

    th = threading.Thread(target=make, name="quadest-dask-connect", daemon=True)
    th.start()
    th.join(timeout_s + 5.0)
    if th.is_alive():
        raise ValueError(
            f"{scheduler} accepted the connection but did not answer as a Dask scheduler within "
            f"{timeout_s:g} s: is that the scheduler's address (tcp://HOST:8786)?"
        )
    if "error" in box:
        exc = box["error"]
        raise ValueError(
            f"cannot reach the Dask scheduler at {scheduler} ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0] if str(exc) else ''})"
        ) from None
    return box["client"]


TRACKER_NOTE = "ignore:resource_tracker:UserWarning"
"""The warning option that keeps multiprocessing's resource tracker from saying "There appear to
be 1 leaked semaphore objects to clean up at shutdown" after a worker was killed: it removes the
semaphore all the same (nothing is left behind), and the sweep has run the worker's runs again."""


def _quiet_resource_tracker() -> None:
    """Give the resource tracker :data:`TRACKER_NOTE`: it is started, with this process's ``-W``
    options, when the first worker process is spawned."""
    if TRACKER_NOTE not in sys.warnoptions:
        sys.warnoptions.append(TRACKER_NOTE)


@contextmanager
def dask_client(workers: int | None = None, scheduler: str | None = None, timeout_s: float = 20.0):
    """A client on ``scheduler`` (tcp://host:port; the handshake must finish within
    ``timeout_s``), or on a local cluster of ``workers`` single-threaded worker processes
    (default: one per core)."""
    distributed = need("distributed", "a Dask cluster (workers or a scheduler)")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster

    if workers is not None and workers < 0:
        raise ValueError(f"workers must be 0 or more, got {workers}")
    if scheduler:
        client = _connect(scheduler, timeout_s)
        try:
            yield client
        finally:
            client.close()
        return
    dask = need("dask", "a Dask cluster (workers or a scheduler)")

    n = workers or os.cpu_count() or 1
    _quiet_resource_tracker()
    # Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in its workers, which switches off glibc's
    # adaptive mmap threshold: every array above 128 KiB is then mapped and unmapped anew, and
    # the simulator and filters ran 1.9x slower per run than in this process (measured). The
    # workers here keep glibc's defaults (docs/sweeps.md says how for a cluster of your own).
    with (
        dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}),
        LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def execute(
    fn: Callable[[Any], Any],
    items: Iterable[Any],
    *,
    keys: Sequence[str] | None = None,
    workers: int | None = 0,
    scheduler: str | None = None,
    on_result: Callable[[int, Any], object] | None = None,
    progress: bool = False,
    desc: str = "runs",
    max_inflight: int | None = None,
    stats: dict | None = None,
    weights: Sequence[int] | None = None,
) -> list:
    """Apply ``fn`` to every item; ``workers=0`` (and no scheduler) runs in this process,
    otherwise on Dask (``workers=None``: a local cluster with one worker per core).
    ``on_result(item_index, result_or_exception)`` is called as results arrive
    (in completion order); returns the results in item order. Exceptions from a task
    (a lost worker, a failing function) are passed on as values, never raised. ``stats`` gets
    ``compute_s``: the time from the first task to the last result, without the cluster's
    start-up. ``weights``: how many runs each item holds (for the progress bar)."""
    items = list(items)
    results: list = [None] * len(items)
    failed = 0
    bar = progress_bar(
        total=sum(weights) if weights else len(items), unit="run", desc=desc, disable=not progress, smoothing=0.1
    )

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
        as_completed = need("distributed", "a Dask cluster (workers or a scheduler)").as_completed

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
                fut = (
                    client.submit(fn, items[i], key=key, pure=False) if key else client.submit(fn, items[i], pure=False)
                )
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
