"""The attitude estimators, one module each (docs/estimators.md), and the adapters of the peers
(:mod:`quadest.filters.peers`: VQF, imufusion, ahrs, in quadest's conventions).

``FILTERS`` maps the command-line name to the estimator class; every class takes a parameter
record (or keyword overrides), offers streaming ``update`` and batch ``run``.
"""

from quadest.filters.afckf import Afckf
from quadest.filters.base import Estimator, FilterResult
from quadest.filters.complementary import Complementary
from quadest.filters.ekf import Ekf
from quadest.filters.kalman import Kalman
from quadest.filters.madgwick import Madgwick
from quadest.filters.mahony import Mahony
from quadest.filters.qukf import Qukf
from quadest.filters.robust import Robust

FILTERS = {cls.name: cls for cls in (Robust, Afckf, Qukf, Ekf, Madgwick, Mahony, Complementary, Kalman)}


def make_filter(name: str, **kwargs) -> Estimator:
    """An estimator by its command-line name."""
    if name not in FILTERS:
        raise ValueError(f"unknown filter {name!r}; filters: {', '.join(FILTERS)}")
    return FILTERS[name](**kwargs)


__all__ = [
    "FILTERS",
    "Estimator",
    "FilterResult",
    "make_filter",
    "Afckf",
    "Complementary",
    "Ekf",
    "Kalman",
    "Madgwick",
    "Mahony",
    "Qukf",
    "Robust",
]
