"""Readers for the benchmark datasets: BROAD (HDF5 and MAT), DIDO (HDF5), Blackbird as prepared
by UZH-RPG (data.hdf5 + stamped_groundtruth_imu.txt), RepoIMU (CSV). Frame conversions are in
docs/readers.md; each was checked on the real files by rotating the measured specific force
into the truth's navigation frame (it must average to +g up)."""

from __future__ import annotations

import math
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from quadest.extras import need
from quadest.readers.common import ReaderError, make_recording, resample_quat, z_up_nav_to_ned
from quadest.readers.rotors import RPM, rotor_meta
from quadest.rotation.frames import quat_enu_flu_to_ned_frd, vec_enu_to_ned, vec_flu_to_frd

DAMAGE = (OSError, RuntimeError, KeyError, TypeError, IndexError, AttributeError, OverflowError)
"""What h5py raises from a damaged file, anywhere in reading it."""


@contextmanager
def _h5(path):
    """An open HDF5 file; any failure of h5py inside the block (a damaged file) becomes one
    ReaderError naming the file."""
    h5py = need("h5py", "reading an HDF5 file")

    try:
        f = h5py.File(path, "r")
    except (OSError, ValueError) as exc:
        raise ReaderError(f"{path}: not a readable HDF5 file ({str(exc).strip().splitlines()[0]})") from None
    try:
        with f:
            yield f
    except DAMAGE as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        raise ReaderError(f"{path}: the HDF5 file is damaged ({type(exc).__name__}: {msg})") from None


MAX_DECLARED_BYTES = 4e9
"""An HDF5 dataset declaring more than this is refused before it is read."""


def _h5_read(f, name, path):
    """A dataset of an open HDF5 file as an array, after checking what it declares against what
    the file stores: a damaged or crafted file can declare 10⁸ rows in a few kilobytes, and
    reading it would allocate gigabytes of fill values."""
    h5py = need("h5py", "reading an HDF5 file")

    ds = f[name]
    if not isinstance(ds, h5py.Dataset):
        raise ReaderError(f"{path}: {name!r} is a group, not a dataset")
    declared = ds.size * ds.dtype.itemsize
    stored = ds.id.get_storage_size()
    if declared > MAX_DECLARED_BYTES or (declared > 64e6 and stored * 1000 < declared):
        raise ReaderError(
            f"{path}: {name!r} declares {ds.shape} values ({declared / 1e6:.0f} MB) but the file "
            f"stores {stored / 1e6:.3g} MB of it: the file is damaged or not what it claims"
        )
    if declared > 0 and stored == 0:  # h5py would read its fill value (zeros) as samples
        raise ReaderError(
            f"{path}: {name!r} declares {ds.shape} values but none was ever written: the file is incomplete"
        )
    try:
        return ds[()]
    except (OSError, ValueError, TypeError) as exc:
        raise ReaderError(f"{path}: cannot read {name!r} ({str(exc).splitlines()[0]})") from None


def _need(d, keys, path, what):
    missing = [k for k in keys if k not in d]
    if missing:
        raise ReaderError(f"{path}: not a {what} file (missing {', '.join(missing)})")


def _intervals(t, mask):
    """``[[t0, t1], ...]`` of the runs where ``mask`` is true (for meta['evaluate_intervals_s'])."""
    m = np.asarray(mask, bool)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], m.astype(int), [0]])))
    return [[float(t[a]), float(t[b - 1])] for a, b in zip(edges[::2], edges[1::2])]


