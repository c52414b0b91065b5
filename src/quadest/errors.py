"""quadest's errors (docs/reliability.md). Every error a user can cause is a ``ValueError`` (or
``OSError``) with one sentence naming the file or option and what to do; the command line prints
it on one line. Exit codes: 2 for a usage error (an option or its value), 1 for a data error."""


class UsageError(ValueError):
    """An option or its value is wrong (command-line exit code 2)."""
