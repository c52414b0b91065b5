"""Benchmarks on real recordings: BROAD with its own metric, and the quadrotor flights (DIDO,
Blackbird) with roll/pitch/yaw RMS; quadest's filters and the installed peers side by side
(docs/readers.md, benchmarks)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from quadest.evaluation.runner import estimate, score_result
from quadest.filters import FILTERS, available_peers
from quadest.progress import bar as progress_bar
from quadest.readers import detect_format, read_recording


def default_names(include_peers: bool = True) -> list[str]:
    return list(FILTERS) + (available_peers() if include_peers else [])


def _folder(data_dir) -> Path:
    d = Path(data_dir)
    if not d.is_dir():
        raise ValueError(f"{data_dir}: no such folder")
    return d


def _files(data_dir, pattern):
    return sorted(_folder(data_dir).glob(pattern))


def _axis_means(rows) -> dict:
    """Mean over recordings of each axis's RMS error (degrees)."""
    return {a: float(np.mean([r["rms_deg"][a] for r in rows])) for a in ("roll", "pitch", "yaw")}


METRICS = ("total_rmse_deg", "heading_rmse_deg", "inclination_rmse_deg")
NEES = ("nees", "nees_tilt")


def _nees_means(rows) -> dict:
    """Mean over recordings of each NEES figure the rows carry (none for an estimator that
    reports no covariance)."""
    return {k: float(np.mean([r[k] for r in rows])) for k in NEES if rows and all(k in r for r in rows)}


def benchmark_broad(data_dir, names=None, *, trials: str = "*", nav: str = "none", progress: bool = False) -> dict:
    """Every filter on every BROAD trial in ``data_dir`` (HDF5 or MAT): total, heading and
    inclination RMSE over the movement phases, per trial and averaged per group of trials.json."""
    names = list(names or default_names())
    files = [f for f in _files(data_dir, trials) if f.suffix.lower() in (".hdf5", ".h5", ".mat")]
    if not files:
        raise ValueError(f"{data_dir}: no BROAD trial (*.hdf5 or *.mat) matching {trials!r}")
    groups_of = {}
    tj = Path(data_dir) / "trials.json"
    if tj.is_file():
        groups_of = {k: v["groups"] for k, v in json.loads(tj.read_text())["trials"].items()}
    out = {"trials": {}, "groups": {}, "filters": names, "alignment": nav}
    bar = progress_bar(total=len(files) * len(names), unit="run", desc="benchmark broad", disable=not progress)
    for f in files:
        rec = read_recording(f, "broad")
        trial = f.stem
        out["trials"][trial] = {}
        for n in names:
            bar.set_postfix_str(f"{trial[:24]} {n}")
            s = score_result(rec, estimate(rec, n), nav=nav, body=False)
            out["trials"][trial][n] = {k: s[k] for k in METRICS + NEES if k in s}
            bar.update(1)
    bar.close()
    groups: dict[str, list[str]] = {}
    for trial in out["trials"]:
        for g in groups_of.get(trial, ["all_trials"]):
            groups.setdefault(g, []).append(trial)
    for g, members in groups.items():
        out["groups"][g] = {
            n: {k: float(np.mean([out["trials"][t][n][k] for t in members])) for k in METRICS}
            | _nees_means([out["trials"][t][n] for t in members])
            for n in names
        }
        out["groups"][g]["_trials"] = len(members)
    return out


