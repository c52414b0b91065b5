"""Progress bars for long runs: tqdm's, redrawn in place on a terminal; written to a file or a
pipe (a CI log, ``2> run.log``) as a line of its own every half minute instead of a redraw per
update run together by carriage returns."""

from __future__ import annotations

import sys

QUIET = False
"""No bar at all (the command line's ``-q``)."""
LOG_EVERY_S = 30.0
"""How often a bar written to a file or a pipe adds a line (s)."""


class _Lines:
    """A stream that writes each redraw of a bar as a line of its own (blank redraws dropped)."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> None:
        text = text.replace("\r", "").strip()
        if text:
            self.stream.write(text + "\n")

    def flush(self) -> None:
        self.stream.flush()


def bar(**kwargs):
    """A tqdm bar (``kwargs`` as :class:`tqdm.tqdm` takes them): in place on a terminal or in a
    notebook, as lines every :data:`LOG_EVERY_S` anywhere else."""
    from tqdm.auto import tqdm  # loaded when a bar is drawn: the command line starts faster

    stream = kwargs.get("file") or sys.stderr
    if QUIET:
        kwargs["disable"] = True
    if not kwargs.get("disable") and not _interactive(stream):
        kwargs.update(file=_Lines(stream), mininterval=LOG_EVERY_S, maxinterval=LOG_EVERY_S, ascii=True)
    return tqdm(**kwargs)


def _interactive(stream) -> bool:
    """A terminal, or a notebook's kernel (whose bars are widgets)."""
    isatty = getattr(stream, "isatty", None)
    return "ipykernel" in sys.modules or bool(isatty and isatty())
