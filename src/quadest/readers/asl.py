"""The ASL (EuRoC / TUM-VI) layout that most visual-inertial datasets use: a folder ``mav0/``
with ``imu0/data.csv`` (``timestamp [ns], w_RS_S_x..z [rad/s], a_RS_S_x..z [m/s²]``) and the
ground truth in ``state_groundtruth_estimate0/data.csv`` (EuRoC: ``timestamp, p_RS_R_x..z,
q_RS_w, q_RS_x..z, v_RS_R_x..z, ...``, the IMU's own pose) or ``mocap0/data.csv`` (TUM-VI:
``timestamp, p_RS_R_x..z, q_RS_w, q_RS_x..z``, the markers' pose). The path is the folder that
holds ``mav0/`` or ``mav0/`` itself (docs/readers.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from quadest.readers.common import ReaderError, make_recording, resample_quat, z_up_nav_to_ned
from quadest.rotation.frames import vec_enu_to_ned

IMU = Path("imu0") / "data.csv"
TRUTHS = {
    "state_groundtruth_estimate0": "the ground-truth estimate of the IMU's pose (EuRoC)",
    "mocap0": "the motion-capture markers' pose (TUM-VI; body rotation to the IMU fitted)",
}


def asl_folder(path) -> Path | None:
    """The ``mav0`` folder of ``path`` (``path`` itself or its ``mav0``), or None."""
    p = Path(path)
    for folder in (p, p / "mav0"):
        if (folder / IMU).is_file():
            return folder
    return None


def _table(path: Path, columns: int) -> np.ndarray:
    try:
        data = np.loadtxt(path, delimiter=",", comments="#", ndmin=2)
    except (ValueError, OSError) as exc:
        raise ReaderError(f"{path}: not a readable ASL CSV ({str(exc).splitlines()[0]})") from None
    if data.shape[1] < columns or len(data) == 0:
        raise ReaderError(f"{path}: expected at least {columns} comma-separated columns per row")
    return data


def _truth(mav: Path, t: np.ndarray) -> tuple[dict, str | None]:
    """The first ground truth found, on the IMU's times: attitude (z-up world to NED, the body
    its own), position and, from EuRoC's estimate, velocity (NaN outside the truth's span)."""
    for name in TRUTHS:
        path = mav / name / "data.csv"
        if not path.is_file():
            continue
        gt = _table(path, 8)
        tg = gt[:, 0] * 1e-9
        truth = {"true_q": z_up_nav_to_ned(resample_quat(tg, gt[:, 4:8], t))}
        truth["true_pos"] = _on_imu(t, tg, gt[:, 1:4])
        if name == "state_groundtruth_estimate0" and gt.shape[1] >= 11:
            truth["true_vel"] = _on_imu(t, tg, gt[:, 8:11])
        return truth, name
    return {}, None


def _on_imu(t, tg, v) -> np.ndarray:
    """A z-up vector series at the IMU's times, in NED; NaN outside the truth's span."""
    out = np.column_stack([np.interp(t, tg, v[:, i]) for i in range(3)])
    out[(t < tg[0]) | (t > tg[-1])] = np.nan
    return vec_enu_to_ned(out)


def read_asl(path):
    """IMU and ground truth of an ASL folder; the body frame is the IMU's own axes (S), the
    z-up world becomes NED with its heading offset left to the alignment."""
    mav = asl_folder(path)
    if mav is None:
        raise ReaderError(f"{path}: no imu0/data.csv in it or in its mav0/ (the EuRoC / TUM-VI layout)")
    imu = _table(mav / IMU, 7)
    t = imu[:, 0] * 1e-9
    truth, source = _truth(mav, t)
    meta = {
        "dataset": "ASL layout (EuRoC / TUM-VI)",
        "sequence": (mav.parent if mav.name == "mav0" else mav).name,
        "units": {"gyr": "rad/s", "acc": "m/s^2"},
        "frames": "z-up world -> NED; body = the IMU's own axes (S)",
        "truth_source": TRUTHS[source] if source else "none",
        "align": {"nav": "heading", "body": source == "mocap0"},
    }
    return make_recording(path, "asl", t, imu[:, 1:4], imu[:, 4:7], None, meta, **truth)
