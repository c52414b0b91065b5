"""State-estimate recovery (Beffa, Ledergerber & D'Andrea): the aerodynamic force model and its
fit, hypotheses spread on the sphere, the bank of EKFs and the recovery logic, and the checks
that start a recovery in flight (docs/recovery.md)."""

from quadest.models.aero import AeroModel, features, fit_aero, psi
from quadest.recovery.divergence import DivergenceParams
from quadest.recovery.logic import RecoveryParams, RecoveryResult, recover
from quadest.recovery.sphere import min_angle, spread_points

__all__ = [
    "AeroModel",
    "DivergenceParams",
    "RecoveryParams",
    "RecoveryResult",
    "features",
    "fit_aero",
    "min_angle",
    "psi",
    "recover",
    "spread_points",
]
