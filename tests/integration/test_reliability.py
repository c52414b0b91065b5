"""Nothing lost, nothing silent (docs/reliability.md): bad samples are skipped and
counted, never turned into NaN for the rest of a run; gaps restart the estimators; parameters
are checked when a filter is built; outputs never destroy inputs."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from quadest.filters import FILTERS, make_filter
from quadest.rotation import angle_between, euler_to_quat, quat_conj, quat_rotate

G = 9.80665
B_N = np.array([20.0, 0.0, 45.0])  # a magnetic field in NED, µT


def _static(q_true, n):
    """Noise-free samples of a vehicle at rest with attitude ``q_true``."""
    acc = quat_rotate(quat_conj(q_true), np.array([0.0, 0.0, -G]))
    mag = quat_rotate(quat_conj(q_true), B_N)
    return np.zeros((n, 3)), np.tile(acc, (n, 1)), np.tile(mag, (n, 1))


BAD = {
    "gyr nan": ("gyr", np.nan),
    "gyr inf": ("gyr", np.inf),
    "gyr huge": ("gyr", 1e200),
    "acc nan": ("acc", np.nan),
    "acc -inf": ("acc", -np.inf),
    "acc huge": ("acc", 1e200),
    "mag inf": ("mag", np.inf),
    "mag huge": ("mag", 1e300),
    "dt nan": ("dt", np.nan),
    "dt zero": ("dt", 0.0),
    "dt negative": ("dt", -0.5),
    "dt inf": ("dt", np.inf),
    "dt huge": ("dt", 1e5),
}


@pytest.mark.parametrize("name", [n for n, c in FILTERS.items() if c.streaming])  # sample by sample
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kinds=st.lists(st.sampled_from(sorted(BAD)), min_size=1, max_size=6),
    start=st.integers(50, 250),
    spread=st.integers(0, 3),
)
def test_a_bad_stretch_never_poisons_a_filter(name, kinds, start, spread):
    """Streaming: whatever bad values arrive, every output is a finite unit quaternion, and
    after the bad stretch the attitude is back within 1° of the truth (noise-free rest, so the
    filters hold the truth before it; a huge interval restarts them from the sensors)."""
    q_true = euler_to_quat([0.2, -0.1, 0.7])
    n = 400 + 200 * (name in ("qukf", "ekf", "mahony", "valenti"))  # slow filters settle longer
    gyr, acc, mag = _static(q_true, n)
    dt = np.full(n, 0.002)
    for i, kind in enumerate(kinds):
        what, value = BAD[kind]
        k = start + i * spread
        if what == "dt":
            dt[k] = value
        else:
            {"gyr": gyr, "acc": acc, "mag": mag}[what][k, i % 3] = value
    f = make_filter(name)
    out = np.array([f.update(gyr[k], acc[k], mag[k], dt=dt[k]) for k in range(n)])
    assert np.isfinite(out).all()
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-9)
    assert np.degrees(angle_between(out[-1], q_true)) < 1.0
    assert f.skipped + f.restarts + f.mag_skipped >= 1


@pytest.mark.parametrize("name", list(FILTERS))
def test_batch_skips_bad_times_and_restarts_after_a_gap(name):
    """A NaN time and a decreasing time are skipped (counted), never NaN for the rest; a 10 s
    gap in which the vehicle turned by 90° restarts the filter from the sensors, which find the
    new heading at once (integrating across the gap would keep the old one)."""
    n = 3000
    t = np.arange(n) * 0.002
    q0, q1 = euler_to_quat([0.0, 0.0, 0.0]), euler_to_quat([0.0, 0.0, np.pi / 2])
    g0, a0, m0 = _static(q0, n // 2)
    g1, a1, m1 = _static(q1, n - n // 2)
    gyr, acc, mag = np.vstack([g0, g1]), np.vstack([a0, a1]), np.vstack([m0, m1])
    t[n // 2 :] += 10.0
    t[100] = np.nan
    t[200] = t[199] - 0.5  # a time going backwards
    res = make_filter(name).run(t=t, gyr=gyr, acc=acc, mag=mag)
    assert np.isfinite(res.q).all()
    assert res.skipped == 2  # the NaN time and the backward one; the next intervals count from the last good time
    assert res.restarts == (pytest.approx(t[n // 2]),)
    assert np.degrees(angle_between(res.q[n // 2 + 5], q1)) < 1.0
    assert np.degrees(angle_between(res.q[-1], q1)) < 1.0


@pytest.mark.parametrize(
    "name, params, match",
    [
        ("roetenberg", {"gyro_noise": -0.01}, r"gyro_noise must be in \(0, 10\]"),
        ("mahony", {"k_p": 1e300}, r"k_p must be in \[0, 1e3\]"),
        ("madgwick", {"beta_marg": float("nan")}, "beta_marg must be a finite number"),
        ("afckf", {"theta_m": 1.0}, r"theta_m must be in \(1, 1e6\]"),
        ("qukf", {"lam": -4.0}, r"lam must be in \(-4, 1e3\]"),
        ("valenti", {"gain_acc": 2.0}, r"gain_acc must be in \[0, 1\]"),
    ],
)
def test_parameters_are_checked_when_a_filter_is_built(name, params, match):
    with pytest.raises(ValueError, match=match):
        make_filter(name, **params)


def test_declination_and_gap_options_are_checked():
    with pytest.raises(ValueError, match="declination must be a finite"):
        make_filter("madgwick", declination=float("nan"))
    with pytest.raises(ValueError, match=r"max_gap_s must be in \(0, 1e9\]"):
        make_filter("madgwick", max_gap_s=-1.0)
    f = make_filter("madgwick", max_gap_s=0.05)
    q_true = euler_to_quat([0.1, 0.0, 0.3])
    gyr, acc, mag = _static(q_true, 3)
    f.update(gyr[0], acc[0], mag[0], dt=0.01)
    f.update(gyr[1], acc[1], mag[1], dt=0.06)  # longer than max_gap_s: a restart
    assert f.restarts == 1 and f.skipped == 0


def test_the_hostile_cases_behave_as_promised(capsys):
    """tools/hostile_cases.py: every case of bad input ends as docs/reliability.md promises."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "tools" / "hostile_cases.py"
    spec = importlib.util.spec_from_file_location("hostile_cases", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    code = mod.main_([])
    table = capsys.readouterr().out
    assert code == 0, table
    assert "**no**" not in table


def test_a_server_that_is_not_a_dask_scheduler_does_not_hang_a_sweep():
    """A listener that accepts the connection and never answers (Dask's own timeout covers only
    TCP): the handshake times out as a whole and says what answered."""
    import socket
    import threading
    import time

    from quadest.evaluation.parallel import dask_client

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    held = []
    threading.Thread(target=lambda: [held.append(srv.accept()) for _ in range(4)], daemon=True).start()
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="did not answer as a Dask scheduler"):
        with dask_client(scheduler=f"tcp://127.0.0.1:{srv.getsockname()[1]}", timeout_s=1.0):
            pass
    assert time.monotonic() - t0 < 30.0
    srv.close()


