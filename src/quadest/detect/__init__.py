"""Noticing a failure from the vehicle's own sensors: rotor-failure detection and isolation
(docs/detection.md), and the rate of a clipped gyroscope axis from the same model of the
vehicle (docs/vehicle.md)."""

from quadest.detect.effectiveness import Detection, Detector, DetectorParams, detect_run, detect_step
from quadest.detect.rate import RatePredictor, RatePredictorParams, rate_step

__all__ = [
    "Detection",
    "Detector",
    "DetectorParams",
    "RatePredictor",
    "RatePredictorParams",
    "detect_run",
    "detect_step",
    "rate_step",
]
