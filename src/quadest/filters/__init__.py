"""The attitude estimators, one module each (docs/estimators.md), and the adapters of the peers
(:mod:`quadest.filters.peers`: VQF, imufusion, ahrs, in quadest's conventions).

``FILTERS`` maps each estimator's name (its algorithm's: ``valenti``, ``roetenberg``, ...) to its
class; every class takes a parameter record (or keyword overrides), offers streaming ``update``
and batch ``run``. Former names (``RENAMED``) are still accepted, with a one-line note.
"""

import warnings

from quadest.filters.afckf import Afckf
from quadest.filters.base import Estimator, FilterResult
from quadest.filters.ekf import Ekf
from quadest.filters.madgwick import Madgwick
from quadest.filters.mahony import Mahony
from quadest.filters.qukf import Qukf
from quadest.filters.robust import Robust
from quadest.filters.roetenberg import Roetenberg
from quadest.filters.valenti import Valenti

FILTERS = {cls.name: cls for cls in (Robust, Afckf, Qukf, Ekf, Madgwick, Mahony, Valenti, Roetenberg)}

RENAMED = {"complementary": "valenti", "kalman": "roetenberg"}
"""Former names of filters, still accepted: ``complementary`` is Valenti et al.'s filter,
``kalman`` Roetenberg et al.'s."""

Complementary, Kalman = Valenti, Roetenberg  # the classes' former names


def filter_name(name: str) -> str:
    """The name a filter is registered under: ``name`` itself, or for a former name the current
    one, with a one-line :class:`FutureWarning`."""
    new = RENAMED.get(name)
    if new is None:
        return name
    warnings.warn(f"filter {name!r} is now called {new!r}; the old name will go", FutureWarning, stacklevel=2)
    return new


def make_filter(name: str, **kwargs) -> Estimator:
    """An estimator by its name (a former name too)."""
    name = filter_name(name)
    if name not in FILTERS:
        raise ValueError(f"unknown filter {name!r}; filters: {', '.join(FILTERS)}")
    return FILTERS[name](**kwargs)


__all__ = [
    "FILTERS",
    "RENAMED",
    "Estimator",
    "FilterResult",
    "filter_name",
    "make_filter",
    "Afckf",
    "Complementary",
    "Ekf",
    "Kalman",
    "Madgwick",
    "Mahony",
    "Qukf",
    "Robust",
    "Roetenberg",
    "Valenti",
]