def test_an_interrupted_or_failed_write_leaves_the_old_file(tmp_path):
    """Outputs are written beside the target and renamed: Ctrl-C or a failing write leaves the
    file that was there, and no temporary file."""
    from quadest.data.files import atomic_output

    p = tmp_path / "out.csv"
    p.write_text("old")
    for exc in (KeyboardInterrupt(), OSError(27, "File too large")):
        with pytest.raises(type(exc)):
            with atomic_output(p) as tmp:
                tmp.write_text("partial")
                raise exc
        assert p.read_text() == "old" and sorted(tmp_path.iterdir()) == [p]


def test_a_file_size_limit_fails_the_command_and_keeps_the_old_output(tmp_path):
    """``ulimit -f`` (the write fails with EFBIG): one line, exit 1, the old output intact."""
    import resource
    import subprocess
    import sys

    from quadest.data import save_recording
    from quadest.sim import simulate

    src = save_recording(simulate("hover", "bebop2", seed=1, duration=20.0), tmp_path / "big.csv")
    keep = tmp_path / "keep.csv"
    keep.write_text("old output")

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))

    r = subprocess.run(
        [sys.executable, "-m", "quadest.cli.main", "estimate", str(src), "--filter", "madgwick", "-o", str(keep)],
        capture_output=True,
        text=True,
        preexec_fn=limit,
        timeout=600,
    )
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "File too large" in r.stderr, r.stderr
    assert keep.read_text() == "old output"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.csv", "big.csv-metadata.json", "keep.csv"]


