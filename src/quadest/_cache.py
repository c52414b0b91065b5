"""numba's on-disk cache, keyed on quadest's whole source (docs/developing.md, the cache rule).

numba keys each compiled function's cache entry on that function's own file. quadest's steps
take constants and kernels from shared modules (``filters/common.py``, ``filters/linalg.py``,
``rotation/kernels.py``); an edit there would leave every filter's cached machine code in use,
and results silently stale. So quadest points numba's cache at a folder named by a hash of every
``.py`` file of the package: any edit anywhere gives a new folder and a fresh compile. Folders of
older hashes are removed, keeping the few most recently used (another checkout or version may
still use them).

``NUMBA_CACHE_DIR`` set by the user is respected as it is. The folder is
``$XDG_CACHE_HOME/quadest/numba/<hash>`` (``~/.cache`` without ``XDG_CACHE_HOME``), or under the
temporary directory where that cannot be written.

This module must run before any compiled function is defined: ``quadest/__init__.py`` calls
:func:`configure` first.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
KEEP = 4
"""Cache folders kept: the current one and the most recently used others."""

_MARK = "QUADEST_NUMBA_CACHE_DIR"  # set beside NUMBA_CACHE_DIR when quadest chose it


def source_hash(root: Path = PACKAGE_DIR) -> str:
    """SHA-256 (first 16 hex digits) of the package's ``.py`` files, names and contents."""
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(p.relative_to(root).as_posix().encode())
        h.update(b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def cache_root() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "quadest" / "numba"


def _usable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.utime(folder)  # marks it as recently used
        probe = folder / f".probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
        return True
    except OSError:
        return False


def clean(root: Path, current: Path, keep: int = KEEP) -> list[Path]:
    """Remove cache folders of other hashes beyond the ``keep − 1`` most recently used."""
    try:
        others = [d for d in root.iterdir() if d.is_dir() and d != current]
    except OSError:
        return []
    others.sort(key=lambda d: d.stat().st_mtime, reverse=True)
    removed = []
    for d in others[max(0, keep - 1):]:
        shutil.rmtree(d, ignore_errors=True)
        removed.append(d)
    return removed


def configure() -> str | None:
    """Point numba's cache at the folder of the current source; returns it (None when the user
    set ``NUMBA_CACHE_DIR``)."""
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user and user != os.environ.get(_MARK):
        return None
    digest = source_hash()
    folder = None
    for root in (cache_root(), Path(tempfile.gettempdir()) / f"quadest-numba-{getattr(os, 'getuid', lambda: 0)()}"):
        if _usable(root / digest):
            folder = root / digest
            clean(root, folder)
            break
    if folder is None:
        return None
    from numba.core import config

    # both: numba re-reads its environment before compiling when a NUMBA_ variable changed,
    # and worker processes inherit it (the mark tells them quadest, not the user, chose it)
    os.environ["NUMBA_CACHE_DIR"] = os.environ[_MARK] = str(folder)
    config.CACHE_DIR = str(folder)
    return str(folder)
