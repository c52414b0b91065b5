"""Controllers that fly the vehicle model (docs/vehicle.md): the nominal geometric controller
on SE(3), the fault-tolerant controller after a rotor loss, the recovery controller after a
throw, their registry, and what they are asked to fly. Layer 1: uses models."""

from quadest.control.ftc import FtcParams, fit_yaw_damping, ftc_command, nutation_rates, relaxed_hover
from quadest.control.reference import circle_reference, figure_eight_reference, hover_reference
from quadest.control.registry import CONTROLLERS, Controller
from quadest.control.se3 import SE3Params, allocation, se3_command

__all__ = [
    "CONTROLLERS",
    "Controller",
    "FtcParams",
    "SE3Params",
    "allocation",
    "circle_reference",
    "figure_eight_reference",
    "fit_yaw_damping",
    "ftc_command",
    "hover_reference",
    "nutation_rates",
    "relaxed_hover",
    "se3_command",
]