def test_an_hdf5_group_where_a_dataset_belongs_is_refused(tmp_path):
    import h5py

    from quadest.readers import read_recording

    p = tmp_path / "g.hdf5"
    with h5py.File(p, "w") as f:
        f.attrs["sampling_rate"] = 100.0
        for k in ("imu_gyr", "imu_mag", "opt_quat", "movement"):
            f[k] = np.zeros((10, 4 if k == "opt_quat" else 3))
        f.create_group("imu_acc")
    with pytest.raises(ValueError, match="'imu_acc' is a group, not a dataset"):
        read_recording(p, "broad")


# -- values of any type, damaged states, bad times and magnetometer values ---------------------------
@pytest.mark.parametrize(
    "value",
    ["nan", np.float32("nan"), "-1", np.int64(-5), "1e300", True, 10**400, float("inf"), None, [0.5]],
    ids=repr,
)
def test_a_parameter_is_checked_whatever_its_type(value):
    """One converter before the bounds: strings, numpy scalars, bools, NaN, huge integers are all
    refused in one line naming the parameter and its bounds."""
    with pytest.raises(ValueError, match=r"^mahony: k_p must be .*in \[0, 1e3\], got ") as err:
        make_filter("mahony", k_p=value)
    assert "\n" not in str(err.value)


def test_numpy_numbers_are_taken_as_plain_numbers():
    f = make_filter("mahony", k_p=np.float32(0.5), k_i=np.int64(0))
    assert type(f.params.k_p) is float and f.params.k_p == 0.5 and type(f.params.k_i) is float
    assert make_filter("madgwick", use_mag=np.bool_(False)).params.use_mag is False
    with pytest.raises(ValueError, match="use_mag must be true or false"):
        make_filter("madgwick", use_mag="false")  # a non-empty string is truthy: never taken as a flag


@pytest.mark.parametrize("q0", [[0, 0, 0, 0], [np.nan, 1, 0, 0], [1, 0, 0], [[1, 0, 0, 0]], "1000", [np.inf, 0, 0, 0]])
def test_a_q0_that_is_not_an_attitude_is_refused(q0):
    with pytest.raises(ValueError, match="madgwick: q0 must be a quaternion"):
        make_filter("madgwick", q0=q0)
    f = make_filter("madgwick")
    with pytest.raises(ValueError, match="madgwick: q0 must be a quaternion"):
        f.reset(q0)


