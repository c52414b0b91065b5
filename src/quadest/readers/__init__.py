"""Readers: every supported file becomes a :class:`~quadest.data.Recording` in quadest's
conventions (docs/readers.md).

``read_recording(path, format=None, **options)`` picks the reader from the file (extension and
contents) unless ``format`` names it. Formats:

============  =====================================================================
quadest       quadest's own CSV / Parquet (``save_recording``)
csv           any CSV with a column mapping (``columns=``, ``units=``, ``frame=``)
ulog          PX4 ULog (pyulog)
dataflash     ArduPilot DataFlash .bin (pymavlink)
rosbag        ROS 1 .bag or ROS 2 bag folder / .db3 / .mcap (rosbags)
broad         BROAD trial, HDF5 or MAT
dido          DIDO flight, HDF5
blackbird     Blackbird as prepared by UZH-RPG: folder with data.hdf5 + ground truth
repoimu       RepoIMU CSV
asl           EuRoC / TUM-VI layout: the folder holding mav0/ (or mav0/ itself)
============  =====================================================================

Every failure is a :class:`ReaderError` (a ValueError) with one line naming the file.
"""

from __future__ import annotations

import inspect
import logging
import os
from pathlib import Path

from quadest.data.inputs import check_input
from quadest.data.recording import Recording
from quadest.data.recording_files import load_recording
from quadest.errors import UsageError
from quadest.extras import need
from quadest.readers import asl, datasets, generic, logs, ros
from quadest.readers.common import ReaderError

LOG = logging.getLogger(__name__)


def _read_broad(path) -> Recording:
    read = datasets.read_broad_mat if Path(path).suffix.lower() == ".mat" else datasets.read_broad_hdf5
    return read(path)


READERS = {
    "quadest": load_recording,
    "csv": generic.read_csv_mapped,
    "ulog": logs.read_ulog,
    "dataflash": logs.read_dataflash,
    "rosbag": ros.read_rosbag,
    "broad": _read_broad,
    "dido": datasets.read_dido,
    "blackbird": datasets.read_blackbird,
    "repoimu": datasets.read_repoimu,
    "asl": asl.read_asl,
}
"""The one registry of readers: each format's name to the function that reads it into a
:class:`~quadest.data.Recording` (``read(path, **options)``)."""
FORMATS = tuple(READERS)


def _first_bytes(p: Path, n=256) -> bytes:
    """The file's first bytes; one that cannot be opened is refused with the system's reason
    (permission denied is not "an empty file" nor "not quadest's own")."""
    try:
        with open(p, "rb") as f:
            return f.read(n)
    except OSError as exc:
        raise ReaderError(f"{p}: cannot be read ({exc.strerror or exc})") from None


