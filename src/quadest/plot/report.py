"""A flight report a person opens in a browser: one self-contained HTML file (bokeh,
its scripts inlined: it opens offline), drawn from what :mod:`quadest.evaluation.inspect`
computed over the whole recording. Long recordings are decimated for display only (each drawn
point keeps its bucket's extremes); the tables' numbers come from all samples. Every time plot
shares one x range: zooming one zooms all."""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np
from bokeh.embed import file_html
from bokeh.layouts import column
from bokeh.models import Div, LinearColorMapper, Range1d, Span
from bokeh.palettes import Category10_10, Viridis256
from bokeh.plotting import figure
from bokeh.resources import INLINE
from scipy.signal import spectrogram

from quadest import __version__
from quadest.data.checks import jitter_note, median_interval, row_norms
from quadest.data.files import write_bytes
from quadest.evaluation.inspect import decimate

AXES = ("roll", "pitch", "yaw")


def _figure(title, x_range, y_label, name, height=230):
    kw = {"x_range": x_range} if x_range is not None else {}
    f = figure(
        title=title,
        height=height,
        sizing_mode="stretch_width",
        tools="xpan,xwheel_zoom,box_zoom,reset,save",
        active_scroll="xwheel_zoom",
        x_axis_label="time [s]",
        y_axis_label=y_label,
        name=name,
        **kw,
    )
    f.toolbar.logo = None
    return f


def _lines(f, t, series: dict, dashed=(), colours: dict | None = None):
    """One line per series (samples at ``t``, or display points ``(t, y)`` already decimated),
    coloured by ``colours[label]`` (one colour per estimator across a page) or in order; the
    legend beside the plot, not over the data."""
    for i, (label, y) in enumerate(series.items()):
        tt, yy = y if isinstance(y, tuple) else decimate(t, y)
        f.line(
            tt,
            yy,
            legend_label=label,
            color=(colours or {}).get(label, Category10_10[i % 10]),
            line_width=1.4,
            line_dash="dashed" if label in dashed else "solid",
        )
    if series:
        f.legend.click_policy = "hide"
        f.legend.label_text_font_size = "9pt"
        f.add_layout(f.legend[0], "right")


def _table(header, rows, table_id=None) -> str:
    attr = f' id="{table_id}"' if table_id else ""  # each Div is its own shadow root: the style goes with it
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f'{STYLE}<table class="q"{attr}><tr>{head}</tr>{body}</table>'


STYLE = """<style>
table.q {border-collapse: collapse; font: 13px sans-serif; margin: 4px 0 12px 0}
table.q td, table.q th {border: 1px solid #ccc; padding: 3px 8px; text-align: right}
table.q th {background: #f2f2f2} table.q td:first-child {text-align: left}
h2 {font: bold 17px sans-serif; margin: 18px 0 4px 0} p.q {font: 13px sans-serif; margin: 2px 0}
</style>"""


def _f(v, fmt="{:.2f}"):
    return "-" if v is None else fmt.format(v)


def _jitter(s: dict) -> str:
    """The intervals' spread about their mean, and what it does to a low-pass that followed it."""
    if s.get("jitter_gain") is None:
        return "-"
    return jitter_note(s) or f"{s['jitter_s'] * 1e3:.3f} ms about {s['interval_mean_s'] * 1e3:.3f} ms"


