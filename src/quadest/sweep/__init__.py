"""Monte Carlo sweeps and parameter tuning on Dask (docs/sweeps.md): a grid of filters and
parameters over simulated flights, recordings or flown flights (estimators in the loop),
executed in this process, on a local cluster or on an existing Dask cluster,
with results in one resumable Parquet file."""

from quadest.evaluation.parallel import execute
from quadest.sweep.engine import ResultStore, run_sweep
from quadest.sweep.runs import build_runs, file_sources, flown_sources, parse_grid, run_id, run_one, sim_sources
from quadest.sweep.tune import format_selection, format_split, halves, select, split_select, tune

__all__ = [
    "ResultStore",
    "build_runs",
    "execute",
    "file_sources",
    "flown_sources",
    "format_selection",
    "format_split",
    "halves",
    "split_select",
    "parse_grid",
    "run_id",
    "run_one",
    "run_sweep",
    "select",
    "sim_sources",
    "tune",
]
