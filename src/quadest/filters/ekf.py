"""The QUKF paper's EKF baseline: the same process and measurement model, linearised.

Liang et al. 2023 compare their QUKF with an EKF using "the same noise covariance matrix S and
R". The process ``X_t = (I + T/2 Ω(ω)) X_{t−1}`` is linear in the state and the measurement
``H = I`` too, so the linearisation is exact: ``Φ = I + T/2 Ω(ω)``, ``P⁻ = Φ P Φᵀ + S``,
``K = P⁻ (P⁻ + R)⁻¹``, ``X = X⁻ + K (Z − X⁻)``, ``P = (I − K) P⁻``, then renormalisation. S, R
and their scaling with the sampling interval are those of :mod:`quadest.filters.qukf`.

Because the model is linear, the unscented transform of the QUKF reproduces these means and
covariances exactly; the two filters differ only through the renormalisation and rounding. The
paper reports the QUKF 0.2° more accurate than the EKF; on the simulator they come out equal
(docs/estimators.md).
"""

from dataclasses import dataclass

import numpy as np

from quadest._jit import njit
from quadest.filters.base import Estimator, params_record
from quadest.filters.common import admit, admitted_mag, finite3, omega_matrix, prepare, publish, run_and_stream
from quadest.filters.linalg import inv_spd, mm, mm_t, mv
from quadest.filters.quatmeas import measurement_quaternion
from quadest.filters.qukf import PB, STATE, QukfParams, coefficients, noise
from quadest.rotation.kernels import FASTMATH


@dataclass(frozen=True)
class EkfParams(QukfParams):
    """The QUKF's parameters; λ, α and β are unused."""


PARAM = Record = params_record(EkfParams)


@njit(cache=True, fastmath=FASTMATH)
def ekf_step(x, p, c, gyr, acc, mag, dt, diag):
    if not admit(x, gyr, acc, mag, dt):  # skipped and counted; the state stays as it was
        return
    mag = admitted_mag(x)  # NaN where its value was unusable (counted): the rest is used
    use_mag = p[PARAM.use_mag] != 0.0
    diag[0] = 0.0
    if not prepare(x, acc, mag, use_mag):
        return
    Q, R = noise(p, c, dt)
    P = x[PB : PB + 16].copy().reshape((4, 4))
    F = omega_matrix(gyr, dt) if finite3(gyr) else np.eye(4)
    X = mv(F, x[0:4])
    P = mm_t(mm(F, P), F) + np.eye(4) * Q
    z, ok = measurement_quaternion(acc, mag, X, use_mag)
    if ok:
        K = mm(P, inv_spd(P + np.eye(4) * R))
        X = X + mv(K, z - X)
        IK = np.eye(4) - K
        # Joseph form: keeps P symmetric positive definite
        P = mm_t(mm(IK, P), IK) + mm_t(K, K) * R
        diag[0] = 1.0
    x[0:4] = X / np.sqrt(np.sum(X * X))
    x[PB : PB + 16] = (0.5 * (P + P.T)).ravel()
    diag[1] = np.trace(P)
    publish(x)


ekf_run, ekf_stream = run_and_stream(ekf_step, fastmath=FASTMATH)


class Ekf(Estimator):
    """The QUKF paper's EKF. Diagnostics: ``updated`` and ``trace_p``."""

    name = "ekf"
    Params = EkfParams
    Record = Record
    coefficients = staticmethod(coefficients)
    state_size = STATE.end
    diag_names = ("updated", "trace_p")
    step = staticmethod(ekf_step)
    batch = staticmethod(ekf_run)
    stream = staticmethod(ekf_stream)

    def _init_state(self, x):
        x[PB : PB + 16] = (np.eye(4) * self.params.p0).ravel()
