"""The survival campaign's page (``quadest campaign --report``, ``quadest report RESULTS``): its
table per estimator, detection mode, gyroscope range and magnetometer latency, survival by
scenario, and survival of the complete losses against the spin, the clipping share, the
detection delay and the magnetometer's latency. One self-contained HTML file (bokeh, inlined)."""

from __future__ import annotations

import html
import math
from pathlib import Path

from bokeh.embed import file_html
from bokeh.layouts import column
from bokeh.models import ColumnDataSource, Div, HoverTool
from bokeh.palettes import Category10_10
from bokeh.plotting import figure
from bokeh.resources import INLINE

from quadest import __version__
from quadest.data.files import write_bytes
from quadest.plot.report import STYLE, _f, _table

HEADER = ["estimator", "detection", "gyro range (°/s)", "mag latency (s)", "height (m)", "losses", "survived",
          "found", "named", "median (ms)", "p90", "p99", "max", "partial named", "partial effectiveness error",
          "nominal hours", "false alarms", "nominal crashed"]  # fmt: skip


def _group_row(g: dict) -> list:
    f, n, d, p = g["failures"], g["nominal"], g["failures"]["delay_ms"], g["failures"]["partial"]
    oracle = g["detection"] == "oracle"
    return [
        g["filter"],
        g.get("detection_label", g["detection"]) + (" (told)" if oracle else ""),
        "none" if math.isinf(g["gyro_range_dps"]) else f"±{g['gyro_range_dps']:.0f}",
        f"{g['mag_latency_s']:g}",
        f"{g['height_m']:g}",
        f["complete"],
        f"{f['survived']} ({100.0 * f['survived'] / f['complete']:.1f} %)" if f["complete"] else "-",
        f["found"],
        f["isolated"],
        _f(d["median"], "{:.0f}"),
        _f(d["p90"], "{:.0f}"),
        _f(d["p99"], "{:.0f}"),
        _f(d["max"], "{:.0f}"),
        f"{p['isolated']}/{p['flights']}" if p["flights"] else "-",
        _f(p["effectiveness_error_median"], "{:.3f}"),
        f"{n['hours']:.2f}",
        "-" if oracle else n["lost_alarms"],
        n["crashed"] if n["flights"] else "-",
    ]


def _scenario_rows(summary: dict) -> tuple[list, list]:
    scenarios = sorted({s for g in summary["groups"] for s in g["survival_by_scenario"]})
    rows = []
    for g in summary["groups"]:
        cells = [
            f"{a}/{b}" if (a, b) != (None, None) else "-"
            for a, b in (g["survival_by_scenario"].get(s, (None, None)) for s in scenarios)
        ]
        gyro = "none" if math.isinf(g["gyro_range_dps"]) else f"±{g['gyro_range_dps']:.0f}"
        rows.append(
            [
                g["filter"],
                g.get("detection_label", g["detection"]),
                gyro,
                f"{g['mag_latency_s']:g}",
                f"{g['height_m']:g}",
                *cells,
            ]
        )
    return ["estimator", "detection", "gyro range (°/s)", "mag latency (s)", "height (m)", *scenarios], rows


def _curve(var: str, curve: dict):
    fig = figure(
        title=f"complete losses that stayed up, against the {curve['label']}",
        height=280,
        sizing_mode="stretch_width",
        x_axis_label=curve["label"],
        y_axis_label="survived [%]",
        y_range=(-5, 105),
        name=f"campaign-{var}",
        tools="pan,wheel_zoom,box_zoom,reset,save",
    )
    fig.toolbar.logo = None
    for i, (name, line) in enumerate(curve["lines"].items()):
        share = [100.0 * s / n for s, n in zip(line["survived"], line["flights"])]
        src = ColumnDataSource({"x": line["x"], "y": share, "n": line["flights"], "s": line["survived"]})
        colour = Category10_10[i % 10]
        fig.line("x", "y", source=src, color=colour, legend_label=name, line_width=1.5)
        fig.scatter("x", "y", source=src, color=colour, legend_label=name, size=6)
    fig.add_tools(HoverTool(tooltips=[("x", "@x{0.000}"), ("survived", "@s of @n (@y{0.0} %)")]))
    fig.legend.click_policy = "hide"
    fig.add_layout(fig.legend[0], "right")
    return fig


def _varies(curve: dict) -> bool:
    """Whether a curve has a line with more than one point (a single value says nothing against it)."""
    return any(len(line["x"]) > 1 for line in curve["lines"].values())


def build_campaign_report(summary: dict, title: str) -> str:
    head = (
        f"{STYLE}<h1 style='font: bold 21px sans-serif'>{html.escape(title)}</h1>"
        f"<p class='q'>quadest {__version__}: {summary['runs']} flights ({summary['ok']} flown, "
        f"{summary['failed']} could not be flown). The oracle is told of a loss 50 ms after it happens "
        "(not what a vehicle knows); the detector finds it from the vehicle's sensors with a model off by "
        "the flight's drawn errors. A false alarm in nominal flight counts as a failed flight. "
        "docs/campaign.md</p>"
    )
    parts = [Div(text=head, sizing_mode="stretch_width")]
    parts.append(Div(text="<h2>Losses, detection and false alarms</h2>"
                     + _table(HEADER, [_group_row(g) for g in summary["groups"]], "campaign-table"),
                     sizing_mode="stretch_width"))  # fmt: skip
    header, rows = _scenario_rows(summary)
    parts.append(Div(text="<h2>Complete losses that stayed up, by scenario</h2>"
                     + _table(header, rows, "campaign-scenarios"), sizing_mode="stretch_width"))  # fmt: skip
    parts += [_curve(var, c) for var, c in summary["curves"].items() if _varies(c)]
    return file_html(column(*parts, sizing_mode="stretch_width"), INLINE, title)


def write_campaign_report(summary: dict, path, title: str) -> Path:
    return write_bytes(path, build_campaign_report(summary, title).encode())
