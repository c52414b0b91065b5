"""The estimator in the loop started as a flying vehicle's is: converged at the vehicle's start
attitude (docs/vehicle.md, *The estimator's start*)."""

from __future__ import annotations

import numpy as np

from quadest.rotation import quat_conj, quat_rotate
from quadest.sim.sensors import SensorModel, mag_rows


def rest_readings(sm: SensorModel, q: np.ndarray, n: int, rate: float, mag_rate: float) -> tuple:
    """``n`` samples at ``rate`` (Hz) of what the flight's sensors ``sm`` read at rest at the
    attitude ``q`` (``q_nb``): their constant parts at the first sample (biases, scale and
    misalignment, soft and hard iron), no noise, no vibration; the magnetometer at ``mag_rate``
    (NaN between its samples, all NaN without one). Returns ``(gyr, acc, mag)``."""
    qc = quat_conj(np.asarray(q, float))
    f = quat_rotate(qc, np.array([0.0, 0.0, -sm.gravity]))
    b = quat_rotate(qc, np.asarray(sm.field_n, float))
    gyr = np.tile(np.asarray(sm.gyr_bias[0], float), (n, 1))
    acc = np.tile(sm.acc_matrix @ f + sm.acc_bias[0], (n, 1))
    mag = np.tile(sm.mag_soft @ b + sm.mag_hard, (n, 1))
    mag[~mag_rows(np.arange(n), rate, mag_rate)] = np.nan
    return gyr, acc, mag


def converge(instance, peer: bool, readings: tuple, rate: float) -> None:
    """Feed an estimator (``instance``; a ``peer`` through its streaming update, else its compiled
    batch run, which continues from its state) ``readings`` ``(gyr, acc, mag)`` ending one sample
    before the flight's first."""
    gyr, acc, mag = readings
    n = len(gyr)
    if n == 0:
        return
    if peer:
        for k in range(n):
            instance.update(gyr[k], acc[k], mag[k], dt=1.0 / rate)
        return
    instance.run(t=(np.arange(n) - n) / rate, gyr=gyr, acc=acc, mag=mag)
