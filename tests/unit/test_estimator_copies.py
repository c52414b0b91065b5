"""An estimator's copy is its own, and a streaming interval is a real number of seconds above
no sensor's (docs/reliability.md)."""

import copy
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

from quadest.errors import UsageError
from quadest.filters import make_filter

GYR, ACC, MAG = np.array([0.1, -0.05, 0.02]), np.array([0.3, -0.2, -9.8]), np.array([20.0, 1.0, 40.0])


@pytest.mark.parametrize("name", ["robust", "madgwick", "ekf"])
def test_a_copy_shares_nothing_with_the_original(name):
    """Before: copy.copy shared the state, parameter and coefficient arrays: updating the copy
    moved the original, a parameter set on the copy changed the original's."""
    f = make_filter(name)
    for _ in range(5):
        f.update(GYR, ACC, MAG, dt=0.01)
    q, state, params = f.q, f.get_state(), f.params
    for c in (copy.copy(f), copy.deepcopy(f)):
        for _ in range(50):
            c.update(-GYR, ACC, MAG, dt=0.01)
        assert not np.allclose(c.q, q)
        assert np.array_equal(f.q, q) and np.array_equal(f.get_state(), state, equal_nan=True) and f.params == params


@pytest.mark.parametrize("dt", [Decimal("0.01"), "0.01", True, np.array([0.01])])
def test_an_interval_that_is_not_a_real_number_is_one_line(dt):
    """Before: a Decimal reached numba's typing error (many lines)."""
    f = make_filter("robust")
    with pytest.raises(UsageError, match="dt must be a real number of seconds") as e:
        f.update(GYR, ACC, dt=dt)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("name", ["robust", "afckf", "qukf", "ekf", "madgwick", "mahony", "valenti", "roetenberg"])
def test_a_vanishing_interval_is_skipped_and_counted(name):
    """Before: robust's compiled step raised on dt = 5e-324 ("please report it"). Real numbers
    of other types are taken as floats."""
    f = make_filter(name)
    for _ in range(20):
        f.update(GYR, ACC, MAG, dt=0.01)
    q = f.q
    for dt in (5e-324, 1e-300, 1e-10):
        f.update(GYR, ACC, MAG, dt=dt)
    assert f.skipped == 3 and np.array_equal(f.q, q)
    f.update(GYR, ACC, MAG, dt=Fraction(1, 100))
    f.update(GYR, ACC, MAG, dt=np.float32(0.01))
    assert f.skipped == 3 and np.isfinite(f.q).all()
