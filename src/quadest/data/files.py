"""Writing outputs so that nothing is lost, whatever the output's name points at
(docs/reliability.md).

Every file quadest writes (recordings, estimates, JSON, calibrations, models, figures, sweep
results) goes through :func:`atomic_output`, which first asks :func:`output_target` what the
name means:

- a regular file, or a new one in a folder that exists: written to a temporary file beside it
  and renamed onto it once complete, so a failed or interrupted write (a full disk,
  ``ulimit -f``, Ctrl-C) leaves the old file as it was, or no file;
- a symbolic link: the same, beside the file it points at; the link is kept;
- a FIFO, a character device (``/dev/null``, a terminal) or an open descriptor
  (``/dev/stdout``, ``-`` for standard output, ``/dev/fd/N``): written to as a stream once the
  content is complete, never replaced;
- refused in one line (``ValueError``): a read-only file (unless forced: ``--force``,
  :func:`replacing_read_only`), a folder, a socket, a block device, a file in a folder that does
  not exist (it is not created: a mistyped folder would be).

JSON is written strict (:func:`dumps_json`): NaN and infinities become ``null``.
"""

from __future__ import annotations

import errno
import fcntl
import json
import math
import os
import shutil
import stat
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path

_FORCE: ContextVar[bool] = ContextVar("quadest_replace_read_only", default=False)

STDOUT = "-"
"""The name of standard output as an output (``-o -``)."""
DESCRIPTORS = {"/dev/stdout": 1, "/dev/stderr": 2, STDOUT: 1}
"""Names of this process's own descriptors, written to directly (not reopened)."""

FIFO_WAIT_S = 10.0
"""How long a FIFO output waits for a process to read it before it is refused."""


@dataclass(frozen=True)
class OutputTarget:
    """What writing ``path`` means: ``file`` is the file written (a link's target), ``stream``
    says it is written to as a stream (a FIFO, a device, a descriptor), never replaced."""

    path: Path
    file: Path
    stream: bool


@contextmanager
def replacing_read_only(force: bool = True) -> Iterator[None]:
    """Within the block, read-only outputs are replaced (the command line's ``--force``)."""
    token = _FORCE.set(force)
    try:
        yield
    finally:
        _FORCE.reset(token)


def _is_descriptor(path: Path) -> bool:
    text = str(path)
    return text in DESCRIPTORS or text.startswith(("/dev/fd/", "/proc/")) or os.path.realpath(text).startswith("/proc/")


def _new_file(path: Path) -> OutputTarget:
    """A file that does not exist yet (or a link to one): its folder must."""
    real = Path(os.path.realpath(path))
    if real.is_symlink():
        raise ValueError(f"{path} is a symbolic link that leads to itself; give a file name")
    folder = real.parent if path.is_symlink() else path.parent
    if not folder.is_dir():
        raise ValueError(f"{path}: the folder {folder} does not exist; create it first, or write elsewhere")
    return OutputTarget(path, real, False)


def _read_only(path: Path, st: os.stat_result) -> bool:
    return not st.st_mode & 0o222 or not os.access(path, os.W_OK)


NOT_WRITTEN = {
    stat.S_IFDIR: "a folder; give a file name in it",
    stat.S_IFSOCK: "a socket; quadest writes files, FIFOs and character devices",
    stat.S_IFBLK: "a block device (a disk); quadest does not write onto disks",
}


def output_target(path, *, force: bool | None = None) -> OutputTarget:
    """What writing ``path`` means (module docstring); ValueError (one line, naming the path)
    when it is refused. ``force`` (default: as :func:`replacing_read_only` set it) replaces a
    read-only file."""
    path = Path(path)
    force = _FORCE.get() if force is None else force
    if _is_descriptor(path):
        return OutputTarget(path, path, True)
    try:
        st = os.stat(path)  # follows links
    except FileNotFoundError:
        return _new_file(path)
    except OSError as exc:  # a link loop, a file where a folder should be, no permission
        raise ValueError(f"{path}: cannot be written ({exc.strerror})") from None
    kind = stat.S_IFMT(st.st_mode)
    if kind == stat.S_IFREG:
        if not force and _read_only(path, st):
            raise ValueError(f"{path} is read-only; give --force to replace it, or write elsewhere")
        return OutputTarget(path, Path(os.path.realpath(path)), False)
    if kind in (stat.S_IFIFO, stat.S_IFCHR):
        return OutputTarget(path, path, True)
    raise ValueError(f"{path} is {NOT_WRITTEN.get(kind, 'not a file')}")


def output_folder(path) -> Path:
    """A folder to write files into (made when absent); ValueError (one line, naming the path)
    when the name is a file, or a link that loops or leads to nothing."""
    path = Path(path)
    try:
        st = os.stat(path)  # follows links
    except FileNotFoundError:
        if path.is_symlink():
            raise ValueError(
                f"{path} is a symbolic link to {os.readlink(path)}, which is not there; give a folder"
            ) from None
        return path
    except OSError as exc:  # a link loop, a file where a folder should be, no permission
        raise ValueError(f"{path}: cannot be written into ({exc.strerror})") from None
    if not stat.S_ISDIR(st.st_mode):
        raise ValueError(f"{path} is not a folder; give a folder for the files")
    return path