# -- BROAD ------------------------------------------------------------------------------------------
def _broad(path, d, rate, info=""):
    _need(d, ("imu_gyr", "imu_acc", "imu_mag", "opt_quat"), path, "BROAD")
    gyr, acc, mag = (np.asarray(d[k], float).reshape(-1, 3) for k in ("imu_gyr", "imu_acc", "imu_mag"))
    n = len(gyr)
    if len(acc) != n or len(mag) != n:
        raise ReaderError(f"{path}: imu_gyr, imu_acc and imu_mag differ in length (truncated file?)")
    t = np.arange(n) / rate
    q = np.asarray(d["opt_quat"], float).reshape(-1, 4)
    bad = ~np.isfinite(q).all(axis=1)
    q_ned = quat_enu_flu_to_ned_frd(np.where(bad[:, None], [1.0, 0, 0, 0], q))
    q_ned[bad] = np.nan
    movement = np.asarray(d["movement"], bool).ravel() if "movement" in d else np.ones(n, bool)
    meta = {
        "dataset": "BROAD",
        "trial": Path(path).stem,
        "imu_rate_hz": float(rate),
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "uT"},
        "evaluate_intervals_s": _intervals(t, movement),
        "frames": "ENU/sensor z-up -> NED/FRD",
        "truth_source": "optical motion capture (BROAD opt_quat)",
    }
    if info:
        meta["description"] = info.splitlines()[3] if len(info.splitlines()) > 3 else info
    return make_recording(
        path, "broad", t, vec_flu_to_frd(gyr), vec_flu_to_frd(acc), vec_flu_to_frd(mag), meta, true_q=q_ned
    )


def read_broad_hdf5(path):
    with _h5(path) as f:
        if "sampling_rate" not in f.attrs:
            raise ReaderError(f"{path}: not a BROAD file (no sampling_rate attribute)")
        d = {k: _h5_read(f, k, path) for k in f.keys()}
        return _broad(path, d, _sampling_rate(path, f.attrs["sampling_rate"]), str(f.attrs.get("info", "")))


_LOADMAT = """
import sys
import numpy as np
from scipy.io import loadmat
try:
    d = loadmat(sys.argv[1], squeeze_me=False)
except NotImplementedError:
    sys.exit(3)
except Exception as exc:
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    sys.stderr.write(msg)
    sys.exit(2)
np.savez(sys.argv[2], **{k: np.asarray(v) for k, v in d.items() if not k.startswith("__")})
"""


def _loadmat_isolated(path):
    """scipy's ``loadmat`` in a child process: on some damaged MAT files it crashes the whole
    process (a segmentation fault, found by tests/unit/test_fuzz_files.py), which no exception
    handler can catch. Returns the variables, or None for a MATLAB v7.3 (HDF5) file."""
    import subprocess
    import sys
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "vars.npz"
        r = subprocess.run(
            [sys.executable, "-c", _LOADMAT, str(path), str(out)], capture_output=True, text=True, timeout=600
        )
        if r.returncode == 3:
            return None
        if r.returncode != 0:
            why = (
                r.stderr.strip().splitlines()[-1]
                if r.returncode == 2 and r.stderr.strip()
                else f"the reader crashed on it (exit {r.returncode})"
            )
            raise ReaderError(f"{path}: not a readable MAT file ({why})")
        with np.load(out, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}


def read_broad_mat(path):
    d = _loadmat_isolated(path)
    if d is None:  # MATLAB v7.3 is HDF5
        return read_broad_hdf5(path)
    if "sampling_rate" not in d:
        raise ReaderError(f"{path}: not a BROAD MAT file (no sampling_rate)")
    return _broad(path, d, _sampling_rate(path, d["sampling_rate"]))


def _sampling_rate(path, value) -> float:
    """A BROAD file's ``sampling_rate`` (Hz): one positive finite number, or an error naming the file."""
    a = np.asarray(value).ravel()
    try:
        rate = float(a[0]) if a.size == 1 and a.dtype.kind in "iuf" else math.nan
    except (TypeError, ValueError):
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise ReaderError(f"{path}: sampling_rate must be one positive number (Hz), got {str(value)[:40]!r}")
    return rate


# -- DIDO -------------------------------------------------------------------------------------------
DIDO_RPM_UNIT = 1.0e4
"""DIDO's ``meas_rpm`` is in units of 10⁴ rpm."""