def find_flights(data_dir) -> list[Path]:
    """DIDO HDF5 files and Blackbird folders anywhere under ``data_dir``."""
    found = []
    for p in sorted(_folder(data_dir).rglob("*")):
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
    names = list(names or default_names())
    flights = find_flights(data_dir)
    if not flights:
        raise ValueError(
            f"{data_dir}: no DIDO flight (*.hdf5) or Blackbird folder found (quadest data fetch "
            "blackbird_clover puts the Blackbird flights in the cache; DIDO: quadest data list)"
        )
    out = {"flights": {}, "mean": {}, "filters": names, "alignment": nav}
    bar = progress_bar(total=len(flights) * len(names), unit="run", desc="benchmark flights", disable=not progress)
    for f in flights:
        rec = read_recording(f)
        folder = f.parent.name + "/" if f.is_dir() else ""
        key = f"{rec.meta.get('dataset', '')}/{folder}{f.stem if f.is_file() else f.name}"
        out["flights"][key] = {"samples": len(rec), "duration_s": rec.duration}
        for n in names:
            bar.set_postfix_str(f"{key[:24]} {n}")
            s = score_result(rec, estimate(rec, n), nav=nav, body=False)
            out["flights"][key][n] = {
                "rms_deg": s["rms_deg"],
                "total_rmse_deg": s["total_rmse_deg"],
                "inclination_rmse_deg": s["inclination_rmse_deg"],
                "alignment": s.get("alignment"),
            } | {k: s[k] for k in NEES if k in s}
            bar.update(1)
    bar.close()
    for n in names:
        rows = [v[n] for v in out["flights"].values()]
        out["mean"][n] = _axis_means(rows)
        out["mean"][n]["inclination_rmse_deg"] = float(np.mean([r["inclination_rmse_deg"] for r in rows]))
        out["mean"][n].update(_nees_means(rows))
    return out


def find_repoimu(data_dir) -> list[Path]:
    """RepoIMU trials (their ``;``-separated CSV files) anywhere under ``data_dir``."""
    found = []
    for p in sorted(_folder(data_dir).rglob("*.csv")):
        try:
            if detect_format(p) == "repoimu":
                found.append(p)
        except ValueError:
            pass
    return found


def benchmark_repoimu(data_dir, names=None, *, progress: bool = False) -> dict:
    """Roll, pitch, yaw and total RMS on the RepoIMU trials (9-axis; the reader's alignment: the
    IMU's and Vicon's frames differ by a constant rotation in the body and a heading, both
    estimated and removed per run, as BROAD's metric does with its heading)."""
    names = list(names or default_names())
    trials = find_repoimu(data_dir)
    if not trials:
        raise ValueError(f"{data_dir}: no RepoIMU trial (*.csv) found (quadest data list says where to get them)")
    out = {
        "trials": {},
        "mean": {},
        "filters": names,
        "alignment": "heading and body rotation (the reader's)",
        "without_truth": [],
    }
    bar = progress_bar(total=len(trials) * len(names), unit="run", desc="benchmark repoimu", disable=not progress)
    for f in trials:
        rec = read_recording(f)
        key = f"{f.parent.name}/{f.stem}"
        if rec.true_q is None or np.isfinite(rec.true_q[:, 0]).sum() < 2:  # a static trial without Vicon
            out["without_truth"].append(key)
            bar.update(len(names))
            continue
        out["trials"][key] = {"samples": len(rec), "duration_s": rec.duration}
        for n in names:
            bar.set_postfix_str(f"{key[:24]} {n}")
            s = score_result(rec, estimate(rec, n))
            out["trials"][key][n] = {
                "rms_deg": s["rms_deg"],
                "total_rmse_deg": s["total_rmse_deg"],
                "samples": s["samples"],
            } | {k: s[k] for k in NEES if k in s}
            bar.update(1)
    bar.close()
    for n in names:
        rows = [v[n] for v in out["trials"].values()]
        out["mean"][n] = _axis_means(rows)
        out["mean"][n]["total_rmse_deg"] = float(np.mean([r["total_rmse_deg"] for r in rows]))
        out["mean"][n].update(_nees_means(rows))
    return out


NEES_LABELS = {"nees": "NEES", "nees_tilt": "NEES tilt"}
NEES_NOTE = (
    "NEES: mean normalised error squared of the reported attitude covariance, 3 dof (ideal 3); "
    "NEES tilt: its tilt's part, 2 dof (ideal 2; without a magnetometer the heading's part is near 0, "
    "so read this one); blank where an estimator reports none"
)


def _nees_lines(row: dict, names, w: int, indent: int) -> list[str]:
    """The NEES rows of one recording or mean (``row[name]``), if any estimator has them."""
    lines = []
    for k, label in NEES_LABELS.items():
        if any(k in row[n] for n in names):
            cells = "".join((f"{row[n][k]:{w}.2f}" if k in row[n] else " " * w) for n in names)
            lines.append(f"  {label}".ljust(indent) + cells)
    return lines


