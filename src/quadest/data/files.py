"""Writing outputs so that nothing is lost (docs/reliability.md).

Every file quadest writes (recordings, estimates, JSON, calibrations, models, figures) goes
through :func:`atomic_output`: the content is written to a temporary file in the same folder
and renamed onto the target only once it is complete. A failed or interrupted write (a full
disk, ``ulimit -f``, Ctrl-C) leaves the old file as it was, or no file, never a shorter one
that reads back as valid.
"""

from __future__ import annotations

import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_output(path, *, suffix: str | None = None):
    """Yield a temporary path beside ``path``; on success it replaces ``path`` (atomically, on
    the same file system), on any error it is removed and ``path`` is untouched. ``suffix``
    (default: the target's) lets writers that choose a format by extension see the right one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(
        prefix=f".{path.name}.", suffix=(suffix if suffix is not None else path.suffix) + ".tmp", dir=path.parent
    )
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        if path.exists():  # keep the permissions of the file being replaced
            os.chmod(tmp, path.stat().st_mode & 0o7777)
        else:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes(path, data: bytes) -> Path:
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_json(path, obj) -> Path:
    """``obj`` as indented JSON, atomically."""
    return write_bytes(path, (json.dumps(obj, indent=2) + "\n").encode())


def same_file(a, b) -> bool:
    """True when two paths name the same file (also through links); False when either is absent."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return Path(a).resolve() == Path(b).resolve()


def refuse_overwriting_inputs(outputs: dict, inputs) -> None:
    """Raise ValueError when an output path names one of the input files: writing there would
    destroy the input. ``outputs``: ``{option: path or None}``."""
    for option, out in outputs.items():
        if out is None:
            continue
        for inp in inputs or []:
            if inp is not None and same_file(out, inp):
                raise ValueError(f"{option} {out} is the input file {inp}; write the output elsewhere")
