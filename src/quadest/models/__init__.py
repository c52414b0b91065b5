"""Models of the vehicle shared by the simulator and the estimators (layer 0: imports only
conventions, rotation and data). The simulator evaluates them as truth; estimators fit and use
their own copies (docs/developing.md, layers)."""

from quadest.models.aero import AeroModel, aero_force, features, fit_aero, free_flight_mask, psi
from quadest.models.multirotor import VEHICLE_PRESETS, MultirotorParams, quad_x, vehicle_preset

__all__ = [
    "AeroModel",
    "MultirotorParams",
    "VEHICLE_PRESETS",
    "vehicle_preset",
    "aero_force",
    "features",
    "fit_aero",
    "free_flight_mask",
    "psi",
    "quad_x",
]
