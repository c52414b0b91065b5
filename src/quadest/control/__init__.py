"""Controllers that fly the vehicle model (issue #13, in progress; docs/vehicle.md): the nominal
geometric controller on SE(3) and the closed loop with the true state. Layer 1: uses models."""
from quadest.control.loop import Failure, circle_reference, fly_se3, hover_reference
from quadest.control.se3 import SE3Params, allocation, se3_command

__all__ = ["Failure", "SE3Params", "allocation", "circle_reference", "fly_se3", "hover_reference", "se3_command"]