def summary_html(title: str, s: dict) -> str:
    rows = [
        ["source", s["source"]],
        ["vehicle or preset", s.get("vehicle") or "-"],
        ["file", s.get("file") or "-"],
        ["duration", f"{s['duration_s']:.2f} s"],
        ["IMU rows", s["rows"]],
        ["IMU rate", _f(s["imu_rate_hz"], "{:.1f} Hz")],
        ["magnetometer rate", _f(s["mag_rate_hz"], "{:.1f} Hz") if s["mag_rate_hz"] else "none"],
        [
            "gaps (> 1.5 sample periods)",
            f"{s['gaps']} ({s['gap_time_s']:.3f} s beyond the median interval, longest {s['longest_gap_s']:.3f} s)",
        ],
        ["timestamps' jitter", _jitter(s)],
        ["rows dropped or skipped by the reader", _f(s["dropped_rows"], "{}")],
        ["gyroscope clipped", f"{100 * s['gyro_clipped_share']:.2f} % of rows"],
        ["accelerometer clipped", f"{100 * s['acc_clipped_share']:.2f} % of rows"],
        [
            f"vibration RMS x / y / z (from {s['vibration_source']})"
            if s["vibration_rms_m_s2"]
            else "vibration RMS x / y / z",
            " / ".join(f"{v:.2f}" for v in s["vibration_rms_m_s2"]) + " m/s²"
            if s["vibration_rms_m_s2"]
            else s["vibration_source"],
        ],
        [
            "magnetic field disturbed (norm > 10 % off its median)",
            f"{100 * s['mag_disturbed_share']:.1f} % of samples" if "mag_disturbed_share" in s else "no magnetometer",
        ],
        [
            "attitude truth",
            {
                "true_q": "independent truth",
                "ref_q": "none: the autopilot's own estimate is the reference",
                None: "none: no errors can be shown",
            }[s["truth"]],
        ],
    ]
    ev = [
        [e["kind"], f"{e['start_s']:.2f}", f"{e['end_s']:.2f}", _f(e.get("rate_rad_s"), "{:.1f}")] for e in s["events"]
    ]
    return (
        f"{STYLE}<h1 style='font: bold 21px sans-serif'>{html.escape(title)}</h1>"
        f"<p class='q'>quadest {__version__}: every number from all samples; the plots are decimated for "
        f"display (each bucket's extremes kept) and share their time axis (zoom one, all follow).</p>"
        "<h2>Summary</h2>"
        + _table(["", ""], rows, "summary")
        + "<h2>Events</h2>"
        + (
            _table(["event", "from [s]", "to [s]", "rate [rad/s]"], ev, "events")
            if ev
            else "<p class='q'>none detected</p>"
        )
    )


def build_report(rec, summ: dict, att: dict, title: str) -> str:
    """The report's HTML (a string)."""
    return file_html(report_layout(rec, summ, att, title), INLINE, title)