def _open_stream(path: Path, wait_s: float) -> int:
    """A descriptor to write ``path`` as a stream; a FIFO waits up to ``wait_s`` for a reader
    (opening it blocking would wait forever), then is refused."""
    if str(path) in DESCRIPTORS:
        stream = sys.stdout if DESCRIPTORS[str(path)] == 1 else sys.stderr
        if stream is None:  # closed when the program started (>&-)
            raise ValueError(f"{path}: standard {'output' if DESCRIPTORS[str(path)] == 1 else 'error'} is closed")
        stream.flush()
        return os.dup(DESCRIPTORS[str(path)])
    deadline = time.monotonic() + wait_s
    while True:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_NONBLOCK)
            break
        except OSError as exc:
            if exc.errno != errno.ENXIO or time.monotonic() > deadline:  # ENXIO: a FIFO nobody reads
                raise ValueError(f"{path}: no process read from this FIFO within {wait_s:g} s") from None
            time.sleep(0.05)
    fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    return fd


def _write_stream(src: Path, path: Path, wait_s: float = FIFO_WAIT_S) -> None:
    with open(src, "rb") as f, os.fdopen(_open_stream(path, wait_s), "wb") as out:
        shutil.copyfileobj(f, out)


def _keep_mode(tmp: Path, file: Path) -> None:
    """The new file gets the permissions of the one it replaces, or the umask's."""
    if file.exists():
        os.chmod(tmp, file.stat().st_mode & 0o7777)
    else:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)


@contextmanager
def atomic_output(path, *, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path to write; on success it becomes ``path`` as :func:`output_target`
    says (renamed onto the file, or streamed), on any error it is removed and ``path`` is
    untouched. ``suffix`` (default: the target's) lets writers that choose a format by
    extension see the right one."""
    target = output_target(path)
    sfx = (suffix if suffix is not None else target.path.suffix) + ".tmp"
    folder = None if target.stream else target.file.parent  # a stream's content waits in the temp folder
    fd, name = tempfile.mkstemp(prefix=f".{target.file.name}.", suffix=sfx, dir=folder)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        if target.stream:
            _write_stream(tmp, target.path)
        else:
            _keep_mode(tmp, target.file)
            os.replace(tmp, target.file)
    finally:
        tmp.unlink(missing_ok=True)


def write_bytes(path, data: bytes) -> Path:
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def strict(obj):
    """``obj`` with every NaN and infinity as None, numpy scalars and arrays as Python values:
    what strict JSON can hold."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict(v) for v in obj]
    if hasattr(obj, "tolist") and hasattr(obj, "dtype"):  # numpy scalars and arrays
        return strict(obj.tolist())
    return obj


def dumps_json(obj, indent: int | None = 2, **kw) -> str:
    """``obj`` as strict JSON (NaN and infinities as ``null``; never ``NaN``, which JSON has not)."""
    return json.dumps(strict(obj), indent=indent, allow_nan=False, **kw)


def write_json(path, obj) -> Path:
    """``obj`` as indented strict JSON (:func:`dumps_json`), atomically."""
    return write_bytes(path, (dumps_json(obj) + "\n").encode())


def same_file(a, b) -> bool:
    """True when two paths name the same file (also through links); False when either is absent."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # realpath, not Path.resolve: a link that loops is a name, not an error
        return os.path.realpath(a) == os.path.realpath(b)


def refuse_overwriting_inputs(outputs: dict, inputs) -> None:
    """Raise ValueError when an output path names one of the input files: writing there would
    destroy the input. ``outputs``: ``{option: path or None}``."""
    for option, out in outputs.items():
        if out is None:
            continue
        for inp in inputs or []:
            if inp is not None and same_file(out, inp):
                raise ValueError(f"{option} {out} is the input file {inp}; write the output elsewhere")


# -- one writer at a time -------------------------------------------------------------------------
def _holder(fd: int) -> str:
    os.lseek(fd, 0, os.SEEK_SET)
    return os.read(fd, 64).decode(errors="replace").strip() or "?"


def _still_named(fd: int, path: Path) -> bool:
    """Whether ``path`` is still the file open as ``fd`` (a holder removes it when done)."""
    try:
        return os.stat(path).st_ino == os.fstat(fd).st_ino
    except FileNotFoundError:
        return False


@contextmanager
def exclusive_lock(path, *, on_wait: Callable[[str], None] | None = None) -> Iterator[None]:
    """Hold an advisory lock (``fcntl.flock``) on the file ``path`` for the block: another
    process asking for it waits until the block ends (``on_wait(holder_pid)`` is called once
    before waiting). The lock goes with the process, also when it is killed; the file is
    removed when the block ends."""
    path = Path(path)
    told = False
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                if on_wait and not told:
                    on_wait(_holder(fd))
                    told = True
                fcntl.flock(fd, fcntl.LOCK_EX)
        except BaseException:
            os.close(fd)
            raise
        if _still_named(fd, path):
            break
        os.close(fd)  # the holder removed the file as it ended: lock the next one
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        path.unlink(missing_ok=True)
        os.close(fd)
