"""Reading inputs within bounds (docs/reliability.md): a file that is not a regular file (a FIFO,
a device, a socket) is refused before it is opened, and one too large for the memory available
is refused with both figures before it is read.

What reading a file needs is estimated from its size (``size × factor``, the factor per kind of
file chosen, not measured per reader: the one file measured, a 10⁷-row Parquet recording, peaked
at 1.7× its values in ``info`` and 2.2× in ``estimate``) or, for Parquet, from the row and column counts its footer
states; what is available is the least of the memory the system says is available, a control
group's limit and ``ulimit -v``.
"""

from __future__ import annotations

import os
import resource
import stat
from pathlib import Path

TEXT_FACTOR = 3.0
"""Memory a text file (CSV, TXT) needs while read, per byte of file: pyarrow's table of the
text (about the file's size) and the arrays made of it."""
BINARY_FACTOR = 4.0
"""The same for a log or an HDF5 / MAT file, whose readers hold the messages and the arrays."""
PARQUET_FACTOR = 3.0
"""Per byte of a Parquet file's decoded values (rows × columns × 8): the decoded columns, the
arrays made of them and the checks' temporaries."""

KINDS = {
    stat.S_ISFIFO: "a FIFO (named pipe)",
    stat.S_ISCHR: "a character device",
    stat.S_ISBLK: "a block device",
    stat.S_ISSOCK: "a socket",
}


def kind_of(mode: int) -> str | None:
    """What a non-regular, non-folder file is (None for a regular file or a folder)."""
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return next((name for test, name in KINDS.items() if test(mode)), "not a regular file")


def check_regular(path, option: str = "") -> None:
    """Refuse, before opening it, an input that is a FIFO, a device or a socket: reading one
    blocks forever or never ends. A missing file is left to the reader's own message."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return
    kind = kind_of(mode)
    if kind:
        raise ValueError(f"{(option + ' ') if option else ''}{path}: {kind}, not a file: quadest reads regular files")


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_available() -> int | None:
    """What a cgroup v2 memory limit leaves (None without one)."""
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text().strip())
    except (OSError, ValueError):
        return None
    return None if limit == "max" else max(0, int(limit) - used)


def _address_space_available() -> int | None:
    """What ``ulimit -v`` leaves of this process's address space (None without a limit)."""
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    try:
        with open("/proc/self/statm") as f:
            used = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        used = 0
    return max(0, soft - used)


def available_memory() -> int | None:
    """Bytes this process may still allocate: the least of the system's available memory, a
    cgroup's limit and ``ulimit -v``; None where none of them can be read."""
    known = [m for m in (_meminfo_available(), _cgroup_available(), _address_space_available()) if m is not None]
    return min(known) if known else None


def _parquet_values(path) -> int | None:
    try:
        import pyarrow.parquet as pq

        with open(path, "rb") as fh:
            md = pq.ParquetFile(fh).metadata
        return md.num_rows * md.num_columns * 8
    except Exception:  # noqa: BLE001 (a damaged footer is the reader's to say)
        return None


def memory_needed(path) -> int:
    """Bytes reading ``path`` is estimated to need (see the module docstring)."""
    p = Path(path)
    size = p.stat().st_size
    ext = p.suffix.lower()
    if ext in (".parquet", ".pq"):
        values = _parquet_values(p)
        return int(PARQUET_FACTOR * (values if values is not None else size))
    return int((TEXT_FACTOR if ext in (".csv", ".txt") else BINARY_FACTOR) * size)


def _gb(n: int) -> str:
    return f"{n / 1e9:.2f} GB" if n >= 1e8 else f"{n / 1e6:.1f} MB"


def check_fits_in_memory(path, available: int | None = None) -> None:
    """Refuse a regular file whose reading would need more memory than is available, with both
    figures, before it is read."""
    p = Path(path)
    if not p.is_file():
        return
    available = available_memory() if available is None else available
    if available is None:
        return
    need = memory_needed(p)
    if need > available:
        raise ValueError(
            f"{path}: reading this {_gb(p.stat().st_size)} file needs about {_gb(need)} of memory and "
            f"{_gb(available)} is available: read a part of it (split the file), or free memory"
        )


def first_hole(path) -> int | None:
    """Where a sparse file's first hole starts (None when it has none, or the system cannot say)."""
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            at = os.lseek(f.fileno(), 0, getattr(os, "SEEK_HOLE", 4))
    except (OSError, AttributeError):
        return None
    return at if at < size else None


def check_text(path) -> None:
    """Refuse a text file with a hole (a sparse file: NUL bytes, never text) before it is read."""
    at = first_hole(path)
    if at is not None:
        raise ValueError(
            f"{path}: a sparse file (a hole of NUL bytes from byte {at:,} of {Path(path).stat().st_size:,}): "
            "not a text file"
        )


def check_input(path, option: str = "") -> None:
    """Every check above, before ``path`` is opened: a regular file (or a folder), text without
    holes, and within the memory available."""
    check_regular(path, option)
    p = Path(path)
    if p.is_file() and p.suffix.lower() in (".csv", ".txt"):
        check_text(p)
    check_fits_in_memory(p)