def report_layout(rec, summ: dict, att: dict, title: str):
    """The report's bokeh layout: the summary, the attitude and its errors, the sensors."""
    t = rec.t
    xr = Range1d(float(t[0]), float(t[-1]))
    parts = [Div(text=summary_html(title, summ), sizing_mode="stretch_width")]
    truth = att["truth"]
    truth_label = {"true_q": "truth", "ref_q": "autopilot's estimate", None: None}[truth]
    euler = {(truth_label if k == truth else k): v for k, v in att["euler_deg"].items()}
    colours = {name: Category10_10[i % 10] for i, name in enumerate(euler)}  # one per estimator, every plot
    parts.append(
        Div(
            text=STYLE
            + "<h2>Attitude</h2>"
            + (
                ""
                if truth
                else "<p class='q'>The recording has no attitude truth and no autopilot estimate: no errors "
                "are shown.</p>"
            )
        )
    )
    for i, a in enumerate(AXES):
        f = _figure(f"{a} [deg]", xr, "deg", f"attitude-{a}")
        _lines(f, t, {k: v[i] for k, v in euler.items()}, dashed=(truth_label,), colours=colours)
        parts.append(f)
    if att["scores"]:
        label = "truth" if truth == "true_q" else "the autopilot's estimate (not an independent truth)"
        rows = [
            [n] + [f"{s['rms_deg'][a]:.3f}" for a in AXES] + [f"{s['total_rmse_deg']:.3f}"]
            for n, s in att["scores"].items()
        ]
        note = (
            " (no magnetometer: each estimate's constant heading offset removed)"
            if att.get("heading_offset_removed")
            else ""
        )
        if att.get("scored_from_s") is not None:
            note += f" (scored from the first magnetometer sample, t = {att['scored_from_s']:.3f} s)"
        parts.append(
            Div(
                text=f"<h2>Errors against {label}{note}</h2>"
                + _table(
                    ["estimator", "roll RMS [deg]", "pitch RMS [deg]", "yaw RMS [deg]", "total RMS [deg]"], rows, "rms"
                )
            )
        )
        for i, a in enumerate(AXES):
            f = _figure(f"{a} error [deg]", xr, "deg", f"error-{a}")
            _lines(f, t, {k: v[i] for k, v in att["error_deg"].items()}, colours=colours)
            parts.append(f)
    parts += _failure_sections(rec, att, xr)
    parts.append(Div(text=STYLE + "<h2>Sensors</h2>"))
    for name, data, unit in (("gyroscope", rec.gyr, "rad/s"), ("accelerometer", rec.acc, "m/s²")):
        f = _figure(f"{name} [{unit}]", xr, unit, f"sensor-{name}")
        _lines(f, t, {f"{name[:3]} {ax}": data[:, j] for j, ax in enumerate("xyz")})
        parts.append(f)
    if att.get("mag") is not None:
        norm, dip = att["mag"]
        for label, y, unit, nm in (
            ("magnetometer norm", norm, rec.meta.get("units", {}).get("mag", ""), "mag-norm"),
            ("magnetic dip below the horizontal", dip, "deg", "mag-dip"),
        ):
            f = _figure(f"{label} [{unit}]", xr, unit, nm, height=200)
            _lines(f, t, {label: y})
            parts.append(f)
    if att.get("rotors") is not None:
        tr, speeds = att["rotors"]
        f = _figure("rotor speeds [rad/s]", xr, "rad/s", "rotor-speeds")
        _lines(f, tr, {k.replace("_speed", ""): v for k, v in speeds.items()})
        parts.append(f)
    for name, label, unit in (("rotor_speed", "rotor speeds", "rad/s"), ("motor_command", "motor commands", "0 to 1")):
        a = getattr(rec, name)  # the recording's own channels (a flight's table drew its speeds above)
        if a is not None and not (name == "rotor_speed" and att.get("rotors") is not None):
            f = _figure(f"{label} (the recording's) [{unit}]", xr, unit, name.replace("_", "-"))
            _lines(f, t, {f"rotor {i}": a[:, i] for i in range(a.shape[1])})
            parts.append(f)
    if att.get("diagnosis") is not None:
        parts += _diagnosis_section(att["diagnosis"], xr)
    parts.append(_spectrogram(rec, xr))
    return column(*parts, sizing_mode="stretch_width")


def _diagnosis_text(j: dict) -> str:
    """quadest diagnose's findings as the page's tables (docs/diagnose.md)."""
    head = (
        f"<h2>Motors and failures (quadest diagnose)</h2><p class='q'>{html.escape(j['autopilot'])}, "
        f"{html.escape(j['frame'])}; IMU {j['imu_rate_hz']:g} Hz, motor outputs {j['output_rate_hz']:g} Hz; "
        "times in the log's own time base, motors in the autopilot's numbering.</p>"
    )
    if j["failures"]:
        rows = [[f"{f['time_s']:.3f}", f["motor"], f"{f['effectiveness']:.2f}"] for f in j["failures"]]
        found = _table(["time [s]", "motor", "effectiveness left"], rows, "diagnose-failures")
    else:
        found = "<p class='q'>No rotor failure found.</p>"
    flagged = {d["motor"] for d in j["damaged"]}
    rows = [
        [m["motor"], f"{m['output']:.0f}", f"{m['output_excess']:+.1f}", f"{100 * m['excess']:+.1f} %",
         "works harder than intact vehicles spread" if m["motor"] in flagged else ""]
        for m in j["motors"]
        if m["output"] is not None  # None: the vehicle did not fly, no share to show
    ]  # fmt: skip
    shares = (
        _table(["motor", "median output", "above the others' mean", "thrust share above the others", ""], rows,
               "diagnose-motors")
        if rows else "<p class='q'>No motor shares (no flight, a flight with a failure, or one shorter than 10 s).</p>"
    )  # fmt: skip
    notes = "".join(f"<p class='q'>note: {html.escape(n)}</p>" for n in j["notes"])
    return STYLE + head + found + shares + notes


