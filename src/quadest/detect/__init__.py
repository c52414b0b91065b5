"""Noticing a failure from the vehicle's own sensors: rotor-failure detection and isolation
(docs/detection.md), and the rate of a clipped gyroscope axis from the same model of the
vehicle (docs/vehicle.md). Every entry here checks its inputs (shapes, the model's rotor count,
units: :mod:`quadest.detect.inputs`); the compiled steps that compiled loops call, which check
nothing, are ``effectiveness.detect_step`` and ``rate.rate_step``."""

from quadest.detect.effectiveness import Detection, Detector, DetectorParams, detect_run
from quadest.detect.effectiveness import detect_sample as detect_step
from quadest.detect.rate import RatePredictor, RatePredictorParams
from quadest.detect.rate import rate_sample as rate_step

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
