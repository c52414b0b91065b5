"""numba's decorators, with quadest's cache folder set before any compiled function is defined
(docs/developing.md, the cache rule).

numba keys each compiled function's cache entry on that function's own file. quadest's steps
take constants and kernels from shared modules (``filters/common.py``, ``filters/linalg.py``,
``rotation/kernels.py``); an edit there would leave every filter's cached machine code in use,
and results silently stale. So numba's cache is a folder named by a hash of every ``.py`` file
of the package: any edit anywhere gives a new folder and a fresh compile.

Every compiled function of quadest is defined with ``from quadest._jit import njit`` (a test
refuses ``from numba import njit``), so the folder is chosen exactly when compiled code is first
imported, never by ``import quadest`` alone. Housekeeping happens only where a compile follows
anyway: when the current folder is new, folders of older hashes beyond the few most recently
used are removed. ``make clean-cache`` removes them all.

A damaged cache entry (a cut ``.nbi`` or ``.nbc`` file, on which numba's unpickling fails at
every call) is removed and compiled again, with one note (:func:`njit`'s loading guard).

The folder is ``$XDG_CACHE_HOME/quadest/numba/<hash>`` (``~/.cache`` without
``XDG_CACHE_HOME``), or under the temporary directory where that cannot be written. A user who
sets ``NUMBA_CACHE_DIR`` gets ``$NUMBA_CACHE_DIR/quadest-<hash>``: the user's folder, still one
subfolder per source (an upgrade or an edit cannot run stale code), and housekeeping there
touches only quadest's own subfolders.
"""

from __future__ import annotations

import contextlib
import functools
import glob
import hashlib
import logging
import os
import shutil
import tempfile
import warnings
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
KEEP = 4
"""Cache folders kept: the current one and the most recently used others."""

_MARK = "QUADEST_NUMBA_CACHE_DIR"  # set beside NUMBA_CACHE_DIR when quadest chose it
_USER = "QUADEST_NUMBA_USER_DIR"  # the user's NUMBA_CACHE_DIR, kept for worker processes


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


def _made(folder: Path) -> bool | None:
    """Make ``folder`` if it is missing: True if it was made now, False if it was there and is
    writable, None if it cannot be used."""
    if folder.is_dir():
        return False if os.access(folder, os.W_OK | os.X_OK) else None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
        return True
    except OSError:
        return None


def clean(root: Path, current: Path, keep: int = KEEP, prefix: str = "") -> list[Path]:
    """Remove cache folders of other hashes (named ``prefix…``) beyond the ``keep − 1`` most
    recently changed."""
    try:
        others = [d for d in root.iterdir() if d.is_dir() and d != current and d.name.startswith(prefix)]
    except OSError:
        return []
    others.sort(key=lambda d: d.stat().st_mtime, reverse=True)
    removed = []
    for d in others[max(0, keep - 1) :]:
        shutil.rmtree(d, ignore_errors=True)
        removed.append(d)
    return removed


USER_PREFIX = "quadest-"
"""The name of quadest's subfolders of a ``NUMBA_CACHE_DIR`` the user set (before the hash)."""


def _roots() -> tuple[tuple[Path, ...], str]:
    """Where the source's folder may go, and its name's prefix: the user's ``NUMBA_CACHE_DIR``
    (a subfolder named ``quadest-<hash>``), else quadest's cache, else the temporary directory."""
    cache = os.environ.get("NUMBA_CACHE_DIR")
    chosen = cache and cache == os.environ.get(_MARK)  # by quadest, in a parent process
    user = os.environ.get(_USER) if chosen else cache
    if user:
        return (Path(user),), USER_PREFIX
    uid = getattr(os, "getuid", lambda: 0)()
    return (cache_root(), Path(tempfile.gettempdir()) / f"quadest-numba-{uid}"), ""


def configure() -> str | None:
    """Point numba's cache at the folder of the current source; returns it (None when no
    folder can be written: numba then keeps nothing)."""
    roots, prefix = _roots()
    digest = source_hash()
    for root in roots:
        made = _made(root / f"{prefix}{digest}")
        if made is not None:
            break
    else:
        return None
    folder = root / f"{prefix}{digest}"
    if made:  # a new source: everything compiles now, and older folders may go
        clean(root, folder, prefix=prefix)
    from numba.core import config

    # both: numba re-reads its environment before compiling when a NUMBA_ variable changed,
    # and worker processes inherit it (the mark tells them quadest, not the user, chose it)
    os.environ["NUMBA_CACHE_DIR"] = os.environ[_MARK] = str(folder)
    if prefix:
        os.environ[_USER] = str(root)
    config.CACHE_DIR = str(folder)
    return str(folder)


CACHE_DIR = configure()
"""Where compiled code is cached (None when no folder could be written)."""


from numba import carray, cfunc, types  # noqa: E402  (after the cache folder is set)
from numba import njit as _numba_njit  # noqa: E402

MENDED: list[str] = []
"""The cache files found damaged and removed in this process (their functions compiled again)."""