def _diagnosis_section(dg: dict, xr) -> list:
    """The diagnosis's tables, and each motor's output over time with the failures found marked."""
    f = _figure("motor outputs [fraction of full thrust]; dashed: a failure found", xr, "thrust", "diagnose-outputs")
    _lines(f, dg["t_out"], {f"motor {m}": dg["thrust"][:, i] for i, m in enumerate(dg["motors"])})
    for fail in dg["json"]["failures"]:
        f.add_layout(Span(location=fail["time_s"], dimension="height", line_color="red", line_dash="dashed"))
    return [Div(text=_diagnosis_text(dg["json"]), sizing_mode="stretch_width"), f]


def _failure_sections(rec, att, xr) -> list:
    """After a sustained spin, the spin rate and tilt; after a throw, what the recovery's bank
    believed: each hypothesis's probability, the spherical variance, the states and the gravity
    estimate's error."""
    t, out = rec.t, []
    if att.get("spin") is not None:
        w, tilt = att["spin"]
        out.append(
            Div(
                text=STYLE + "<h2>Sustained spin (a rotor loss?): spin and tilt</h2><p class='q'>With the "
                "attitude of "
                f"{html.escape(str(att['reference']))}: the body rate about the vertical and the tilt of "
                "the body's z axis (a relaxed hover settles both).</p>"
            )
        )
        for label, y, unit, nm in (
            ("spin rate about the vertical", w, "rad/s", "spin-rate"),
            ("tilt of body z from the vertical", tilt, "deg", "tilt"),
        ):
            f = _figure(f"{label} [{unit}]", xr, unit, nm, height=200)
            _lines(f, t, {label: y})
            out.append(f)
    res = att.get("recovery")
    if res is not None:
        s = res.summary
        ev = [[e["state"], f"{e['t_s']:.3f}"] for e in s["events"]]
        conv = (
            f"converged {1e3 * s['t_converge_from_detection_s']:.0f} ms after the detection"
            if s.get("converged")
            else "the bank did not converge"
        )
        model = att.get("recovery_model") or "a given aerodynamic model"
        out.append(
            Div(
                text=STYLE + "<h2>Throw: the recovery's bank of EKFs</h2>"
                f"<p class='q'>With {html.escape(model)}: {html.escape(conv)}"
                + (f"; gravity error there {s['gravity_err_deg']:.2f}°" if "gravity_err_deg" in s else "")
                + "</p>"
                + _table(["state", "from [s]"], ev, "recovery-states")
            )
        )
        if res.probabilities is not None and np.isfinite(res.probabilities).any():
            f = _figure("each hypothesis's probability", xr, "probability", "hypotheses", height=260)
            for j in range(res.probabilities.shape[1]):
                tt, yy = decimate(t, res.probabilities[:, j])
                f.line(tt, yy, color=Category10_10[j % 10], line_width=1.0, alpha=0.8)
            out.append(f)
        f = _figure("spherical variance S_g of the hypotheses' gravity directions", xr, "S_g", "s-g", height=200)
        _lines(f, t, {"S_g": res.s_g})
        out.append(f)
        if att.get("throw_error") is not None:
            f = _figure("gravity estimate's error against the truth [deg]", xr, "deg", "gravity-error", height=200)
            _lines(f, t, {"most likely hypothesis": att["throw_error"]})
            out.append(f)
    return out


SPECTROGRAM_COLUMNS = 800  # at most about this many columns drawn (chosen)


SPECTROGRAM_MIN = 16
"""Samples of the shortest segment a spectrogram is computed on."""


def _spectrogram(rec, xr):
    """The accelerometer norm's spectrogram (vibration, the spin's frequency), in dB; a note
    for a recording shorter than one segment."""
    t = rec.t
    if len(t) < SPECTROGRAM_MIN:
        return Div(text=STYLE + f"<p class='q'>No spectrogram: {len(t)} sample(s), fewer than {SPECTROGRAM_MIN}.</p>")
    fs = 1.0 / median_interval(t)
    S = 10 * np.log10(_spectrogram_columns(row_norms(rec.acc), fs) + 1e-12)
    f = _figure("accelerometer norm: spectrogram [dB]", xr, "frequency [Hz]", "spectrogram", height=260)
    f.image(
        image=[S],
        x=float(t[0]),
        y=0.0,
        dw=float(t[-1] - t[0]),
        dh=float(fs / 2),
        color_mapper=LinearColorMapper(
            palette=Viridis256, low=float(np.percentile(S, 5)), high=float(np.percentile(S, 99.5))
        ),
    )
    f.y_range = Range1d(0.0, fs / 2)
    return f


