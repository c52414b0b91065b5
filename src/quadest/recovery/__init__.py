"""State-estimate recovery (Beffa, Ledergerber & D'Andrea): the aerodynamic force model."""
from quadest.recovery.aero import AeroModel, features, psi

__all__ = ["AeroModel", "features", "psi"]