def _remove_entry(cache_file) -> list[str]:
    """A function's index and data files in numba's cache folder."""
    folder, index = Path(cache_file._cache_path), Path(cache_file._index_path)
    stem = index.name[: -len(".nbi")]
    removed = []
    for f in [index, *folder.glob(f"{glob.escape(stem)}.*.nbc")]:
        with contextlib.suppress(OSError):
            f.unlink()
            removed.append(str(f))
    return removed


COMPILING = "quadest: compiling"
"""How the line said before the first compile of a process begins (:func:`say_compiling`)."""
_SAID: list[str] = []
QUICK_TO_COMPILE = ("quadest.rotation.",)
"""Modules of small shared kernels (a second or two to compile) whose compile is not said: what
called them (an estimator) compiles next, and is said."""


def compile_label(func) -> tuple[str, str]:
    """What compiling ``func`` is, for a user, and about how long it takes: an estimator's batch
    run or streaming call (``<name>_run``, ``<name>_stream``, made in ``filters/common.py``) is
    the estimator; anything else is named by its module and function."""
    name, module = func.__name__, func.__module__
    estimator = name.removesuffix("_run").removesuffix("_stream")
    if module.startswith("quadest.filters") and estimator != name:
        return f"the {estimator} estimator", "about 20 s"
    return f"quadest's compiled code ({module.removeprefix('quadest.')}.{name})", "up to a minute"


def say_compiling(func) -> None:
    """Say, once a process and on stderr whether a terminal or a log (the logger ``quadest``),
    that compiled code is being made: numba's cache does not hold ``func`` (the first use after
    installing or editing quadest), and the wait would otherwise be silent."""
    if _SAID or func.__module__.startswith(QUICK_TO_COMPILE):
        return
    what, how_long = compile_label(func)
    _SAID.append(what)
    logging.getLogger("quadest.compiling").warning(
        f"{COMPILING} {what} (first use after an install or an edit, {how_long}; cached for the next runs)…"
    )


def _load_or_mend(dispatcher, load, sig, target_context):
    """numba's ``Cache.load_overload``, where a miss (nothing cached for ``sig``: numba compiles
    next) is said (:func:`say_compiling`), and a damaged entry (a cut or overwritten ``.nbi`` /
    ``.nbc`` file: pickle fails on it, on every run) is removed, said once in one line, and
    compiled again (numba then saves it anew) instead of failing every call."""
    cache = dispatcher._cache
    try:
        loaded = load(sig, target_context)
    except Exception as exc:  # noqa: BLE001 (whatever unpickling a damaged file raises)
        removed = _remove_entry(cache._cache_file)
        if not MENDED:
            warnings.warn(
                f"the compiled-code cache in {Path(cache._cache_file._cache_path).parent} was damaged "
                f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); its damaged entries "
                "are compiled again",
                RuntimeWarning,
                stacklevel=2,
            )
        MENDED.extend(removed or [cache._cache_file._index_path])
        loaded = None
    if loaded is None:
        say_compiling(dispatcher.py_func)
    return loaded


def _mending(dispatcher):
    """``dispatcher`` with its disk cache (if any) loading through :func:`_load_or_mend`."""
    cache = getattr(dispatcher, "_cache", None)
    if cache is not None and hasattr(cache, "_cache_file"):
        cache.load_overload = functools.partial(_load_or_mend, dispatcher, cache.load_overload)
    return dispatcher


def njit(*args, **options):
    """numba's ``njit`` with reference counting and ``fastmath`` stated, never inherited.

    numba compiles a function that does not state them with its first caller's: a kernel first
    called from a ``fastmath`` step would be compiled with ``fastmath`` (and kept so in the disk
    cache), first called from elsewhere without; a function first called from code without
    reference counting (:data:`NO_ALLOCATION`) without it. Results then depended on what was
    compiled first (madgwick's start moved by 1e-5 rad). Here a function has the options it
    states, else ``fastmath=False`` and reference counting; a function inlined
    (``inline="always"``) is part of its caller and compiled with the caller's options."""
    options.setdefault("_nrt", True)
    options.setdefault("fastmath", False)
    if args and callable(args[0]):
        return _mending(_numba_njit(**options)(args[0]))
    decorate = _numba_njit(*args, **options)
    return lambda func: _mending(decorate(func))


NO_ALLOCATION = {"_nrt": False}
"""``njit`` options for a compiled step that allocates no array: numba's reference counting is
left out, and with it the counts of the arrays the step passes to its inlined phases, at every
call (robust's step: 0.43 -> 0.24 µs a sample; docs/developing.md). A step that does allocate
fails to compile ("NRT required but not enabled"), never runs wrong."""


@njit(cache=True, inline="always")
def copy_into(dst, src):
    """``dst[:] = src`` for one-dimensional arrays of one length, in code compiled with
    :data:`NO_ALLOCATION` (numba's slice assignment needs its reference counting)."""
    for i in range(dst.shape[0]):
        dst[i] = src[i]


__all__ = ["CACHE_DIR", "NO_ALLOCATION", "carray", "cfunc", "copy_into", "njit", "say_compiling", "types"]
