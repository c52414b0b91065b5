"""The one way quadest runs an estimator on a recording and scores it: every command that
compares estimators (compare, benchmark, sweep, reproduce) goes through :func:`estimate` and
:func:`score`.

- :func:`estimate`: a quadest filter (compiled batch run) or a peer (``quadest[peers]``), with
  the recording's declination, so every estimate references true north.
- :func:`score`: the rows to evaluate (BROAD's movement phases, ``t_from``), the constant frame
  rotations removed (by default what the reader recommends in ``meta['align']``), then the
  error figures of :func:`quadest.evaluation.metrics.summarize_errors`.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from quadest.data.recording import Recording
from quadest.errors import UsageError
from quadest.evaluation.align import Alignment, fit_alignment
from quadest.evaluation.metrics import SUM_ROWS, nees_terms, summarize_errors
from quadest.filters import ESTIMATORS, FILTERS, FilterResult, available_peers, estimator_class, filter_name


def estimator_names(spec: str, all_includes_peers: bool = False) -> list[str]:
    """``all`` (quadest's filters, and the installed peers with ``all_includes_peers``),
    ``quadest``, ``peers`` (the installed peers) or a comma-separated list of filters and peers."""
    spec = (spec or "all").strip()
    if spec in ("all", "quadest"):
        return list(FILTERS) + (available_peers() if spec == "all" and all_includes_peers else [])
    if spec == "peers":
        return available_peers()
    names = [filter_name(s.strip()) for s in spec.split(",") if s.strip()]
    bad = [n for n in names if n not in ESTIMATORS]
    if bad or not names:
        estimator_class(bad[0] if bad else spec)  # raises, naming the filters and peers
    missing = [n for n in names if not ESTIMATORS[n].available()]
    if missing:
        raise UsageError(f"peer(s) {', '.join(missing)} not installed: pip install 'quadest[peers]'")
    return names


def check_params(name: str, params: dict) -> None:
    """Refuse parameters a filter does not have (a peer has only ``use_mag``)."""
    cls = estimator_class(name)
    known = {d["name"] for d in cls.Params.describe()}
    bad = [k for k in params if k not in known]
    if bad:
        own = " (a peer runs at its own defaults)" if cls.peer else ""
        raise UsageError(f"{name} has no parameter {', '.join(bad)}{own}; parameters: {', '.join(sorted(known))}")


def estimate(
    rec: Recording, name: str, params: dict | None = None, *, declination: float | None = None
) -> FilterResult:
    """Run one estimator over ``rec``: a quadest filter with ``params``, or a peer at its own
    defaults. ``declination`` (rad) defaults to the recording's."""
    cls, params = estimator_class(name), params or {}
    check_params(cls.name, params)
    decl = rec.declination if declination is None else declination
    return cls(declination=decl, **params).run(rec)


ESTIMATE_ROWS = SUM_ROWS
"""Rows per piece where :func:`estimate_pieces` runs a quadest filter on a long recording (the
blocks its errors are summed by)."""


def estimate_pieces(rec: Recording, name: str, params: dict | None = None, rows: int | None = None):
    """:func:`estimate` piece by piece: ``(first row, FilterResult of the piece)``, a quadest
    filter resuming from its state at each piece (a recording up to ``rows`` long is one piece:
    :func:`estimate` itself; default :data:`ESTIMATE_ROWS`); a peer and an acausal estimator
    (each estimate uses the whole recording) run whole. A causal filter's outputs are never held
    whole."""
    cls, params, rows = estimator_class(name), params or {}, rows or ESTIMATE_ROWS
    if cls.peer or cls.acausal or len(rec) <= rows:
        yield 0, estimate(rec, name, params)
        return
    check_params(cls.name, params)
    est = cls(declination=rec.declination, **params)
    for a in range(0, len(rec), rows):
        b = a + rows
        mag = None if rec.mag is None else rec.mag[a:b]
        yield a, est.run(t=rec.t[a:b], gyr=rec.gyr[a:b], acc=rec.acc[a:b], mag=mag)


def filter_notes(res: FilterResult) -> list[str]:
    """What a user must be told about a run: samples skipped, restarts after gaps."""
    out = []
    if res.skipped:
        out.append(
            f"{res.name}: skipped {res.skipped} unusable sample(s) (an interval that is not positive, "
            "or a value that is not finite or beyond any sensor); the attitude was held there"
        )
    if res.mag_skipped:
        out.append(
            f"{res.name}: used {res.mag_skipped} sample(s) without their magnetometer value, which was not "
            "finite or beyond any sensor"
        )
    if res.restarts:
        times = ", ".join(f"{t:.3f}" for t in res.restarts[:5]) + (" ..." if len(res.restarts) > 5 else "")
        out.append(f"{res.name}: started again from the sensors after {len(res.restarts)} gap(s), at t = {times} s")
    return out


def estimate_all(rec: Recording, names: Iterable[str], params: dict | None = None, labels: dict | None = None) -> dict:
    """``{label: FilterResult}`` of several estimators; ``params`` and ``labels`` by name."""
    params = params or {}
    return {(labels or {}).get(n, n): estimate(rec, n, params.get(n)) for n in names}


def truth_of(rec: Recording) -> str:
    """``true_q``, or the log's onboard attitude ``ref_q`` when there is no independent truth."""
    if rec.true_q is not None:
        return "true_q"
    if rec.ref_q is not None:
        return "ref_q"
    raise ValueError("the recording has no attitude truth (true_q) or onboard reference (ref_q) to compare against")


def evaluation_mask(rec: Recording, t_from: float | None = None) -> np.ndarray:
    """Rows to evaluate: ``meta['evaluate_intervals_s']`` (BROAD's movement phases) or all,
    from the first magnetometer sample on when there is a magnetometer (before it a 9-axis
    estimator's heading is not yet known: :func:`first_mag_time`), and from ``t_from`` seconds
    after the recording's first sample on (a log's time need not start at 0)."""
    iv = rec.meta.get("evaluate_intervals_s")
    if iv:
        m = np.zeros(len(rec), bool)
        for a, b in iv:
            m |= (rec.t >= a) & (rec.t <= b)
    else:
        m = np.ones(len(rec), bool)
    if t_from is not None:
        m &= rec.t >= rec.t[0] + t_from
    return m & (rec.t >= first_mag_time(rec))


def first_mag_time(rec: Recording) -> float:
    """The time of the first magnetometer sample (the first sample's time without one)."""
    if rec.mag is None:
        return float(rec.t[0])
    finite = np.isfinite(rec.mag[:, 0])
    return float(rec.t[int(np.argmax(finite))]) if finite.any() else float(rec.t[0])


def alignment_of(rec: Recording, nav: str | None = None, body: bool | None = None) -> tuple[str, bool]:
    """The constant rotations to remove: as asked, else what the reader recommends
    (``meta['align']``), else none."""
    rec_align = rec.meta.get("align", {})
    return (
        nav if nav is not None else rec_align.get("nav", "none"),
        body if body is not None else bool(rec_align.get("body", False)),
    )


def align_estimate(
    rec: Recording, q, *, truth: str = "true_q", nav: str = "none", body: bool = False, mask=None
) -> tuple[np.ndarray, Alignment | None]:
    """The estimate in the truth's frames and the :class:`Alignment` removed (None if none asked)."""
    if nav == "none" and not body:
        return q, None
    m = evaluation_mask(rec) if mask is None else mask
    al = fit_alignment(q, getattr(rec, truth), nav=nav, body=body, mask=m, rate_hz=rec.imu_rate_hz())
    return al.apply(q), al


def score_result(rec: Recording, res: FilterResult, *, t_from: float | None = None, **alignment) -> dict:
    """:func:`score` of a run (``nav``, ``body`` as there), with the mean NEES of its reported
    covariance on the estimate as scored (:func:`consistency`: ``nees``, ``nees_tilt``) when the
    estimator reports one and the recording has an independent truth."""
    aligned: list = []
    out = score(rec, res.q, t_from=t_from, aligned=aligned, **alignment)
    out.update(consistency(rec, res, aligned[0], mask=evaluation_mask(rec, t_from)))
    return out


def consistency(rec: Recording, res: FilterResult, q: np.ndarray | None = None, *, mask=None) -> dict:
    """Mean NEES of a run's reported attitude covariance against the recording's independent
    truth (``true_q``; none against an onboard reference) over ``mask`` (default the evaluated
    rows): ``nees`` (3 degrees of freedom, ideal 3) and ``nees_tilt`` (the tilt's part: 2,
    ideal 2). Without a magnetometer the reported heading variance is that of an unknown
    heading (π²/3, or π²/6 for robust-offline's two passes fused) and the heading's part is
    near 0, so ``nees_tilt`` is the one to read. ``q`` is the estimate as scored (after the
    alignment :func:`score` removed; with a heading offset and a rotation in the body removed
    the error is still the navigation frame's, which the diagonal covariance describes),
    default the run's own. Empty when the estimator reports no covariance or there is no
    independent truth."""
    if rec.true_q is None or "var_tilt" not in res.diag or "var_heading" not in res.diag:
        return {}
    m = evaluation_mask(rec) if mask is None else mask
    tilt, heading = nees_terms(res.q if q is None else q, rec.true_q, res.diag["var_tilt"], res.diag["var_heading"], m)
    return {"nees": tilt + heading, "nees_tilt": tilt}


def score(
    rec: Recording,
    q: np.ndarray,
    *,
    truth: str | None = None,
    nav: str | None = None,
    body: bool | None = None,
    mask: np.ndarray | None = None,
    t_from: float | None = None,
    aligned: list | None = None,
) -> dict:
    """Error figures of one estimate (:func:`summarize_errors`) over the evaluated rows, after
    removing the constant rotations (:func:`alignment_of`); the alignment removed is under
    ``"alignment"``. ``aligned``, a list, receives the aligned estimate."""
    truth = truth or truth_of(rec)
    nav, body = alignment_of(rec, nav, body)
    m = evaluation_mask(rec, t_from) if mask is None else mask
    qa, al = align_estimate(rec, q, truth=truth, nav=nav, body=body, mask=m)
    out = summarize_errors(qa, getattr(rec, truth), m)
    if al is not None:
        out["alignment"] = al.describe()
    if aligned is not None:
        aligned.append(qa)
    return out
