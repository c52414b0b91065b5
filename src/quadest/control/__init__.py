"""Controllers that fly the vehicle model (issue #13; docs/vehicle.md): the nominal geometric
controller on SE(3), the fault-tolerant controller after a rotor loss, and the closed loop on
the true state. Layer 1: uses models."""

from quadest.control.ftc import FtcParams, fit_yaw_damping, ftc_command, relaxed_hover
from quadest.control.loop import Failure, circle_reference, fly_se3, hover_reference
from quadest.control.se3 import SE3Params, allocation, se3_command

__all__ = [
    "Failure",
    "FtcParams",
    "SE3Params",
    "allocation",
    "circle_reference",
    "fit_yaw_damping",
    "fly_se3",
    "ftc_command",
    "hover_reference",
    "relaxed_hover",
    "se3_command",
]
