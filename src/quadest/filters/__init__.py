"""The attitude estimators, one module each (docs/estimators.md), and the peers
(:mod:`quadest.filters.peers`: VQF, imufusion, ahrs, in quadest's conventions).

``ESTIMATORS`` is the one registry: each estimator's name (its algorithm's: ``valenti``,
``roetenberg``, ...; a peer's package's) to its :class:`Estimator` class. Every class takes a
parameter record (or keyword overrides) and offers batch ``run``; those with ``streaming`` offer
``update``. ``FILTERS`` and ``PEERS`` are its two parts (quadest's own, the other packages').
Former names (``RENAMED``) are still accepted, with a one-line note.
"""

import warnings

from quadest.errors import UsageError
from quadest.filters.afckf import Afckf
from quadest.filters.base import Estimator, FilterResult
from quadest.filters.ekf import Ekf
from quadest.filters.madgwick import Madgwick
from quadest.filters.mahony import Mahony
from quadest.filters.peers import PEER_CLASSES, Peer
from quadest.filters.qukf import Qukf
from quadest.filters.robust import Robust, RobustOffline
from quadest.filters.roetenberg import Roetenberg
from quadest.filters.valenti import Valenti

ESTIMATORS = {
    cls.name: cls
    for cls in (Robust, RobustOffline, Afckf, Qukf, Ekf, Madgwick, Mahony, Valenti, Roetenberg, *PEER_CLASSES)
}
FILTERS = {name: cls for name, cls in ESTIMATORS.items() if not cls.peer}
"""quadest's own estimators (compiled)."""
PEERS = {name: cls for name, cls in ESTIMATORS.items() if cls.peer}
"""Other packages' estimators at their own defaults (``pip install 'quadest[peers]'``)."""

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


def estimator_class(name: str) -> type[Estimator]:
    """The class registered under ``name`` (a former name too)."""
    cls = ESTIMATORS.get(filter_name(name))
    if cls is None:
        raise UsageError(f"unknown filter {name!r}; filters: {', '.join(FILTERS)}; peers: {', '.join(PEERS)}")
    return cls


def make_filter(name: str, **kwargs) -> Estimator:
    """An estimator (quadest's or a peer) by its name (a former name too)."""
    return estimator_class(name)(**kwargs)


def available_peers() -> list[str]:
    """The peers whose package is installed."""
    return [name for name, cls in PEERS.items() if cls.available()]


__all__ = [
    "ESTIMATORS",
    "FILTERS",
    "PEERS",
    "Peer",
    "available_peers",
    "estimator_class",
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
    "RobustOffline",
    "Roetenberg",
    "Valenti",
]
