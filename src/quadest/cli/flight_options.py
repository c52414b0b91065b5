"""The options ``quadest fly``, ``quadest campaign`` and the detection benchmarks share: a
failure (``--failure``) and the detector's parameters (``--set detector.*``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from quadest.cli.common import CliError, parse_sets
from quadest.errors import UsageError

if TYPE_CHECKING:  # the library is imported when a command runs
    from quadest.sim.faults import Failure


def parse_failure(text) -> Failure | None:
    """``--failure``'s value as a :class:`~quadest.sim.faults.Failure` (None: none)."""
    from quadest.sim.faults import Failure

    return None if text is None else Failure.parse(text)


def failure_record(f: Failure | None) -> dict | None:
    """A failure as the sweeps keep it (:meth:`~quadest.sim.faults.Failure.to_dict`)."""
    return None if f is None else f.to_dict()


MODE_HINT = " (--detection rotor-speeds or commands)"
"""How fly and campaign choose the detection mode, for their messages."""


def detector_changes(texts: dict, modes, hint: str = MODE_HINT) -> dict:
    """``--set detector.*`` (``{"lost_threshold": "0.008"}``) as ``{name: value}``, checked against
    the detector's bounds, those equal to the defaults left out. Refused where no detector flies
    (every one of ``modes`` the oracle) and for ``rotor_speeds``, which the detection mode decides
    (``hint``: how the command decides it)."""
    from quadest.detect import DetectorParams
    from quadest.records import check, with_fields

    if not texts:
        return {}
    if "rotor_speeds" in texts:
        raise CliError(f"--set detector.rotor_speeds: the detection mode decides it{hint}")
    if all(m == "oracle" for m in modes):
        raise CliError("--set detector.*: the oracle flies no detector; give --detection rotor-speeds or commands")
    record = with_fields(DetectorParams(), texts, "detector")
    try:
        check(record, "detector")
    except UsageError as exc:
        raise CliError(f"--set {exc}") from None
    default = DetectorParams()
    return {name: getattr(record, name) for name in texts if getattr(record, name) != getattr(default, name)}


def detector_sets(items, modes, command: str, hint: str = MODE_HINT) -> dict:
    """``--set detector.KEY=VALUE`` items, the only ``--set`` ``command`` takes, as the detector's
    changed parameters (:func:`detector_changes`)."""
    texts = {}
    for key, text in parse_sets(items).items():
        prefix, _, name = key.partition(".")
        if prefix != "detector" or not name:
            raise CliError(f"--set {key}: {command} takes detector.* (e.g. --set detector.lost_threshold=0.008)")
        texts[name] = text
    return detector_changes(texts, modes, hint)
