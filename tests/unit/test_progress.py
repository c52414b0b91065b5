"""Progress bars: redrawn in place on a terminal, whole lines in a file or a pipe."""

import io

from quadest.progress import bar


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_bar_in_a_file_writes_lines_without_carriage_returns():
    """Written to a file, each redraw is a line of its own (a CI log reads as lines), and the
    last shows the total; on a terminal the same bar redraws in place with carriage returns."""
    out, term = io.StringIO(), _Terminal()
    for stream in (out, term):
        with bar(total=3, desc="sweep", file=stream, mininterval=0) as b:
            for _ in range(3):
                b.update(1)
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue() and lines and all(line.startswith("sweep") for line in lines)
    assert "3/3" in lines[-1]
    assert "\r" in term.getvalue()


def test_a_disabled_bar_writes_nothing():
    out = io.StringIO()
    with bar(total=3, file=out, disable=True) as b:
        b.update(3)
    assert out.getvalue() == ""