def _spectrogram_columns(x, fs: float) -> np.ndarray:
    """The power spectral density of the segments drawn (half-overlapping, of at most 256
    samples; every ``step``-th of them, at most about :data:`SPECTROGRAM_COLUMNS`), computed on
    those segments alone: ``(frequencies, columns)``. ``x`` is overwritten."""
    x -= np.nanmean(x)
    x = np.nan_to_num(x, copy=False)
    nper = int(min(256, max(SPECTROGRAM_MIN, len(x) // 8)))
    hop = nper - nper // 2
    segments = (len(x) - nper // 2) // hop
    step = max(1, segments // SPECTROGRAM_COLUMNS)
    drawn = np.stack([x[j * hop : j * hop + nper] for j in range(0, segments, step)])
    return spectrogram(drawn, fs=fs, nperseg=nper, noverlap=0, axis=-1)[2][:, :, 0].T


def write_report(rec, summ: dict, att: dict, path, title: str) -> Path:
    """Write the report to ``path`` atomically. A file name that is not UTF-8 (its bytes kept by
    Python as surrogates) is shown with U+FFFD for the bytes UTF-8 cannot say."""
    html = build_report(rec, summ, att, title).encode("utf-8", "surrogateescape")
    return write_bytes(path, html.decode("utf-8", "replace").encode())


def build_sweep_report(summ: dict, title: str) -> str:
    """A sweep's results page: per filter, its parameter sets (best first) with their mean
    metrics, and the metric against each swept parameter."""
    metrics = summ["metrics"]
    head = (
        f"{STYLE}<h1 style='font: bold 21px sans-serif'>{html.escape(title)}</h1>"
        f"<p class='q'>quadest {__version__}: {summ['runs']} runs ({summ['ok']} ok, {summ['failed']} failed) on "
        f"{summ['sources']} sources; each figure is the mean over the sources a parameter set ran on.</p>"
    )
    parts = [Div(text=head, sizing_mode="stretch_width")]
    for name, f in summ["filters"].items():
        rows = [
            [json.dumps(e["params"], sort_keys=True), e["runs"]]
            + [_f(e.get(m), "{:.3f}") for m in metrics]
            + ([e["survived"]] if "survived" in e else [])
            for e in f["sets"]
        ]
        header = ["parameters", "runs"] + metrics + (["survived"] if f["sets"] and "survived" in f["sets"][0] else [])
        parts.append(
            Div(
                text=f"{STYLE}<h2>{html.escape(name)}</h2>"
                + (f"<p class='q'>{f['failed']} runs failed</p>" if f["failed"] else "")
                + _table(header, rows[:50], f"sweep-{name}")
                + ("<p class='q'>(the 50 best of " + str(len(rows)) + ")</p>" if len(rows) > 50 else ""),
                sizing_mode="stretch_width",
            )
        )
        for key in f["params"]:
            pts = sorted(
                (e["params"][key], e.get("total_rmse_deg"))
                for e in f["sets"]
                if key in e["params"] and e.get("total_rmse_deg") is not None
            )
            if len(pts) < 2:
                continue
            x = np.array([p[0] for p in pts], float)
            y = np.array([p[1] for p in pts], float)
            log = x.min() > 0 and x.max() / x.min() > 20
            fig = figure(
                title=f"{name}: total RMS error against {key}",
                height=260,
                sizing_mode="stretch_width",
                x_axis_type="log" if log else "linear",
                x_axis_label=key,
                y_axis_label="total RMS [deg]",
                name=f"sweep-{name}-{key}",
                tools="pan,wheel_zoom,box_zoom,reset,save",
            )
            fig.toolbar.logo = None
            fig.scatter(x, y, size=6, color=Category10_10[0])
            parts.append(fig)
    return file_html(column(*parts, sizing_mode="stretch_width"), INLINE, title)


def write_sweep_report(summ: dict, path, title: str) -> Path:
    return write_bytes(path, build_sweep_report(summ, title).encode())


__all__ = ["build_report", "build_sweep_report", "decimate", "write_report", "write_sweep_report"]
