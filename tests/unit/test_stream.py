"""The streaming call in C (src/quadest/filters/_stream.c, quadest.filters.base).

The C call must behave exactly as the Python ``Estimator.update`` it stands in for: the same
compiled step on the same state, so every output, diagnostic and counter bit-equal, whatever the
input (common case in C, the rest handed to Python). Not timed: speed is `quadest benchmark
speed`'s (docs/estimators.md).
"""

import gc
import pickle
import weakref

import numpy as np
import pytest
from numba import carray, cfunc, njit

from quadest.filters import FILTERS, base, make_filter
from quadest.sim import simulate


def test_the_extension_is_built():
    """`pip install -e .` builds it wherever a C compiler is found (as here and on CI): without
    it streaming still works, through Python, a microsecond slower per call."""
    assert base.STREAM_C, "quadest.filters._stream is not built: reinstall with a C compiler (make clean test)"


@pytest.fixture(scope="module")
def flight():
    return simulate("damaged-rotor", "bebop2", seed=3, duration=2)


def _inputs(rec):
    """The recording's samples in every form `update` accepts, and some it refuses or skips:
    views and copies, lists, float32, strided views, None or NaN for the magnetometer, the
    magnetometer by keyword, a numpy float, an int, NaN, zero, negative and gap intervals."""
    n = len(rec)
    dt = np.diff(rec.t, prepend=rec.t[0] - 0.002)
    wide = np.zeros((n, 6))
    wide[:, ::2] = rec.gyr
    calls = []
    for k in range(n):
        g, a, m, d = rec.gyr[k], rec.acc[k], rec.mag[k], float(dt[k])
        kind = k % 13
        args, kw = (g, a, m), {"dt": d}
        if kind == 1:
            args = (list(g), a.astype(np.float32), m)
        elif kind == 2:
            args = (wide[k, ::2], a, None)
        elif kind == 3:
            args, kw = (g, a), {"mag": m, "dt": np.float64(d)}
        elif kind == 4:
            args = (g, a)
        elif kind == 5 and k % 5 == 0:
            kw = {"dt": [float("nan"), 0.0, -d, 0.7][(k // 13) % 4]}  # skipped, skipped, skipped, a gap
        elif kind == 6:
            kw = {"dt": 1 if k % 7 == 0 else d}  # an int interval (1 s: a gap)
        elif kind == 7:
            args = (g.copy(), a.copy(), np.full(3, np.nan))
        elif kind == 8:
            args = (g, a, m.byteswap().view(m.dtype.newbyteorder()))  # the other byte order
        calls.append((args, kw))
    return calls


@pytest.mark.parametrize("name", [n for n, c in FILTERS.items() if c.streaming])
def test_c_and_python_streaming_agree_bit_for_bit(flight, name, monkeypatch):
    calls = _inputs(flight)
    c = make_filter(name, declination=0.03)
    out_c, diag_c = [], []
    for args, kw in calls:
        out_c.append(c.update(*args, **kw))
        diag_c.append(c._diag.copy())
    assert type(c.__dict__["update"]).__name__ == "Stream"  # the C call ran
    monkeypatch.setattr(base, "STREAM_C", False)
    py = make_filter(name, declination=0.03)
    out_py, diag_py = [], []
    for args, kw in calls:
        out_py.append(py.update(*args, **kw))
        diag_py.append(py._diag.copy())
    assert "update" not in py.__dict__  # the Python path ran
    np.testing.assert_array_equal(np.array(out_c), np.array(out_py))
    np.testing.assert_array_equal(np.array(diag_c), np.array(diag_py))
    np.testing.assert_array_equal(c.get_state(), py.get_state())
    assert (c.skipped, c.restarts) == (py.skipped, py.restarts)
    assert c.restarts >= 2 and c.skipped >= 3  # the odd intervals above were met


def test_the_c_call_follows_the_state_and_options(flight):
    """A new state (set_state, reset, unpickling) and a changed gap option reach the C call; its
    output is a new array each time, never a view of the state."""
    rec = flight
    f = make_filter("robust")
    for k in range(100):
        f.update(rec.gyr[k], rec.acc[k], rec.mag[k], dt=0.002)
    saved = f.get_state()
    a = f.update(rec.gyr[100], rec.acc[100], rec.mag[100], dt=0.002)
    b = f.update(rec.gyr[101], rec.acc[101], rec.mag[101], dt=0.002)
    assert a is not b and not np.shares_memory(a, f._x)
    a[:] = 0.0
    np.testing.assert_array_equal(f.q, b)
    f.set_state(saved)
    np.testing.assert_array_equal(f.update(rec.gyr[100], rec.acc[100], rec.mag[100], dt=0.002), f.q)
    assert type(f.__dict__["update"]).__name__ == "Stream"
    g = pickle.loads(pickle.dumps(f))
    np.testing.assert_array_equal(g.update(rec.gyr[101], rec.acc[101], rec.mag[101], dt=0.002), b)
    f.reset()
    assert f.skipped == 0 and np.isnan(f.get_state()[base.T_LAST])
    f.update(rec.gyr[0], rec.acc[0], rec.mag[0], dt=0.002)
    f.max_gap_s = 0.001  # now 2 ms is a gap: a restart, in the C call too
    f.update(rec.gyr[1], rec.acc[1], rec.mag[1], dt=0.002)
    assert f.restarts == 1
    with pytest.raises(ValueError, match=r"max_gap_s must be in \(0, 1e9\]"):
        f.max_gap_s = 0.0
    with pytest.raises(TypeError):
        f.update(rec.gyr[1], rec.acc[1], rec.mag[1], 0.002)  # dt is keyword-only, as in Python
    with pytest.raises(ValueError, match="vector of 3"):
        f.update(rec.gyr[1][:2], rec.acc[1], dt=0.002)


def test_an_estimator_streaming_in_c_is_freed():
    """The C call refers back to its estimator (for the Python path): the cycle is collected."""
    f = make_filter("madgwick")
    f.update(np.zeros(3), np.array([0.0, 0.0, -9.81]), dt=0.002)
    assert type(f.__dict__["update"]).__name__ == "Stream"
    ref = weakref.ref(f)
    del f
    gc.collect()
    assert ref() is None


@njit
def _faulty_step(x, gyr):
    if gyr[0] > 1.0:
        raise ValueError("a step that raises")
    x[0] = 1.0 / gyr[1]  # ZeroDivisionError at gyr[1] == 0


def _faulty(x, nx, p, n_p, c, nc, gyr, acc, mag, dt, diag, nd):
    try:
        _faulty_step(carray(x, nx), carray(gyr, 3))
    except Exception:  # noqa: BLE001
        return 1
    return 0


def test_an_exception_in_the_compiled_step_is_raised_not_swallowed():
    """numba cannot pass an exception through a C callback (it would print and go on): the
    stream functions return a status, and the C call raises from it."""
    from quadest.filters._stream import Stream

    fn = cfunc(base.STREAM_SIGNATURE)(_faulty)
    x, s = np.zeros(8), np.array([0.01, 0.5])
    st = Stream(fn.address, x, np.zeros(1), np.zeros(1), np.zeros(1), s, 4, lambda *a, **k: "python")
    st(np.array([0.0, 2.0, 0.0]), np.zeros(3), dt=0.01)
    assert x[0] == 0.5
    for bad in ([0.0, 0.0, 0.0], [2.0, 1.0, 0.0]):
        with pytest.raises(RuntimeError, match="compiled step raised"):
            st(np.array(bad), np.zeros(3), dt=0.01)
    assert st([0.0, 1.0, 0.0], np.zeros(3), dt=0.01) == "python"  # not the common case: Python's
    assert st(np.zeros(3), np.zeros(3), dt=0.7) == "python"  # a gap: Python's
    with pytest.raises(ValueError, match="contiguous float64"):
        Stream(fn.address, x[::2], np.zeros(1), np.zeros(1), np.zeros(1), s, 0, print)
    with pytest.raises(ValueError, match="q_off"):
        Stream(fn.address, x, np.zeros(1), np.zeros(1), np.zeros(1), s, 6, print)


def test_an_estimator_without_a_stream_function_streams_through_python(flight):
    """A class that sets no ``stream`` (an estimator being written) still streams, through the
    Python path, with the same results."""
    from quadest.filters.madgwick import Madgwick

    class Plain(Madgwick):
        stream = None

    a, b = Madgwick(), Plain()
    for k in range(50):
        args = (flight.gyr[k], flight.acc[k], flight.mag[k])
        np.testing.assert_array_equal(a.update(*args, dt=0.002), b.update(*args, dt=0.002))
    assert "update" in a.__dict__ and "update" not in b.__dict__
