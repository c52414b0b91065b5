"""Sensor calibration (docs/calibration.md): gyro bias, accelerometer bias/scale/misalignment,
magnetometer hard and soft iron, the AFCKF's centrifugal constants and the recovery paper's
aerodynamic model; one file format, applied before any filter."""

from quadest.calibration.fit import (
    calibrate,
    calibrate_accel,
    calibrate_centrifugal,
    calibrate_gyro,
    calibrate_mag,
    static_segments,
)
from quadest.calibration.model import Calibration, apply_calibrations, load_calibration

__all__ = [
    "Calibration",
    "apply_calibrations",
    "calibrate",
    "calibrate_accel",
    "calibrate_centrifugal",
    "calibrate_gyro",
    "calibrate_mag",
    "load_calibration",
    "static_segments",
]
