"""What ``quadest info`` prints: duration, rates, ranges, gaps, the truth present and the rotors'
channels."""

import numpy as np

from quadest.data.checks import BLOCK, GAP_FACTOR, GAP_MIN_S, jitter_note, row_norms, timestamp_jitter
from quadest.data.recording import ROTOR_FIELDS, TRUTH_FIELDS, Recording

IRREGULAR_FACTOR = 1.5  # an interval longer than this many median intervals is irregular


def summarize(rec: Recording) -> dict:
    """Facts about a recording as a plain dict (JSON-serialisable)."""
    dt = np.diff(rec.t)
    med = float(np.median(dt)) if len(dt) else float("nan")
    gaps = np.flatnonzero(dt > max(GAP_FACTOR * med, GAP_MIN_S)) if len(dt) else np.array([], int)
    irregular = int((dt > IRREGULAR_FACTOR * med).sum()) if len(dt) else 0
    out = {
        "samples": len(rec),
        "t_start_s": float(rec.t[0]),
        "duration_s": rec.duration,
        "imu_rate_hz": rec.imu_rate_hz(),
        "dt_min_s": float(dt.min()) if len(dt) else float("nan"),
        "dt_max_s": float(dt.max()) if len(dt) else float("nan"),
        "mag_samples": int(np.isfinite(rec.mag[:, 0]).sum()),
        "mag_rate_hz": rec.mag_rate_hz(),
        "gaps": {
            "count": int(len(gaps)),
            "longest_s": float(dt[gaps].max()) if len(gaps) else 0.0,
            "first_at_s": float(rec.t[gaps[0]]) if len(gaps) else None,
        },
        "irregular_intervals": irregular,
        **timestamp_jitter(dt, med),
        "ranges": {},
        "truth": {k: TRUTH_FIELDS[k][1] for k in rec.truth},
        "units": rec.meta.get("units", {}),
        "dropped_rows": int(rec.meta.get("dropped_rows", 0)),
        "warnings": list(rec.meta.get("warnings", [])),
    }
    for name in ("gyr", "acc", "mag"):
        a = getattr(rec, name)
        ok = np.isfinite(a[:, 0])
        if ok.any():
            v = a if ok.all() else a[ok]  # no copy of a long recording's array when every row is there
            out["ranges"][name] = {
                "min": v.min(axis=0).tolist(),
                "max": v.max(axis=0).tolist(),
                "norm_mean": sum(float(row_norms(v[s : s + BLOCK]).sum()) for s in range(0, len(v), BLOCK)) / len(v),
            }
    for key in ("source", "format", "dataset", "frames", "reference", "scenario", "preset", "seed"):
        if key in rec.meta:
            out[key] = rec.meta[key]
    if "imu_sources" in rec.meta:
        out["imu_source"] = rec.meta.get("imu_source")
        out["imu_sources"] = rec.meta["imu_sources"]
    out["declination_deg"] = float(np.degrees(rec.declination))
    out["declination_source"] = rec.declination_source
    out["rotors"] = rotor_summary(rec)
    return out


def rotor_summary(rec: Recording) -> dict:
    """The rotors' channels: per channel its rows with a reading and each rotor's median and largest
    value; and what the source states of the rotors (``meta['rotors']``: numbering, spin, the
    readings' sources and rates)."""
    out = {"count": rec.rotors, "channels": {}, **{k: v for k, v in rec.meta.get("rotors", {}).items() if k != "count"}}
    for name in rec.rotor_channels:
        a = getattr(rec, name)
        read = np.isfinite(a)
        rows = read.any(axis=1)
        out["channels"][name] = {
            "meaning": ROTOR_FIELDS[name],
            "rows": int(rows.sum()),
            "median": [float(np.median(a[read[:, i], i])) if read[:, i].any() else None for i in range(a.shape[1])],
            "max": [float(a[read[:, i], i].max()) if read[:, i].any() else None for i in range(a.shape[1])],
        }
    return out


def format_summary(s: dict, name: str = "") -> str:
    """Human-readable text of :func:`summarize`'s dict."""
    u = s.get("units", {})
    lines = [f"recording   {name}".rstrip()]
    for key in ("source", "format", "dataset", "frames", "reference", "scenario", "preset", "seed"):
        if key in s:
            lines.append(f"{key:<11} {s[key]}")
    if "imu_sources" in s:
        others = [x for x in s["imu_sources"] if x != "logged"]
        also = f" (also in the log: --imu {', '.join(others)})" if others else ""
        lines.append(f"IMU from    {s['imu_source']}{also}")
    if "declination_deg" in s:
        lines.append(f"declination {s['declination_deg']:+.2f}° ({s['declination_source']})")
    lines += [
        f"samples     {s['samples']}",
        f"duration    {s['duration_s']:.3f} s (from t = {s['t_start_s']:.3f} s)",
        f"IMU rate    {s['imu_rate_hz']:.2f} Hz (interval {s['dt_min_s'] * 1e3:.3f} to {s['dt_max_s'] * 1e3:.3f} ms)",
        f"mag         {s['mag_samples']} samples, {s['mag_rate_hz']:.2f} Hz"
        if s["mag_samples"]
        else "mag         none",
    ]
    for w in s.get("warnings", []):
        lines.append(f"warning     {w}")
    if s.get("dropped_rows"):
        lines.append(
            f"dropped     {s['dropped_rows']} row(s) of the file (repeated or decreasing time, or a "
            "non-finite IMU value)"
        )
    g = s["gaps"]
    lines.append(
        f"gaps        {g['count']} (intervals > {GAP_FACTOR:g}x median and {GAP_MIN_S:g} s: the estimators "
        f"start again after each), longest {g['longest_s'] * 1e3:.1f} ms, first at t = {g['first_at_s']:.3f} s"
        if g["count"]
        else "gaps        none"
    )
    if s.get("irregular_intervals"):
        lines.append(f"irregular   {s['irregular_intervals']} intervals > {IRREGULAR_FACTOR:g}x median")
    if note := jitter_note(s):
        lines.append(f"jitter      {note}")
    for name, r in s["ranges"].items():
        unit = u.get(name, "")
        lo = ", ".join(f"{v:+.3g}" for v in r["min"])
        hi = ", ".join(f"{v:+.3g}" for v in r["max"])
        lines.append(f"{name:<11} min [{lo}]  max [{hi}]  mean norm {r['norm_mean']:.4g} {unit}")
    truth = s["truth"]
    lines.append("truth       " + ("; ".join(f"{k} ({v})" for k, v in truth.items()) if truth else "none"))
    return "\n".join(lines + _rotor_lines(s.get("rotors", {})))


def _rotor_lines(r: dict) -> list[str]:
    """:func:`rotor_summary` as lines (none without rotor channels)."""
    if not r.get("count"):
        return []
    stated = [f"{k} {r[k]}" for k in ("frame", "motors", "spin", "numbering") if k in r]
    lines = [f"rotors      {r['count']}" + (f" ({'; '.join(stated)})" if stated else "")]
    for name, c in r["channels"].items():
        med = ", ".join("-" if v is None else f"{v:.4g}" for v in c["median"])
        rate = r.get("rates_hz", {}).get(name)
        source = r.get("sources", {}).get(name)
        lines.append(
            f"  {name:<13} {c['rows']} rows{f', read at {rate:.1f} Hz' if rate else ''}; median [{med}] "
            f"({c['meaning']}){f'; from {source}' if source else ''}"
        )
    return lines