def detect_format(path: str | Path) -> str:
    """The format of ``path`` from its extension and first bytes (or, for HDF5, its datasets)."""
    p = Path(path)
    if not p.exists():
        if p.is_symlink():
            raise ReaderError(f"{path}: a symbolic link that loops or leads to nothing ({os.readlink(p)})")
        raise ReaderError(f"{path}: no such file or folder")
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "rosbag"
        if (p / "data.hdf5").is_file() and (p / "stamped_groundtruth_imu.txt").is_file():
            return "blackbird"
        if asl.asl_folder(p) is not None:
            return "asl"
        raise ReaderError(
            f"{path}: a folder that is neither a ROS 2 bag (metadata.yaml), a Blackbird sequence "
            "(data.hdf5 + stamped_groundtruth_imu.txt) nor an ASL one (mav0/imu0/data.csv)"
        )
    ext = p.suffix.lower()
    head = _first_bytes(p)
    if not head:
        raise ReaderError(f"{path}: the file is empty")
    if head.startswith(b"ULog"):
        return "ulog"
    if ext in (".bin",) or head[:2] == b"\xa3\x95":
        return "dataflash"
    if ext in (".bag", ".db3", ".mcap") or head.startswith(b"#ROSBAG"):
        return "rosbag"
    if ext == ".parquet" or ext == ".pq":
        return "quadest"
    if ext == ".mat":
        return "broad"
    if ext in (".hdf5", ".h5") or head.startswith(b"\x89HDF"):
        h5py = need("h5py", "reading an HDF5 file")

        try:
            with h5py.File(p, "r") as f:
                keys = set(f.keys())
        except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:
            raise ReaderError(f"{path}: not a readable HDF5 file ({str(exc).strip().splitlines()[0]})") from None
        if {"imu_gyr", "imu_acc", "opt_quat"} <= keys:
            return "broad"
        if {"ts", "gyr", "acc", "gt_q"} <= keys:
            return "dido"
        if {"ts", "gyro_raw", "accel_raw"} <= keys:
            return "blackbird"
        raise ReaderError(
            f"{path}: HDF5 file of unknown layout (datasets {', '.join(sorted(keys)[:8])}); "
            "known: BROAD, DIDO, Blackbird"
        )
    if ext == ".csv" or ext == ".txt":
        if head.startswith(b"# quadest recording"):
            return "quadest"
        if head.startswith((b"Time (s);", b"Time;Vicon Orientation")):  # RepoIMU's two header variants
            return "repoimu"
        first = head.split(b"\n")[0].decode("utf-8", "replace")
        if first.startswith("t,gyr_x"):
            return "quadest"
        raise ReaderError(
            f"{path}: a CSV that is not quadest's own; say which columns are what: "
            "--format csv --map t=COL --map gyr=X,Y,Z --map acc=X,Y,Z [--map mag=...] "
            "[--units gyr=deg/s ...] (docs/readers.md)"
        )
    raise ReaderError(f"{path}: unknown file type {ext!r}; give --format (one of {', '.join(FORMATS)})")


def read_recording(path: str | Path, format: str | None = None, **options) -> Recording:
    """Read any supported file as a Recording (see the module docstring). A FIFO, a device, a
    sparse text file or a file larger than the memory available is refused before it is opened
    (:func:`quadest.data.inputs.check_input`)."""
    try:
        check_input(path)
    except ValueError as exc:
        raise ReaderError(str(exc)) from None
    fmt = format or detect_format(path)
    if fmt not in READERS:
        raise ReaderError(f"unknown format {fmt!r}; formats: {', '.join(READERS)}")
    if not Path(path).exists():
        raise ReaderError(f"{path}: no such file or folder")
    refuse_options_that_do_not_apply(fmt, options, path)
    rec = READERS[fmt](path, **options)
    LOG.debug(f"quadest: {path}: read as {fmt}{'' if format else ' (detected)'}: {_what_was_read(rec)}")
    return rec


def _what_was_read(rec: Recording) -> str:
    """Rows, span and channels of a recording read, for ``-v``."""
    channels = ["gyr", "acc", *(["mag"] if rec.has_mag else []), *rec.truth, *rec.rotor_channels]
    span = f"{rec.duration:.3f} s at {rec.imu_rate_hz():.1f} Hz" if len(rec) > 1 else "one row"
    return f"{len(rec)} rows, {span}; {', '.join(channels)}"


OPTION_FLAGS = {
    "columns": "--map",
    "units": "--units",
    "frame": "--frame",
    "quat_order": "--quat-order",
    "imu": "--imu",
    "msgs": "--msgs",
    "imu_topic": "--topic imu=",
    "mag_topic": "--topic mag=",
    "truth_topic": "--topic truth=",
}
"""The command line's spelling of each reader option."""


def refuse_options_that_do_not_apply(fmt: str, options: dict, path) -> None:
    """Raise :class:`UsageError` naming the first option that the format's reader does not take
    (never ignored: ``--units`` on a ULog would otherwise be silently without effect)."""
    takes = [n for n, p in inspect.signature(READERS[fmt]).parameters.items() if p.kind is p.KEYWORD_ONLY]
    for name in options:
        if name not in takes:
            flag = OPTION_FLAGS.get(name, name)
            usable = ", ".join(OPTION_FLAGS.get(n, n) for n in takes) or "none"
            raise UsageError(f"{path}: {flag} does not apply to a {fmt} file (its options: {usable}); leave it out")


__all__ = ["FORMATS", "READERS", "ReaderError", "detect_format", "read_recording"]
