"""The Recording type: validation, files (CSV, Parquet) and summaries."""

import json

import numpy as np
import pytest

from quadest import Recording, save_recording
from quadest.data import format_summary, summarize
from quadest.data.recording import columns_of
from quadest.data.recording_files import load_recording


def make(n=200, rate=100.0, truth=True, rng=None):
    rng = rng or np.random.default_rng(0)
    t = np.arange(n) / rate
    gyr = rng.normal(0, 0.1, (n, 3))
    acc = rng.normal(0, 0.1, (n, 3)) + [0, 0, -9.81]
    mag = np.full((n, 3), np.nan)
    mag[::4] = rng.normal(0, 20, (len(mag[::4]), 3))
    kw = {}
    if truth:
        q = rng.normal(size=(n, 4))
        kw["true_q"] = q / np.linalg.norm(q, axis=1, keepdims=True)
        for k in ("true_gyr", "true_pos", "true_vel", "true_acc"):
            kw[k] = rng.normal(size=(n, 3))
        kw["true_q"][5] = np.nan  # a row without truth
    return Recording(
        t=t, gyr=gyr, acc=acc, mag=mag, meta={"source": "test", "units": {"mag": "uT"}, "nested": {"a": [1, 2.5]}}, **kw
    )


def raises(match, **kw):
    base = dict(t=np.arange(20) * 0.01, gyr=np.zeros((20, 3)), acc=np.tile([0, 0, -9.81], (20, 1)))
    base.update(kw)
    with pytest.raises(ValueError, match=match):
        Recording(**base)


def test_validation_names_field_and_row():
    raises(r"gyr: expected shape \(N, 3\), got \(20, 2\)", gyr=np.zeros((20, 2)))
    raises("acc: has 19 rows but t has 20", acc=np.zeros((19, 3)))
    t = np.arange(20) * 0.01
    t[7] = np.nan
    raises("t: non-finite value at row 7", t=t)
    t = np.arange(20) * 0.01
    t[9] = t[8]
    raises("t: not strictly increasing at row 9", t=t)
    g = np.zeros((20, 3))
    g[4, 1] = np.inf
    raises("gyr: non-finite value at row 4", gyr=g)
    m = np.zeros((20, 3))
    m[3, 0] = np.nan
    raises("mag: row 3 is partly NaN", mag=m)
    q = np.tile([1.0, 0, 0, 0], (20, 1))
    q[6] = [0.5, 0, 0, 0]
    raises("true_q: row 6 is not a unit quaternion", true_q=q)
    raises("meta: must be JSON", meta={"x": object()})


def test_unit_mistakes_are_refused():
    g = np.zeros((20, 3))
    g[11, 2] = 200.0  # deg/s
    raises(r"gyr: 200.0 at row 11 .* deg/s", gyr=g)
    raises("acc: norms look like g", acc=np.tile([0, 0, -1.0], (20, 1)))
    a = np.tile([0, 0, -9.81], (20, 1))
    a[2] = [0, 0, -9810.0]  # mm/s² or mg
    raises("acc: norm 9810.0 at row 2", acc=a)
    # free fall is not a unit mistake, and the check can be switched off
    Recording(t=np.arange(20) * 0.01, gyr=np.zeros((20, 3)), acc=np.zeros((20, 3)))
    Recording(t=np.arange(20) * 0.01, gyr=np.zeros((20, 3)), acc=np.tile([0, 0, -1.0], (20, 1)), check_units=False)


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_lossless_round_trip(tmp_path, ext):
    rec = make()
    back = load_recording(save_recording(rec, tmp_path / f"r{ext}"))
    for name in ("t", "gyr", "acc", "mag", *rec.truth):
        np.testing.assert_array_equal(getattr(back, name), getattr(rec, name), err_msg=name)
    assert back.truth == rec.truth
    assert back.meta == rec.meta


def test_round_trip_without_truth_or_mag(tmp_path):
    rec = Recording(t=np.arange(30) * 0.01, gyr=np.zeros((30, 3)), acc=np.tile([0, 0, -9.81], (30, 1)))
    back = load_recording(save_recording(rec, tmp_path / "r.csv"))
    assert back.truth == [] and not back.has_mag
    assert np.isnan(back.mag).all()


def test_csv_header_is_fixed_and_its_metadata_stands_beside_it(tmp_path):
    path = save_recording(make(), tmp_path / "r.csv")
    lines = path.read_text().splitlines()
    want = ["t"] + [
        c
        for f in ("gyr", "acc", "mag", "true_q", "true_gyr", "true_pos", "true_vel", "true_acc")
        for c in columns_of(f)
    ]
    assert lines[0].split(",") == want and len(lines) == 201  # the header, then the rows: nothing else
    assert want[10:14] == ["true_q_w", "true_q_x", "true_q_y", "true_q_z"]
    assert want[17:20] == ["true_pos_n", "true_pos_e", "true_pos_d"]
    side = json.loads((tmp_path / "r.csv-metadata.json").read_text())
    assert side["url"] == "r.csv" and side["quadest"]["rows"] == 200
    assert side["quadest"]["format"] == "quadest recording v3" and side["quadest"]["meta"]["source"] == "test"
    units = {c["name"]: c["dc:description"] for c in side["tableSchema"]["columns"]}
    assert list(units) == want and units["gyr_x"].startswith("rad/s") and units["mag_x"] == "uT, body FRD"


