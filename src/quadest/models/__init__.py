"""Models of the vehicle shared by the simulator and the estimators (layer 0: imports only
conventions, rotation and data). The simulator evaluates them as truth; estimators fit and use
their own copies (docs/developing.md, layers)."""
from quadest.models.aero import AeroModel, aero_force, features, fit_aero, free_flight_mask, psi
from quadest.models.multirotor import MultirotorParams, quad_x

__all__ = ["AeroModel", "MultirotorParams", "aero_force", "features", "fit_aero", "free_flight_mask", "psi",
           "quad_x"]
