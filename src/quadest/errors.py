"""quadest's errors (docs/reliability.md). Every error a user can cause is a ``ValueError`` (or
``OSError``) with one sentence naming the file or option and what to do; the command line prints
it on one line. Exit codes: 2 for a usage error (an option or its value), 1 for a data error."""


class UsageError(ValueError):
    """An option or its value is wrong (command-line exit code 2)."""


MAX_RUNS = 1_000_000
"""How many runs (flights, throws, or in a sweep filter × parameter set × flight) a command that
runs many starts at most, unless its ``--max-runs`` says otherwise (docs/reliability.md)."""


def check_run_count(count: int, max_runs: int | None = MAX_RUNS, what: str = "the command") -> int:
    """``count`` when it is within ``max_runs`` (None: no bound), else a UsageError naming both;
    checked before anything is allocated or run."""
    if max_runs is not None and count > max_runs:
        raise UsageError(
            f"{what} makes {count:,} runs, more than --max-runs {max_runs:,}: choose fewer, or raise --max-runs"
        )
    return count