def test_a_recording_csv_is_read_by_standard_readers_as_it_is(tmp_path):
    """pandas and Python's csv module read the file with their defaults (no comment option):
    the same columns and the same numbers."""
    import csv

    import pandas as pd

    rec = make()
    path = save_recording(rec, tmp_path / "r.csv")
    frame = pd.read_csv(path)
    assert len(frame) == len(rec) and list(frame.columns) == list(rec.columns())
    np.testing.assert_array_equal(frame[["gyr_x", "gyr_y", "gyr_z"]].to_numpy(), rec.gyr)
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(rec) and float(rows[-1]["t"]) == rec.t[-1]


def test_a_parquet_recording_states_its_units(tmp_path):
    import pyarrow.parquet as pq

    schema = pq.read_schema(save_recording(make(), tmp_path / "r.parquet"))
    assert schema.field("acc_z").metadata[b"unit"].decode().startswith("m/s²")
    assert json.loads(schema.metadata[b"quadest"])["rows"] == 200


def test_bad_files_give_one_clear_error(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("t,gyr_x\n0,1\n")
    with pytest.raises(ValueError, match="missing column"):
        load_recording(p)
    good = save_recording(make(), tmp_path / "good.csv").read_text()
    p.write_text(good[: len(good) // 2] + "\n1,2\n")  # truncated mid-row
    with pytest.raises(ValueError, match="bad.csv"):
        load_recording(p)
    with pytest.raises(ValueError, match="unknown recording extension"):
        load_recording(tmp_path / "x.txt")
    with pytest.raises(ValueError, match="no such file"):
        load_recording(tmp_path / "missing.csv")
    (tmp_path / "bad.parquet").write_bytes(b"not parquet")
    with pytest.raises(ValueError, match="not a readable Parquet"):
        load_recording(tmp_path / "bad.parquet")
    p.write_text(good.replace("true_acc_z", "true_acc_q"))
    with pytest.raises(ValueError, match="true_acc needs all"):
        load_recording(p)


def test_summary_rates_gaps_and_truth():
    t = np.concatenate([np.arange(100) * 0.01, 1.5 + np.arange(100) * 0.01])  # one 0.51 s gap
    n = len(t)
    mag = np.full((n, 3), np.nan)
    mag[::5] = 1.0
    rec = Recording(
        t=t, gyr=np.zeros((n, 3)), acc=np.tile([0, 0, -9.81], (n, 1)), mag=mag, true_q=np.tile([1.0, 0, 0, 0], (n, 1))
    )
    s = summarize(rec)
    assert s["imu_rate_hz"] == pytest.approx(100.0)
    assert s["gaps"]["count"] == 1 and s["gaps"]["longest_s"] == pytest.approx(0.51)
    assert s["gaps"]["first_at_s"] == pytest.approx(0.99)
    assert s["mag_samples"] == 40
    assert list(s["truth"]) == ["true_q"]
    text = format_summary(s, "x.csv")
    assert "gaps        1" in text and "true_q" in text


def test_summary_names_timestamps_that_jitter():
    """Stamps alternately 0 and 0.5 periods late: their intervals spread 0.5 periods about the
    period and ``mean(Δt²) / mean(Δt)²`` is 1 + 0.5² (docs/estimators.md, robust, item 12);
    ``quadest info`` says so. Regular stamps are not called jittered."""
    n = 1000
    k = np.arange(n)
    for t, gain in ((k * 0.01 + 0.005 * (k % 2), 1.25), (k * 0.01, 1.0)):
        rec = Recording(t=t, gyr=np.zeros((n, 3)), acc=np.tile([0, 0, -9.81], (n, 1)), mag=np.full((n, 3), np.nan))
        s = summarize(rec)
        assert s["jitter_gain"] == pytest.approx(gain, rel=1e-3)
        assert s["interval_mean_s"] == pytest.approx(0.01, rel=1e-3)
        assert ("jitter      " in format_summary(s)) == (gain > 1.0)
    assert s["jitter_s"] < 1e-12


def test_select_and_between():
    rec = make()
    part = rec.between(0.5, 1.0)
    assert part.t[0] >= 0.5 and part.t[-1] <= 1.0 and len(part) == 51
    assert part.meta == rec.meta


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(*[finite] * 9), min_size=1, max_size=20), st.booleans())
def test_csv_round_trip_property(rows, with_mag):
    import tempfile
    from pathlib import Path

    a = np.array(rows, float)
    n = len(a)
    mag = a[:, 6:9] if with_mag else None
    rec = Recording(t=np.arange(n) * 0.01 + 0.1, gyr=a[:, :3], acc=a[:, 3:6], mag=mag, check_units=False)
    with tempfile.TemporaryDirectory() as d:
        back = load_recording(save_recording(rec, Path(d) / "r.csv"), check_units=False)
    for name in ("t", "gyr", "acc", "mag"):
        np.testing.assert_array_equal(getattr(back, name), getattr(rec, name))


def test_a_recording_cut_short_or_changed_is_refused(tmp_path):
    """The CSV's metadata file states its rows and checksum: a file cut at a row boundary or
    inside its last number, or a row removed, is refused, never read as a shorter recording;
    without the metadata file the rows are read as they are (the user's choice, said in the
    error)."""
    rec = make()
    data = save_recording(rec, tmp_path / "r.csv").read_bytes()
    side = (tmp_path / "r.csv-metadata.json").read_bytes()
    last_row = data.rfind(b"\n", 0, len(data) - 1) + 1
    lines = data.split(b"\n")
    for name, cut in [("cut1", data[:-2]), ("cut2", data[: last_row + 3]), ("cut3", data[:last_row]),
                      ("half", data[: len(data) // 2]), ("row", b"\n".join(lines[:-6] + lines[-5:]))]:  # fmt: skip
        p = tmp_path / f"{name}.csv"
        p.write_bytes(cut)
        (tmp_path / f"{name}.csv-metadata.json").write_bytes(side)
        with pytest.raises(
            ValueError, match="it states 200 rows: cut short or changed since.*delete the metadata file"
        ):
            load_recording(p)
    (tmp_path / "row.csv-metadata.json").unlink()
    assert len(load_recording(tmp_path / "row.csv")) == 199


def _legacy(rec, version: int) -> bytes:
    """``rec`` as the CSV of an earlier version: metadata in ``#`` lines above the header, v2
    with its row count and end line."""
    body = ",".join(rec.columns()) + "\n" + "\n".join(",".join(repr(float(v)) for v in row)
                                                      for row in zip(*rec.columns().values())) + "\n"  # fmt: skip
    head = f"# quadest recording v{version}\n" + (f"# rows: {len(rec)}\n" if version == 2 else "")
    head += "".join(f"# {k}: {json.dumps(v)}\n" for k, v in rec.meta.items())
    return (head + body + (f"# end: {len(rec)} rows\n" if version == 2 else "")).encode()


def test_earlier_versions_still_read_and_a_v2_cut_short_is_refused(tmp_path):
    rec = make()
    for version in (1, 2):
        p = tmp_path / f"v{version}.csv"
        p.write_bytes(_legacy(rec, version))
        back = load_recording(p)
        assert np.array_equal(back.t, rec.t) and back.meta["source"] == "test"
    data = _legacy(rec, 2)
    body_end = data.rfind(b"# end:")
    for cut in (len(data) - 1, body_end, body_end - 3, len(data) // 2):
        p = tmp_path / f"cut{cut}.csv"
        p.write_bytes(data[:cut])
        with pytest.raises(ValueError, match="cut short"):
            load_recording(p)


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (lambda d: d["quadest"].update(rows="200"), "damaged metadata of r.csv"),
        (lambda d: d["quadest"].update(format="quadest recording v9"), "damaged metadata"),
        (lambda d: d["quadest"].pop("values_sha256"), "damaged metadata"),
        (lambda d: d["quadest"]["meta"].update(earth_field_ned_ut="abc"), "earth_field_ned_ut must be 3 finite"),
        (lambda d: d["quadest"]["meta"].update(declination_rad=[1]), "declination_rad must be a finite number"),
    ],
)
def test_a_damaged_metadata_file_is_one_line_naming_it(tmp_path, edit, said):
    """Found by a hostile read: a row count as a string blamed the intact CSV, an unknown format
    was read as v3, a field of the wrong kind ended in an internal error."""
    path = save_recording(make(), tmp_path / "r.csv")
    side = tmp_path / "r.csv-metadata.json"
    doc = json.loads(side.read_text())
    edit(doc)
    side.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=said) as exc:
        load_recording(path)
    assert "\n" not in str(exc.value)
    side.write_text("[" * 100_000 + "]" * 100_000)  # nested beyond Python's recursion
    with pytest.raises(ValueError, match="damaged metadata"):
        load_recording(path)


def test_through_a_link_the_metadata_stands_beside_the_file(tmp_path):
    """Written and read through a link, the metadata is the linked file's (before: written beside
    the link, the file's own left stale)."""
    real = save_recording(make(), tmp_path / "real.csv")
    (tmp_path / "link.csv").symlink_to(real)
    rec = make(rng=np.random.default_rng(5))
    save_recording(rec, tmp_path / "link.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.csv", "real.csv", "real.csv-metadata.json"]
    for name in ("real.csv", "link.csv"):
        back = load_recording(tmp_path / name)
        assert np.array_equal(back.gyr, rec.gyr) and back.meta["source"] == "test"
