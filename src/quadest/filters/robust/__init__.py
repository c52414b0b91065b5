"""``robust``, quadest's own attitude estimator: VQF's structure (Laidig & Seel, "VQF: Highly
accurate IMU orientation estimation with bias estimation and magnetic disturbance rejection",
Information Fusion 91, 2023) in quadest's conventions (NED / FRD, ``q_nb``), with what a
quadcopter needs besides: gyro clipping, the lever arm, a spin-aware heading, the
magnetometer's latency, a reported covariance, and an initial averaging that ends at a sustained
acceleration.

``q_nb = Rz(δ) ⊗ q_EI ⊗ q_Ib``: the gyro's strapdown in an almost-inertial frame I, an
inclination correction from the specific force low-passed in I, and a heading offset about down
from the magnetometer. The equations (R1-R8), their derivation and how each default was chosen
are in docs/estimators.md (robust). One module per phase of the step:

- :mod:`~quadest.filters.robust.params`: parameters, the state's layout, coefficients;
- :mod:`~quadest.filters.robust.clipping`: gyro clipping and a clipped axis's rate (item 6, R4-R4c);
- :mod:`~quadest.filters.robust.bias`: the bias filter, rest detection (item 4, R3b);
- :mod:`~quadest.filters.robust.tilt`: strapdown, inclination, lever arm, the initial averaging,
  the bias in motion, the tilt's variance (items 1, 2, 7, 10, 11; R1, R3, R3c, R6, R8);
- :mod:`~quadest.filters.robust.heading`: heading, disturbance, spin, latency (items 3, 5, 8, 9;
  R2, R5, R6, R7);
- :mod:`~quadest.filters.robust.step`: the step joining them, the batch and stream loops, the class;
- :mod:`~quadest.filters.robust.offline`: ``robust-offline``, the forward and the time-reversed
  pass fused (acausal, batch only).
"""

from quadest.filters.robust.clipping import mag_rate_terms
from quadest.filters.robust.offline import RobustOffline
from quadest.filters.robust.params import STATE, UNKNOWN_HEADING_VAR, RobustParams
from quadest.filters.robust.step import Robust, robust_run, robust_step

__all__ = [
    "UNKNOWN_HEADING_VAR",
    "Robust",
    "RobustOffline",
    "RobustParams",
    "STATE",
    "mag_rate_terms",
    "robust_run",
    "robust_step",
]
