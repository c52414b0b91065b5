"""Benchmarks on real recordings: BROAD with its own metric, and the quadrotor flights (DIDO,
Blackbird) with roll/pitch/yaw RMS; quadest's filters and the installed peers side by side
(docs/readers.md, benchmarks)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from quadest.evaluation.align import fit_alignment
from quadest.evaluation.metrics import summarize_errors
from quadest.filters import FILTERS


def evaluation_mask(rec) -> np.ndarray:
    """Rows to evaluate: ``meta['evaluate_intervals_s']`` (BROAD's movement phases) or all."""
    iv = rec.meta.get("evaluate_intervals_s")
    if not iv:
        return np.ones(len(rec), bool)
    m = np.zeros(len(rec), bool)
    for a, b in iv:
        m |= (rec.t >= a) & (rec.t <= b)
    return m


def estimate_all(rec, names, params: dict | None = None) -> dict:
    """``{name: q (N, 4)}`` for quadest filters and peers (names from FILTERS or PEERS)."""
    from quadest.evaluation.compare import declination_of
    from quadest.evaluation.peers import PEERS, run_peer
    from quadest.filters import make_filter

    params = params or {}
    out = {}
    for n in names:
        if n in FILTERS:
            out[n] = make_filter(n, declination=declination_of(rec), **params.get(n, {})).run(rec).q
        elif n in PEERS:
            out[n] = run_peer(n, rec, use_mag=rec.has_mag)
        else:
            raise ValueError(f"unknown filter {n!r}")
    return out


def align_estimate(rec, q, *, truth: str = "true_q", nav: str = "none", body: bool = False, mask=None):
    """The estimate in the truth's frames and the :class:`Alignment` removed (None if none asked)."""
    if nav == "none" and not body:
        return q, None
    m = evaluation_mask(rec) if mask is None else mask
    al = fit_alignment(q, getattr(rec, truth), nav=nav, body=body, mask=m, rate_hz=rec.imu_rate_hz())
    return al.apply(q), al


def evaluate(rec, q, *, truth: str = "true_q", nav: str = "none", body: bool = False, mask=None) -> dict:
    """Error figures of one estimate after removing the constant rotations asked for; the
    alignment removed is reported under ``"alignment"``."""
    m = evaluation_mask(rec) if mask is None else mask
    qa, al = align_estimate(rec, q, truth=truth, nav=nav, body=body, mask=m)
    out = summarize_errors(qa, getattr(rec, truth), m)
    if al is not None:
        out["alignment"] = al.describe()
    return out


def default_names(include_peers: bool = True) -> list[str]:
    from quadest.evaluation.peers import available_peers

    return list(FILTERS) + (available_peers() if include_peers else [])


def _files(data_dir, pattern):
    d = Path(data_dir)
    if not d.is_dir():
        raise ValueError(f"{data_dir}: no such folder")
    return sorted(d.glob(pattern))


METRICS = ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg")


def benchmark_broad(data_dir, names=None, *, trials: str = "*", nav: str = "none", progress: bool = False) -> dict:
    """Every filter on every BROAD trial in ``data_dir`` (HDF5 or MAT): total, heading and
    inclination RMSE over the movement phases, per trial and averaged per group of trials.json."""
    from tqdm.auto import tqdm

    from quadest.readers import read_recording

    names = list(names or default_names())
    files = [f for f in _files(data_dir, trials) if f.suffix.lower() in (".hdf5", ".h5", ".mat")]
    if not files:
        raise ValueError(f"{data_dir}: no BROAD trial (*.hdf5 or *.mat) matching {trials!r}")
    groups_of = {}
    tj = Path(data_dir) / "trials.json"
    if tj.is_file():
        groups_of = {k: v["groups"] for k, v in json.loads(tj.read_text())["trials"].items()}
    out = {"trials": {}, "groups": {}, "filters": names, "alignment": nav}
    bar = tqdm(total=len(files) * len(names), unit="run", desc="benchmark broad", disable=not progress)
    for f in files:
        rec = read_recording(f, "broad")
        trial = f.stem
        out["trials"][trial] = {}
        for n in names:
            bar.set_postfix_str(f"{trial[:24]} {n}")
            q = estimate_all(rec, [n])[n]
            s = evaluate(rec, q, nav=nav)
            out["trials"][trial][n] = {k: s[k] for k in METRICS}
            bar.update(1)
    bar.close()
    groups: dict[str, list[str]] = {}
    for trial in out["trials"]:
        for g in groups_of.get(trial, ["all_trials"]):
            groups.setdefault(g, []).append(trial)
    for g, members in groups.items():
        out["groups"][g] = {n: {k: float(np.mean([out["trials"][t][n][k] for t in members])) for k in METRICS}
                            for n in names}
        out["groups"][g]["_trials"] = len(members)
    return out


def find_flights(data_dir) -> list[Path]:
    """DIDO HDF5 files and Blackbird folders anywhere under ``data_dir``."""
    from quadest.readers import detect_format

    d = Path(data_dir)
    if not d.is_dir():
        raise ValueError(f"{data_dir}: no such folder")
    found = []
    for p in sorted(d.rglob("*")):
        if p.is_dir() and (p / "data.hdf5").is_file() and (p / "stamped_groundtruth_imu.txt").is_file():
            found.append(p)
        elif p.is_file() and p.suffix.lower() in (".hdf5", ".h5") and p.name != "data.hdf5":
            try:
                if detect_format(p) == "dido":
                    found.append(p)
            except ValueError:
                pass
    return found


def benchmark_flights(data_dir, names=None, *, nav: str = "heading", progress: bool = False) -> dict:
    """Roll, pitch and yaw RMS on the quadrotor flights (6-axis: no magnetometer, so the
    heading offset between the estimate's and the motion capture's frames is removed)."""
    from tqdm.auto import tqdm

    from quadest.readers import read_recording

    names = list(names or default_names())
    flights = find_flights(data_dir)
    if not flights:
        raise ValueError(f"{data_dir}: no DIDO flight (*.hdf5) or Blackbird folder found")
    out = {"flights": {}, "mean": {}, "filters": names, "alignment": nav}
    bar = tqdm(total=len(flights) * len(names), unit="run", desc="benchmark flights", disable=not progress)
    for f in flights:
        rec = read_recording(f)
        key = f"{rec.meta.get('dataset', '')}/{f.parent.name + '/' if f.is_dir() else ''}{f.stem if f.is_file() else f.name}"
        out["flights"][key] = {"samples": len(rec), "duration_s": rec.duration}
        for n in names:
            bar.set_postfix_str(f"{key[:24]} {n}")
            s = evaluate(rec, estimate_all(rec, [n])[n], nav=nav)
            out["flights"][key][n] = {"rms_deg": s["rms_deg"], "total_rmse_deg": s["total_rmse_deg"],
                                      "inclination_rmse_deg": s["inclination_rmse_deg"],
                                      "alignment": s.get("alignment")}
            bar.update(1)
    bar.close()
    for n in names:
        rows = [v[n] for v in out["flights"].values()]
        out["mean"][n] = {a: float(np.mean([r["rms_deg"][a] for r in rows])) for a in ("roll", "pitch", "yaw")}
        out["mean"][n]["inclination_rmse_deg"] = float(np.mean([r["inclination_rmse_deg"] for r in rows]))
    return out


def format_broad(res: dict) -> str:
    names = res["filters"]
    w = max(9, *(len(n) for n in names)) + 1
    lines = [f"BROAD: total RMSE [deg] over the movement phases (alignment: {res['alignment']})",
             "trial".ljust(34) + "".join(n.rjust(w) for n in names)]
    for t, row in res["trials"].items():
        lines.append(t[:33].ljust(34) + "".join(f"{row[n]['total_rmse_deg']:{w}.2f}" for n in names))
    lines.append("")
    lines.append("group means: total / heading / inclination RMSE [deg]")
    lines.append("group (trials)".ljust(34) + "".join(n.rjust(w) for n in names))
    for g, row in res["groups"].items():
        lines.append(f"{g} ({row['_trials']})"[:33].ljust(34) + "".join(f"{row[n]['total_rmse_deg']:{w}.2f}" for n in names))
        lines.append("  heading".ljust(34) + "".join(f"{row[n]['heading_rmse_deg']:{w}.2f}" for n in names))
        lines.append("  inclination".ljust(34) + "".join(f"{row[n]['inclination_rmse_deg']:{w}.2f}" for n in names))
    return "\n".join(lines)


def format_flights(res: dict) -> str:
    names = res["filters"]
    w = max(9, *(len(n) for n in names)) + 1
    lines = [f"quadrotor flights: RMS error [deg] (6-axis; alignment: {res['alignment']})"]
    for f, row in res["flights"].items():
        lines.append(f"{f} ({row['samples']} samples, {row['duration_s']:.0f} s)")
        lines.append("".ljust(12) + "".join(n.rjust(w) for n in names))
        for a in ("roll", "pitch", "yaw"):
            lines.append(f"  {a}".ljust(12) + "".join(f"{row[n]['rms_deg'][a]:{w}.2f}" for n in names))
    lines.append("mean over flights")
    lines.append("".ljust(12) + "".join(n.rjust(w) for n in names))
    for a in ("roll", "pitch", "yaw"):
        lines.append(f"  {a}".ljust(12) + "".join(f"{res['mean'][n][a]:{w}.2f}" for n in names))
    return "\n".join(lines)