def _dido_rotor_speed(d, t, meta) -> dict:
    """``meas_rpm`` as ``rotor_speed`` (rad/s) on the IMU's rows: N×4, or N×5 with a time column
    first (both layouts are in the dataset); a negative or non-finite value is no reading (NaN,
    counted in a warning); rows that do not match the IMU's leave the speeds out (a warning). The
    readings' rate is that of the rows where a speed changes (the telemetry's, held on the IMU's
    rows: about 100 Hz on the shared flights)."""
    if "meas_rpm" not in d:
        return {}
    n = len(t)
    r = np.asarray(d["meas_rpm"], float)
    if r.ndim != 2 or r.shape[1] not in (4, 5) or len(r) != n:
        meta.setdefault("warnings", []).append(
            f"meas_rpm is {r.shape}, not (N, 4) or (N, 5) on the {n} IMU rows: the rotor speeds are left out"
        )
        return {}
    speed = r[:, -4:] * (DIDO_RPM_UNIT * RPM)
    bad = ~np.isfinite(speed) | (speed < 0)
    if bad.any():
        speed[bad] = np.nan
        meta.setdefault("warnings", []).append(f"meas_rpm: {int(bad.sum())} negative or non-finite value(s) left out")
    layout = "N×5: a time column, then the four speeds" if r.shape[1] == 5 else "N×4"
    meta["rotors"] = rotor_meta(
        4,
        numbering="DIDO's meas_rpm column order; the dataset states neither the rotors' places nor their spin",
        sources={"rotor_speed": f"meas_rpm ({layout}), 10⁴ rpm"},
        rates={"rotor_speed": _change_rate(t, speed)},
    )
    return {"rotor_speed": speed}


def _change_rate(t, a) -> float:
    """Hz of the rows where a value of ``a`` changes (a reading held over several rows counts once)."""
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    changed = (np.diff(np.nan_to_num(a), axis=0) != 0).any(axis=1).sum()
    return float(changed / span) if span > 0 else 0.0


def read_dido(path):
    with _h5(path) as f:
        _need(f, ("ts", "acc", "gyr", "gt_q"), path, "DIDO")
        d = {k: _h5_read(f, k, path) for k in f.keys()}
    t = np.asarray(d["ts"], float)
    truth = {"true_q": quat_enu_flu_to_ned_frd(d["gt_q"])}
    if "gt_p" in d:
        truth["true_pos"] = vec_enu_to_ned(d["gt_p"])
    if "gt_v" in d:
        truth["true_vel"] = vec_enu_to_ned(d["gt_v"])
    if "gt_gyr" in d:
        truth["true_gyr"] = vec_flu_to_frd(d["gt_gyr"])
    meta = {
        "dataset": "DIDO",
        "flight": Path(path).stem,
        "units": {"gyr": "rad/s", "acc": "m/s^2"},
        "frames": "gravity-aligned z-up / body z-up -> NED/FRD (heading offset arbitrary)",
        "truth_source": "motion capture (DIDO gt_*)",
        "align": {"nav": "heading"},
    }
    if "dynamic_params" in d:  # kept as stored: the dataset does not document its nine values
        meta["dido_dynamic_params"] = np.asarray(d["dynamic_params"], float).ravel().tolist()
    truth.update(_dido_rotor_speed(d, t, meta))
    return make_recording(path, "dido", t, vec_flu_to_frd(d["gyr"]), vec_flu_to_frd(d["acc"]), None, meta, **truth)