def format_repoimu(res: dict) -> str:
    names = res["filters"]
    w = max(9, *(len(n) for n in names)) + 1
    lines = [
        f"RepoIMU: RMS error [deg] (9-axis; alignment: {res['alignment']})",
        "trial / roll, pitch, yaw, total".ljust(36) + "".join(n.rjust(w) for n in names),
    ]
    for t, row in res["trials"].items():
        lines.append(f"{t} ({row['samples']} samples)")
        for a in ("roll", "pitch", "yaw"):
            lines.append(f"  {a}".ljust(36) + "".join(f"{row[n]['rms_deg'][a]:{w}.2f}" for n in names))
        lines.append("  total".ljust(36) + "".join(f"{row[n]['total_rmse_deg']:{w}.2f}" for n in names))
        lines += _nees_lines(row, names, w, 36)
    if res["without_truth"]:
        lines.append(f"not scored (no Vicon truth): {', '.join(res['without_truth'])}")
    lines.append("mean over trials")
    for a in ("roll", "pitch", "yaw", "total_rmse_deg"):
        lines.append(
            f"  {a}".ljust(36)
            + "".join(
                f"{(res['mean'][n][a] if a != 'total_rmse_deg' else res['mean'][n]['total_rmse_deg']):{w}.2f}"
                for n in names
            )
        )
    nees = _nees_lines(res["mean"], names, w, 36)
    return "\n".join(lines + nees + ([NEES_NOTE] if nees else []))


def format_broad(res: dict) -> str:
    names = res["filters"]
    w = max(9, *(len(n) for n in names)) + 1
    lines = [
        f"BROAD: total RMSE [deg] over the movement phases (alignment: {res['alignment']})",
        "trial".ljust(34) + "".join(n.rjust(w) for n in names),
    ]
    for t, row in res["trials"].items():
        lines.append(t[:33].ljust(34) + "".join(f"{row[n]['total_rmse_deg']:{w}.2f}" for n in names))
    per_trial = [(t, _nees_lines(row, names, w, 34)) for t, row in res["trials"].items()]
    if any(nl for _, nl in per_trial):
        lines += ["", "mean NEES of the reported covariance per trial (3 dof, and the tilt's part)"]
        for t, nl in per_trial:
            lines += [t[:33]] + nl
    lines.append("")
    lines.append("group means: total / heading / inclination RMSE [deg]")
    lines.append("group (trials)".ljust(34) + "".join(n.rjust(w) for n in names))
    for g, row in res["groups"].items():
        lines.append(
            f"{g} ({row['_trials']})"[:33].ljust(34) + "".join(f"{row[n]['total_rmse_deg']:{w}.2f}" for n in names)
        )
        lines.append("  heading".ljust(34) + "".join(f"{row[n]['heading_rmse_deg']:{w}.2f}" for n in names))
        lines.append("  inclination".ljust(34) + "".join(f"{row[n]['inclination_rmse_deg']:{w}.2f}" for n in names))
        lines += _nees_lines(row, names, w, 34)
    has_nees = any(k in row[n] for row in res["groups"].values() for n in names for k in NEES)
    return "\n".join(lines + ([NEES_NOTE] if has_nees else []))


def format_flights(res: dict) -> str:
    names = res["filters"]
    w = max(9, *(len(n) for n in names)) + 1
    lines = [f"quadrotor flights: RMS error [deg] (6-axis; alignment: {res['alignment']})"]
    for f, row in res["flights"].items():
        lines.append(f"{f} ({row['samples']} samples, {row['duration_s']:.0f} s)")
        lines.append("".ljust(12) + "".join(n.rjust(w) for n in names))
        for a in ("roll", "pitch", "yaw"):
            lines.append(f"  {a}".ljust(12) + "".join(f"{row[n]['rms_deg'][a]:{w}.2f}" for n in names))
        lines += _nees_lines(row, names, w, 12)
    lines.append("mean over flights")
    lines.append("".ljust(12) + "".join(n.rjust(w) for n in names))
    for a in ("roll", "pitch", "yaw"):
        lines.append(f"  {a}".ljust(12) + "".join(f"{res['mean'][n][a]:{w}.2f}" for n in names))
    nees = _nees_lines(res["mean"], names, w, 12)
    return "\n".join(lines + nees + ([NEES_NOTE] if nees else []))