def test_q0_is_normalised():
    f = make_filter("madgwick", q0=[2.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(f.q, [1.0, 0.0, 0.0, 0.0])


def _state_with(f, index, value):
    x = f.get_state()
    x[index] = value
    return x


@pytest.mark.parametrize(
    "what, edit",
    [
        ("shape", lambda f: f.get_state()[:-1]),
        ("not finite", lambda f: _state_with(f, 0, np.nan)),
        ("not finite", lambda f: _state_with(f, -1, np.inf)),
        ("not finite", lambda f: _state_with(f, 6, np.inf)),  # the last time may be NaN, never infinite
        ("unit quaternion", lambda f: _state_with(f, 0, 0.5)),
        ("0 or 1", lambda f: _state_with(f, 4, 0.5)),
        ("counter", lambda f: _state_with(f, 7, 1e308)),
        ("counter", lambda f: _state_with(f, 7, -1.0)),
        ("counter", lambda f: _state_with(f, 8, 2.5)),
        ("unit circle", lambda f: _state_with(f, 10, 3.0)),
        ("numbers", lambda f: ["a"] * len(f.get_state())),
    ],
)
def test_set_state_refuses_what_cannot_be_a_state(what, edit):
    f = make_filter("mahony")
    q_true = euler_to_quat([0.1, 0.2, 0.3])
    gyr, acc, mag = _static(q_true, 20)
    f.run(t=np.arange(20) * 0.01, gyr=gyr, acc=acc, mag=mag)
    x = f.get_state()
    with pytest.raises(ValueError, match=what):
        f.set_state(edit(f))
    np.testing.assert_array_equal(f.get_state(), x)  # left as it was
    f.set_state(x)  # a state it gave is taken back


def test_every_public_setter_is_checked():
    f = make_filter("madgwick")
    for value in ("0.1", float("nan"), np.float32("inf"), True):
        with pytest.raises(ValueError, match="madgwick: declination must be a finite number"):
            f.declination = value
        with pytest.raises(ValueError, match=r"madgwick: max_gap_s must be"):
            f.max_gap_s = value
    with pytest.raises(ValueError, match="madgwick: k_p|madgwick: params must be a MadgwickParams"):
        f.params = make_filter("mahony").params
    with pytest.raises(ValueError, match=r"madgwick: beta_imu must be in"):
        f.params = type(f.params)(beta_imu=-1.0)
    f.max_gap_s = np.float64(0.2)
    assert f.max_gap_s == 0.2
    f.declination = np.float32(0.5)  # applies at once
    np.testing.assert_allclose(f.q, [np.cos(0.25), 0.0, 0.0, np.sin(0.25)], atol=1e-7)


def test_a_parameter_record_set_later_takes_effect():
    """A new record is checked and used from the next sample, as if built with it."""
    q_true = euler_to_quat([0.3, 0.0, 0.0])
    gyr, acc, mag = _static(q_true, 50)
    a, b = make_filter("madgwick"), make_filter("madgwick", beta_marg=0.5)
    a.params = type(a.params)(beta_marg=0.5)
    qa = [a.update(gyr[k], acc[k], mag[k], dt=0.01) for k in range(50)]
    qb = [b.update(gyr[k], acc[k], mag[k], dt=0.01) for k in range(50)]
    np.testing.assert_array_equal(qa, qb)


@pytest.mark.parametrize("bad_t", [np.inf, -np.inf, np.nan])
def test_a_non_finite_time_is_skipped_and_counted_not_a_gap(bad_t):
    n = 400
    t = np.arange(n) * 0.01
    t[200] = bad_t
    gyr, acc, mag = _static(euler_to_quat([0.1, 0.2, 0.3]), n)
    res = make_filter("madgwick").run(t=t, gyr=gyr, acc=acc, mag=mag)
    assert res.skipped == 1 and res.restarts == ()
    assert np.isfinite(res.q).all()


@pytest.mark.parametrize("name", list(FILTERS))
def test_a_bad_magnetometer_value_skips_only_the_magnetometer(name):
    """A non-finite or absurd magnetometer value is used as "no magnetometer sample" (counted in
    mag_skipped): the gyroscope and accelerometer of that sample are used, exactly as if the row
    were NaN; streaming does the same."""
    rng = np.random.default_rng(3)
    n = 600
    t = np.arange(n) * 0.005
    gyr = 0.3 * rng.standard_normal((n, 3))
    acc = np.array([0.5, -0.3, -9.7]) + 0.2 * rng.standard_normal((n, 3))
    mag = np.array([20.0, 2.0, 40.0]) + 0.5 * rng.standard_normal((n, 3))
    bad, nan = mag.copy(), mag.copy()
    rows = [100, 250, 251, 400]
    for r, v in zip(rows, (np.inf, 1e300, -np.inf, np.nan)):
        bad[r, r % 3] = v  # one axis bad: a partly NaN row is bad too
        nan[r] = np.nan
    res = make_filter(name).run(t=t, gyr=gyr, acc=acc, mag=bad)
    ref = make_filter(name).run(t=t, gyr=gyr, acc=acc, mag=nan)
    assert res.skipped == 0 and res.mag_skipped == len(rows) and ref.mag_skipped == 0
    np.testing.assert_array_equal(res.q, ref.q)
    if not make_filter(name).streaming:  # robust-offline: batch only
        return
    f = make_filter(name)
    streamed = np.array([f.update(gyr[k], acc[k], bad[k], dt=0.005) for k in range(n)])
    assert f.mag_skipped == len(rows) and f.skipped == 0
    np.testing.assert_allclose(streamed, res.q, rtol=0, atol=1e-12)  # as every batch and stream agree


# -- damaged and mislabelled input ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def hover():
    from quadest.sim import simulate

    return simulate("hover", "bebop2", seed=1, duration=3.0)


def _short_log():
    from quadest.sim import simulate

    return simulate("hover", "bebop2", seed=4, duration=2.0, overrides={"imu.rate_hz": 100.0, "mag.rate_hz": 100.0})


def test_a_dataflash_log_cut_inside_a_message_is_read_with_a_warning(tmp_path):
    from logwriters import write_dataflash

    from quadest.readers import read_recording

    whole = tmp_path / "whole.bin"
    write_dataflash(whole, _short_log())
    raw = whole.read_bytes()
    assert "warnings" not in read_recording(whole).meta
    cut = tmp_path / "cut.bin"
    at = len(raw) // 2 + 5
    at += 1 if at % 512 == 0 else 0
    cut.write_bytes(raw[:at])
    (warning,) = read_recording(cut).meta["warnings"]
    assert "cut short inside a message" in warning and "t = " in warning
    between = tmp_path / "between.bin"  # cut exactly after a message: cannot be told
    between.write_bytes(raw[: raw.rfind(b"\xa3\x95", 0, at)])
    assert "warnings" not in read_recording(between).meta


def _parquet_with(path, hover, name, values):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from quadest.data import save_recording

    save_recording(hover, path)
    table = pq.read_table(path)
    i = table.column_names.index(name)
    table = table.set_column(i, name, pa.array(values))
    pq.write_table(table.replace_schema_metadata(pq.read_table(path).schema.metadata), path)
    return path


@pytest.mark.parametrize(
    "values, said",
    [
        (lambda n: np.ones(n, bool), "column gyr_x holds bool values, not numbers"),
        (lambda n: ["0.1"] * n, "column gyr_x holds string values, not numbers"),
        (lambda n: np.full(n, 2**62, np.int64), "column gyr_x holds the integer 4611686018427387904 at row 0"),
    ],
)
def test_a_parquet_column_of_another_type_is_refused(tmp_path, hover, values, said):
    from quadest.data import load_recording

    path = _parquet_with(tmp_path / "r.parquet", hover, "gyr_x", values(len(hover)))
    with pytest.raises(ValueError, match=said):
        load_recording(path)


def test_a_csv_column_of_words_is_refused(tmp_path, hover):
    from quadest.data import load_recording, save_recording

    path = save_recording(hover, tmp_path / "r.csv")
    lines = path.read_text().splitlines(keepends=True)
    head = next(i for i, line in enumerate(lines) if line.startswith("t,"))
    for k in range(head + 1, len(lines)):
        cells = lines[k].split(",")
        cells[1] = "true" if k % 2 else "false"
        lines[k] = ",".join(cells)
    path.write_text("".join(lines))
    with pytest.raises(ValueError, match="column gyr_x holds bool values, not numbers"):
        load_recording(path)


@pytest.mark.parametrize("name, unit", [("gyr", "deg/s"), ("acc", "g")])
def test_a_units_line_that_contradicts_si_is_refused(tmp_path, hover, name, unit):
    from quadest.data import load_recording, save_recording

    path = save_recording(hover, tmp_path / "r.csv")
    side = tmp_path / "r.csv-metadata.json"  # the recording's metadata, its units among them
    text = side.read_text()
    assert '"gyr": "rad/s"' in text
    side.write_text(text.replace(f'"{name}": "{hover.meta["units"][name]}"', f'"{name}": "{unit}"'))
    with pytest.raises(ValueError, match=rf"{name} is stated to be in '{unit}', but a recording holds"):
        load_recording(path)
    from quadest.data import Recording

    with pytest.raises(ValueError, match="is stated to be in"):  # a Parquet file's metadata, or any
        Recording(t=hover.t, gyr=hover.gyr, acc=hover.acc, meta={"units": {name: unit}})


@pytest.mark.parametrize("edit", ["crlf", "blank line", "blank lines and spaces"])
def test_a_csv_with_crlf_or_trailing_blank_lines_is_whole(tmp_path, hover, edit):
    from quadest.data import load_recording, save_recording

    path = save_recording(hover, tmp_path / "r.csv")
    data = path.read_bytes()
    data = {
        "crlf": data.replace(b"\n", b"\r\n"),
        "blank line": data + b"\n",
        "blank lines and spaces": data + b"\r\n  \n\n",
    }[edit]
    path.write_bytes(data)
    back = load_recording(path)
    np.testing.assert_array_equal(back.t, hover.t)
    np.testing.assert_array_equal(back.gyr, hover.gyr)
    path.write_bytes(data[: data.rstrip().rfind(b"\n") + 1])  # and a file without its last row is cut short
    with pytest.raises(ValueError, match="cut short"):
        load_recording(path)


def test_a_hover_recorded_in_deg_s_is_warned_of(hover):
    """A hover's rates are hundredths of a rad/s; in deg/s the same rates read a few units where
    the accelerometer holds still: warned of (the magnetometer cannot tell over 3 s of hover)."""
    from quadest.data import Recording

    with pytest.warns(UserWarning, match="where the accelerometer holds still .* is it in deg/s"):
        Recording(t=hover.t, gyr=np.degrees(hover.gyr), acc=hover.acc, mag=hover.mag, meta=hover.meta)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Recording(t=hover.t, gyr=hover.gyr, acc=hover.acc, mag=hover.mag, meta=hover.meta)


def _cli(*argv) -> tuple[int, str]:
    import contextlib
    import io

    from quadest.cli.main import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main([str(a) for a in argv])
    return code, err.getvalue()


@pytest.mark.parametrize("kind", ["ulog", "dataflash"])
def test_reader_options_that_do_not_apply_are_refused(tmp_path, kind):
    from logwriters import write_dataflash, write_ulog

    from quadest.readers import read_recording

    path = tmp_path / ("log.ulg" if kind == "ulog" else "log.bin")
    (write_ulog if kind == "ulog" else write_dataflash)(path, _short_log())
    code, err = _cli("info", path, "--units", "gyr=deg/s")
    assert code == 2 and f"--units does not apply to a {kind} file" in err and err.count("\n") == 1, err
    code, err = _cli("info", path, "--frame", "enu-flu")
    assert code == 2 and "--frame does not apply" in err, err
    with pytest.raises(ValueError, match=r"instance=5, but the log holds IMU instance\(s\) 0"):
        read_recording(path, instance=5)
    for bad in ("1", -1, 1.5, True):
        with pytest.raises(ValueError, match="instance"):
            read_recording(path, instance=bad)
    assert len(read_recording(path, instance=np.int64(0)))


def test_an_unreadable_file_says_permission_denied(tmp_path, hover, monkeypatch):
    """A file its user may not read: "Permission denied", not "not quadest's own". Root, whom
    permissions do not stop (this machine's CI), gets the system's refusal imitated: the file's
    ``open`` raises the PermissionError a user gets."""
    import builtins
    import errno
    import os

    from quadest.data import save_recording

    path = save_recording(hover, tmp_path / "r.csv")
    os.chmod(path, 0)
    if os.access(path, os.R_OK):  # root
        real_open = builtins.open

        def refusing_open(file, *args, **kwargs):
            if isinstance(file, (str, os.PathLike)) and os.fspath(file) == str(path):
                raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
            return real_open(file, *args, **kwargs)

        monkeypatch.setattr(builtins, "open", refusing_open)
    try:
        code, err = _cli("info", path)
    finally:
        os.chmod(path, 0o644)
    assert code == 1 and "Permission denied" in err and "not quadest's own" not in err, err


def test_file_names_that_are_not_utf8_are_read_and_written(tmp_path):
    """Any bytes in a file name: pyarrow opens only UTF-8 names, so quadest hands it open files;
    the report shows the bytes UTF-8 cannot say as U+FFFD."""
    import os

    from quadest.cli.main import main

    names = [
        os.path.join(str(tmp_path), os.fsdecode(n))
        for n in (b"h\xff.parquet", b"e\xfe.parquet", b"c\xfd.csv", b"r\xfc.html")
    ]
    rec, est, csv, html = names
    assert main(["simulate", "--scenario", "hover", "--duration", "2", "-o", rec]) == 0
    assert main(["estimate", rec, "--filter", "madgwick", "-o", est]) == 0
    assert main(["simulate", "--scenario", "hover", "--duration", "2", "-o", csv]) == 0
    assert main(["estimate", csv, "--filter", "madgwick", "-o", est]) == 0
    assert main(["info", rec]) == 0
    assert main(["report", rec, "-o", html]) == 0
    assert "h\ufffd.parquet" in open(html, "rb").read().decode("utf-8")
    written = [*names, csv + "-metadata.json"]  # the CSV's metadata beside it
    assert sorted(os.listdir(os.fsencode(tmp_path))) == sorted(os.fsencode(os.path.basename(n)) for n in written)
