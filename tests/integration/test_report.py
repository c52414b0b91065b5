"""`quadest report`, checked as a person would: the page opened in headless Chromium
(Debian's, driven by Playwright) shows no console error, every plot draws, the RMS table shows
the figures computed here independently, zooming one plot zooms the others, and a recording
without truth says so instead of showing errors. The browser tests skip, saying why, only where
Chromium or Playwright is absent (.ci/run installs Chromium)."""

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from quadest.cli.main import main
from quadest.data import Recording, save_recording
from quadest.evaluation.runner import estimate, score
from quadest.plot.report import decimate
from quadest.readers import read_recording
from quadest.sim import simulate

DATA = Path(os.environ.get("QUADEST_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
SITL_LOSS = DATA / "ardupilot" / "sitl_quadx_motor1_loss.bin"

CHROMIUM = os.environ.get("QUADEST_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")


def test_decimation_keeps_the_extremes():
    t = np.arange(100_000) / 1000.0
    y = np.sin(t)
    y[54_321] = 50.0  # one spike
    td, yd = decimate(t, y, 4000)
    assert len(td) <= 4200 and np.all(np.diff(td) > 0)
    assert yd.max() == 50.0 and yd.min() == pytest.approx(y.min())


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    rec = simulate("damaged-rotor", "bebop2", seed=3, duration=12.0)
    save_recording(rec, d / "flight.csv")
    bare = rec.__class__(t=rec.t, gyr=rec.gyr, acc=rec.acc, mag=rec.mag, meta={"source": "no truth"})
    save_recording(bare, d / "bare.csv")
    for name in ("flight", "bare"):
        assert (
            main(
                [
                    "report",
                    str(d / f"{name}.csv"),
                    "--filters",
                    "madgwick,afckf",
                    "-o",
                    str(d / f"{name}.html"),
                    "--json",
                    str(d / f"{name}.json"),
                ]
            )
            == 0
        )
    throw = simulate("throw", "fma", seed=5)
    save_recording(throw, d / "throw.csv")
    assert main(["report", str(d / "throw.csv"), "--filters", "madgwick", "-o", str(d / "throw.html")]) == 0
    assert main(["recover", str(d / "throw.csv"), "--report", str(d / "recover.html")]) == 0
    # the same page from compare and estimate
    assert (
        main(
            [
                "compare",
                "--recording",
                str(d / "flight.csv"),
                "--filters",
                "madgwick",
                "--no-timing",
                "--report",
                str(d / "compare.html"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "estimate",
                str(d / "flight.csv"),
                "--filter",
                "afckf",
                "-o",
                str(d / "q.csv"),
                "--report",
                str(d / "estimate.html"),
            ]
        )
        == 0
    )
    return d


def test_compare_and_estimate_write_the_report(reports):
    for name in ("compare", "estimate"):
        page = (reports / f"{name}.html").read_text()
        assert page.startswith("<!DOCTYPE html>") and "roll RMS [deg]" in page and f"<title>quadest {name}" in page


def test_the_report_is_made_from_the_data(reports):
    """The tables' numbers are the recording's: the RMS errors equal score() over the same
    estimates (computed here), the events find the rotor loss's spin, no truth means no errors."""
    rep = json.loads((reports / "flight.json").read_text())
    rec = read_recording(reports / "flight.csv")
    for name in ("madgwick", "afckf"):
        s = score(rec, estimate(rec, name).q)
        for a in ("roll", "pitch", "yaw"):
            assert rep["rms_deg"][name][a] == pytest.approx(s["rms_deg"][a], rel=1e-9)
    spins = [e for e in rep["summary"]["events"] if "spin" in e["kind"]]
    assert spins and 4.5 < spins[0]["start_s"] < 6.0  # the loss at 5 s, the spin up in about a second
    # the spin passes ±1000°/s on this seed: the flat tops found in the readings are the samples the
    # simulator clipped (its own count, from the true rates)
    assert rep["summary"]["gyro_clipped_share"] == pytest.approx(rec.meta["gyro_saturated_share"], abs=0.002)
    assert rep["summary"]["gyro_clipped_share"] > 0.1
    bare = json.loads((reports / "bare.json").read_text())
    assert bare["truth"] is None and bare["rms_deg"] == {}
    html = (reports / "bare.html").read_text()
    assert "no attitude truth" in html and "Errors against" not in html
    assert (reports / "flight.html").stat().st_size < 20e6


@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None:
        pytest.skip("no Chromium found (Debian's chromium package; .ci/run installs it): browser tests skipped")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright is not installed (pip install 'quadest[test]'): browser tests skipped")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=["--no-sandbox"])
        yield b
        b.close()


def _open(browser, path):
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(path.as_uri())
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length > 0")
    page.wait_for_timeout(1500)  # the plots draw after the document loads
    return page, errors


FIGURES = [
    "attitude-roll",
    "attitude-pitch",
    "attitude-yaw",
    "error-roll",
    "error-pitch",
    "error-yaw",
    "sensor-gyroscope",
    "sensor-accelerometer",
    "mag-norm",
    "mag-dip",
    "spectrogram",
]


def test_the_report_in_a_browser(browser, reports):
    page, errors = _open(browser, reports / "flight.html")
    assert errors == []
    # every plot is in the document and draws: its canvases hold more than one colour
    names = page.evaluate("() => Array.from(Bokeh.documents[0].all_models).filter(m => m.name).map(m => m.name)")
    assert set(FIGURES) <= set(names), names
    drawn = page.evaluate("""() => {
        const out = [];
        const walk = (root) => {
            for (const el of root.querySelectorAll('*')) {
                if (el.tagName === 'CANVAS' && el.width > 0 && el.height > 0) {
                    const d = el.getContext('2d').getImageData(0, 0, el.width, el.height).data;
                    const seen = new Set();
                    for (let i = 0; i < d.length && seen.size < 3; i += 4 * 97)
                        seen.add(d[i] + ',' + d[i+1] + ',' + d[i+2]);
                    out.push(seen.size);
                }
                if (el.shadowRoot) walk(el.shadowRoot);
            }
        };
        walk(document);
        return out;
    }""")
    assert sum(n > 1 for n in drawn) >= len(FIGURES), drawn
    # the RMS table shows the JSON's figures
    rep = json.loads((reports / "flight.json").read_text())
    rows = page.locator("#rms tr").all_inner_texts()
    cells = {r.split("\t")[0]: r.split("\t")[1:] for r in rows[1:]}
    for name, rms in rep["rms_deg"].items():
        assert [float(c) for c in cells[name][:3]] == pytest.approx(
            [rms[a] for a in ("roll", "pitch", "yaw")], abs=1e-3
        )
    # zooming one plot zooms the others: they share one time range
    before = page.evaluate("() => Bokeh.documents[0].get_model_by_name('sensor-gyroscope').x_range.end")
    box = page.locator(".bk-Figure").nth(0).bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.wheel(0, -400)
    page.wait_for_timeout(500)
    after = page.evaluate(
        "() => [Bokeh.documents[0].get_model_by_name('attitude-roll').x_range.end, "
        "Bokeh.documents[0].get_model_by_name('sensor-gyroscope').x_range.end]"
    )
    assert after[0] == after[1] and after[1] < before
    page.close()


def test_a_report_without_truth_in_a_browser(browser, reports):
    page, errors = _open(browser, reports / "bare.html")
    assert errors == []
    names = page.evaluate("() => Array.from(Bokeh.documents[0].all_models).filter(m => m.name).map(m => m.name)")
    assert "attitude-roll" in names and "error-roll" not in names
    assert page.locator("text=no attitude truth").count() >= 1
    page.close()


def test_a_throw_report_shows_what_the_bank_believed(browser, reports):
    """A simulated throw (no magnetometer): the recovery's hypotheses, their spherical variance,
    the states and the gravity estimate's error are drawn; the heading offset is removed."""
    for name in ("throw.html", "recover.html"):
        page, errors = _open(browser, reports / name)
        assert errors == []
        names = page.evaluate("() => Array.from(Bokeh.documents[0].all_models).filter(m => m.name).map(m => m.name)")
        assert {"hypotheses", "s-g", "gravity-error"} <= set(names), names
        assert page.locator("#recovery-states tr").count() >= 4  # waiting, thrown, converging, nominal
        page.close()
    assert "constant heading offset removed" in (reports / "throw.html").read_text()


def test_a_sweeps_results_as_a_page(browser, tmp_path):
    """`quadest report RESULTS.parquet`: per filter its parameter sets with the mean of each
    metric over the sources (computed here from the Parquet file), and the metric against the
    swept parameter, in a page that draws without errors."""
    import pyarrow.parquet as pq

    res = tmp_path / "sweep.parquet"
    assert (
        main(
            [
                "sweep",
                "--filters",
                "madgwick",
                "--grid",
                "madgwick.beta_marg=0.02,0.2",
                "--seeds",
                "1-2",
                "--duration",
                "4",
                "--workers",
                "0",
                "-o",
                str(res),
            ]
        )
        == 0
    )
    assert main(["report", str(res), "-o", str(tmp_path / "sweep.html"), "--json", str(tmp_path / "sweep.json")]) == 0
    summ = json.loads((tmp_path / "sweep.json").read_text())
    rows = [r for r in pq.read_table(res).to_pylist() if r["status"] == "ok"]
    for e in summ["filters"]["madgwick"]["sets"]:
        mine = [r["total_rmse_deg"] for r in rows if json.loads(r["params"]) == e["params"]]
        assert e["runs"] == len(mine) == 2 and e["total_rmse_deg"] == pytest.approx(np.mean(mine), rel=1e-12)
    page, errors = _open(browser, tmp_path / "sweep.html")
    assert errors == []
    names = page.evaluate("() => Array.from(Bokeh.documents[0].all_models).filter(m => m.name).map(m => m.name)")
    assert "sweep-madgwick-beta_marg" in names
    assert page.locator("#sweep-madgwick tr").count() == 3  # header and two parameter sets
    page.close()


def test_a_flown_recording_shows_its_rotor_speeds(browser, tmp_path, capsys):
    """quadest fly writes NAME-flight.parquet beside NAME.csv; the report of NAME.csv draws the
    rotor speeds from it; a named --rotors file that is absent is refused in one line."""
    assert (
        main(
            [
                "fly",
                "--scenario",
                "hover",
                "--estimator",
                "truth",
                "--duration",
                "2",
                "--no-plot",
                "-o",
                str(tmp_path / "f"),
            ]
        )
        == 0
    )
    csv = next((tmp_path / "f").glob("*.csv"))
    assert main(["report", str(csv), "--filters", "madgwick", "-o", str(tmp_path / "r.html")]) == 0
    page, errors = _open(browser, tmp_path / "r.html")
    assert errors == []
    names = page.evaluate("() => Array.from(Bokeh.documents[0].all_models).filter(m => m.name).map(m => m.name)")
    assert "rotor-speeds" in names
    page.close()
    capsys.readouterr()
    assert main(["report", str(csv), "--rotors", str(tmp_path / "nope.parquet"), "-o", str(tmp_path / "x.html")]) == 2
    err = capsys.readouterr().err
    assert "--rotors" in err and len(err.strip().splitlines()) == 1


def test_a_report_never_overwrites_an_input(reports, capsys):
    """--report and -o naming the recording are refused in one line, the recording untouched."""
    before = (reports / "flight.csv").read_bytes()
    for argv in (
        [
            "compare",
            "--recording",
            str(reports / "flight.csv"),
            "--filters",
            "madgwick",
            "--no-timing",
            "--report",
            str(reports / "flight.csv"),
        ],
        ["report", str(reports / "flight.csv"), "-o", str(reports / "flight.csv")],
    ):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1, err
    assert (reports / "flight.csv").read_bytes() == before


def test_one_colour_per_estimator_and_legends_beside_the_data(reports):
    """An estimator has one colour in every plot of a page (attitude and errors alike), and each
    legend stands beside its plot, not over the data."""
    from bokeh.models import Legend, Plot

    from quadest.evaluation.inspect import report_data
    from quadest.plot.report import report_layout

    rec = read_recording(reports / "flight.csv")
    summ, att = report_data(rec, ["robust", "madgwick", "afckf"])
    colour_of, seen = {}, 0
    for plot in report_layout(rec, summ, att, "t").select({"type": Plot}):
        if not (plot.name or "").startswith(("attitude-", "error-")):
            continue
        (legend,) = [r for r in plot.right if isinstance(r, Legend)]
        assert not [r for r in plot.center if isinstance(r, Legend)]
        for item in legend.items:
            colour = item.renderers[0].glyph.line_color
            assert colour_of.setdefault(item.label.value, colour) == colour, item.label.value
            seen += 1
    assert seen == 3 * 4 + 3 * 3 and len(set(colour_of.values())) == 4  # truth and three estimators


def test_report_defaults_span_and_vibration(reports, tmp_path):
    """robust is among the default estimators; --from / --to cut the span shown and scored (seconds
    after the first sample); vibration says n/a where the IMU is too slow to tell it."""
    from quadest.cli.main import build_parser
    from quadest.evaluation.inspect import summary

    assert "robust" in build_parser().parse_args(["report", "x.csv", "-o", "y.html"]).filters.split(",")
    out = tmp_path / "span.json"
    argv = ["report", str(reports / "flight.csv"), "--filters", "madgwick", "--from", "2", "--to", "4.5"]
    assert main([*argv, "-o", str(tmp_path / "span.html"), "--json", str(out)]) == 0
    assert json.loads(out.read_text())["summary"]["duration_s"] == pytest.approx(2.5, abs=0.01)
    assert main([*argv[:-4], "--from", "9", "--to", "3", "-o", str(tmp_path / "x.html")]) == 2
    slow = simulate("nominal", "lowcost-20hz", seed=1, duration=20.0)
    s = summary(slow)
    assert s["vibration_rms_m_s2"] is None and s["vibration_source"].startswith("n/a: the IMU at 20 Hz")
    fast = read_recording(reports / "flight.csv")
    assert summary(fast)["vibration_source"] == "the accelerometer"
    own = {"source": "the log's VIBE messages", "rms_m_s2": [0.1, 0.2, 0.3], "max_m_s2": [1, 1, 1], "clips": 0}
    fast.meta["vibration"] = own
    assert summary(fast)["vibration_rms_m_s2"] == [0.1, 0.2, 0.3]


@pytest.fixture(scope="module")
def log_report(tmp_path_factory):
    """quadest report of the ArduPilot SITL log of a loss of motor 1 (HTML and JSON)."""
    if not SITL_LOSS.is_file():
        pytest.skip(f"the ArduPilot SITL log is not at {SITL_LOSS} (set QUADEST_DATA)")
    d = tmp_path_factory.mktemp("log")
    argv = ["report", str(SITL_LOSS), "--filters", "madgwick", "-o", str(d / "log.html"), "--json", str(d / "l.json")]
    assert main(argv) == 0
    return d


def test_a_logs_report_has_its_diagnosis(log_report, tmp_path, capsys):
    """The page's JSON holds what quadest diagnose finds: the loss of motor 1 within 150 ms of its
    logged SERVO1_FUNCTION change, in the log's own time and the autopilot's numbering; diagnose
    --report writes the same section."""
    diag = json.loads((log_report / "l.json").read_text())["diagnosis"]
    cut = [c["time_s"] for c in diag["parameter_changes"] if c["name"] == "SERVO1_FUNCTION" and c["value"] == 1]
    found = diag["failures"]
    assert len(found) == 1 and found[0]["motor"] == 1 and 0 <= found[0]["time_s"] - cut[0] <= 0.15
    assert main(["diagnose", str(SITL_LOSS), "--report", str(tmp_path / "d.html")]) == 0
    text = (tmp_path / "d.html").read_text()
    assert "Motors and failures" in text and "diagnose-failures" in text and f"{found[0]['time_s']:.3f}" in text
    capsys.readouterr()


def test_a_logs_report_in_a_browser(browser, log_report):
    """The log's page draws without a console error, with the motors' outputs and the failure."""
    page, errors = _open(browser, log_report / "log.html")
    assert errors == []
    names = page.evaluate("() => Array.from(Bokeh.documents[0].all_models).filter(m => m.name).map(m => m.name)")
    assert "diagnose-outputs" in names and "Motors and failures" in page.content()
    page.close()


def test_report_summary_names_timestamps_that_jitter():
    """The report's first table gives the timestamps' spread and, where it is large (stamps a
    host gave on arrival), what a low-pass that followed it would do (docs/report.md)."""
    from quadest.evaluation.inspect import summary
    from quadest.plot.report import summary_html

    rec = simulate("nominal", "bebop2", seed=1, duration=5.0)
    k = np.arange(len(rec.t))
    late = Recording(t=rec.t + 0.5 * (rec.t[1] - rec.t[0]) * (k % 2), gyr=rec.gyr, acc=rec.acc, mag=rec.mag)
    regular, jittered = summary_html("x", summary(rec)), summary_html("x", summary(late))
    assert "timestamps&#x27; jitter" in regular and "mean(dt²)/mean(dt)²" not in regular
    assert "mean(dt²)/mean(dt)² 1.250" in jittered
