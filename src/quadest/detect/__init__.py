"""Noticing a failure from the vehicle's own sensors: rotor-failure detection and isolation
(docs/detection.md)."""

from quadest.detect.effectiveness import Detection, Detector, DetectorParams, detect_run, detect_step

__all__ = ["Detection", "Detector", "DetectorParams", "detect_run", "detect_step"]