# -- Blackbird (UZH-RPG preparation) -------------------------------------------------------------------
def read_blackbird(path, *, calibrated: bool = False):
    """``path``: the folder with data.hdf5 and stamped_groundtruth_imu.txt, or data.hdf5 itself.
    The IMU frame is kept as the body frame (it is the frame the Vicon pose is given for);
    the z-up world becomes NED."""
    p = Path(path)
    folder = p if p.is_dir() else p.parent
    h5, gt_path = folder / "data.hdf5", folder / "stamped_groundtruth_imu.txt"
    for f_ in (h5, gt_path):
        if not f_.is_file():
            raise ReaderError(f"{path}: a Blackbird folder needs {f_.name}")
    with _h5(h5) as f:
        _need(f, ("ts", "gyro_raw", "accel_raw"), h5, "Blackbird")
        t = _h5_read(f, "ts", h5)
        gyr = _h5_read(f, "gyro_calib" if calibrated else "gyro_raw", h5)
        acc = _h5_read(f, "accel_calib" if calibrated else "accel_raw", h5)
    try:
        gt = np.loadtxt(gt_path, comments="#", ndmin=2)
    except ValueError as exc:
        raise ReaderError(f"{gt_path}: malformed ground-truth text ({exc})") from None
    if gt.shape[1] < 8:
        raise ReaderError(f"{gt_path}: expected ts x y z qx qy qz qw [vx vy vz] per row")
    q = z_up_nav_to_ned(resample_quat(gt[:, 0], gt[:, [7, 4, 5, 6]], t))
    truth = {"true_q": q}
    if len(gt) == len(t) and np.allclose(gt[:, 0], t):
        truth["true_pos"] = vec_enu_to_ned(gt[:, 1:4])
        if gt.shape[1] >= 11:
            truth["true_vel"] = vec_enu_to_ned(gt[:, 8:11])
    meta = {
        "dataset": "Blackbird",
        "sequence": folder.name,
        "units": {"gyr": "rad/s", "acc": "m/s^2"},
        "frames": "Vicon z-up world -> NED; body = the IMU's own axes",
        "truth_source": "Vicon (stamped_groundtruth_imu.txt, x y z w)",
        "align": {"nav": "heading"},
    }
    return make_recording(path, "blackbird", t, gyr, acc, None, meta, **truth)


# -- RepoIMU ----------------------------------------------------------------------------------------
def read_repoimu(path):
    """``;``-separated, two header rows: time, Vicon quaternion w x y z, accelerometer,
    gyroscope, magnetometer (normalised). All-zero quaternions mean no truth."""
    try:
        data = np.genfromtxt(path, delimiter=";", skip_header=2, usecols=range(14), invalid_raise=False)
    except (ValueError, OSError) as exc:
        raise ReaderError(f"{path}: not a readable RepoIMU CSV ({exc})") from None
    data = np.atleast_2d(data)
    if data.shape[1] != 14 or len(data) == 0:
        raise ReaderError(f"{path}: expected 14 ';'-separated columns (time, quaternion, acc, gyr, mag)")
    data = data[np.isfinite(data[:, [0, 5, 6, 7, 8, 9, 10]]).all(axis=1)]
    q = data[:, 1:5].copy()
    none = (np.abs(q).sum(axis=1) == 0) | ~np.isfinite(q).all(axis=1)
    q[none] = [1.0, 0, 0, 0]
    q = quat_enu_flu_to_ned_frd(q / np.linalg.norm(q, axis=1, keepdims=True))
    q[none] = np.nan
    meta = {
        "dataset": "RepoIMU",
        "trial": Path(path).stem,
        "units": {"gyr": "rad/s", "acc": "m/s^2", "mag": "normalised"},
        "frames": "Vicon z-up world and sensor z-up -> NED/FRD; the IMU and marker bodies are not "
        "aligned (evaluation estimates the body rotation)",
        "truth_source": "Vicon",
        "rows_without_truth": int(none.sum()),
        "align": {"nav": "heading", "body": True},
    }
    return make_recording(
        path,
        "repoimu",
        data[:, 0],
        vec_flu_to_frd(data[:, 8:11]),
        vec_flu_to_frd(data[:, 5:8]),
        vec_flu_to_frd(data[:, 11:14]),
        meta,
        true_q=q,
    )
