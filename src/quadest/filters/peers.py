"""The estimators people already use, as :class:`~quadest.filters.base.Estimator` subclasses
in quadest's registry, each run through its own package at its own defaults
(``pip install quadest[peers]``; docs/readers.md, peers).

Every peer takes quadest's samples (NED / FRD, rad/s, m/s², magnetometer in any unit) and
returns ``q_nb`` in quadest's convention, one row per sample. The frame changes were found by
running each library on simulated flights with truth and are pinned by tests:

- ``vqf``, ``vqf-offline`` (Laidig & Seel 2023): inputs in a z-up body frame (FLU), output
  ``q`` of that body in an ENU earth frame;
- ``imufusion`` (Madgwick's Fusion): degrees per second and g; ``AhrsSettings(convention)``
  is ignored by the Python binding, so the convention is set by attribute to NED, which takes
  quadest's FRD samples as they are;
- ``ahrs-madgwick``: behaves as an NWU-frame filter on FRD samples (``q_nwu = Q_F ⊗ q_ned``);
- ``ahrs-mahony``: behaves as an ENU-frame filter on FRD samples (``q_enu = Q_T* ⊗ q_ned``);
- ``ahrs-ekf``: ``frame='NED'`` on FRD gyro and magnetometer samples, but the accelerometer
  negated (it expects the gravity direction, +g down at rest, not the specific force);
- ``ahrs-aqua``: Valenti's filter, returns ``q_bn`` in NWU.

Magnetometer rows without a new sample (NaN) are held from the last sample for the per-sample
Python filters that need one every step (ahrs, imufusion), and given as zero (meaning "none")
to VQF. With the magnetometer the peers reference magnetic north; their heading is turned by
the estimator's ``declination`` so that every estimate references true north.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import TYPE_CHECKING, NoReturn

import numpy as np
from numpy.typing import ArrayLike

from quadest.conventions import GRAVITY
from quadest.errors import UsageError
from quadest.filters.base import Estimator, FilterResult, Params, declination_quat
from quadest.filters.timing import sample_intervals, sample_times
from quadest.records import param
from quadest.rotation import quat_conj, quat_mul
from quadest.rotation.frames import quat_enu_flu_to_ned_frd, vec_frd_to_flu

if TYPE_CHECKING:
    from quadest.data.recording import Recording

Q_F = np.array([0.0, 1.0, 0.0, 0.0])  # NED <-> NWU: half turn about x
Q_T = np.array([0.0, np.sqrt(0.5), np.sqrt(0.5), 0.0])  # ENU <-> NED


@dataclass(frozen=True)
class PeerParams(Params):
    """A peer runs at its own defaults: the only choice is whether it reads the magnetometer."""

    use_mag: bool = param(True, "-", "fuse the magnetometer when the recording has one")


class Peer(Estimator):
    """A peer estimator: subclasses set ``name``, ``package`` and :meth:`_batch` (whole arrays
    in quadest's frames -> ``q_nb`` in the magnetic frame), and for a per-sample API
    ``streaming = True`` and :meth:`_stream` (an object whose ``step(gyr, acc, mag, dt)``
    returns the magnetic-frame ``q_nb``). A peer has no compiled step: the closed loop calls
    its :meth:`update` from Python."""

    peer = True
    streaming = False
    package = ""
    Params = PeerParams

    def __init__(
        self, params: PeerParams | None = None, *, q0: ArrayLike | None = None, declination: float = 0.0, **overrides
    ):
        self.params = self._checked(params, overrides)
        self.declination = declination
        self.reset(q0)

    @classmethod
    def available(cls) -> bool:
        return importlib.util.find_spec(cls.package) is not None

    def _require(self):
        if not self.available():
            raise UsageError(f"peer {self.name} needs the package {self.package!r}: pip install 'quadest[peers]'")

    def reset(self, q0: ArrayLike | None = None) -> None:
        if q0 is not None:
            raise UsageError(f"{self.name} initialises its attitude itself; it takes no q0")
        self._stepper, self._qv = None, np.array([1.0, 0.0, 0.0, 0.0])

    def compiled(self) -> NoReturn:
        raise UsageError(f"{self.name} is a peer: it has no compiled step (the loop calls its update)")

    @property
    def skipped(self) -> int:
        return 0

    @property
    def restarts(self) -> int:
        return 0

    @property
    def mag_skipped(self) -> int:
        return 0

    def get_state(self) -> NoReturn:
        raise UsageError(f"{self.name} is a peer: its state is inside its own package")

    def set_state(self, x: ArrayLike) -> NoReturn:
        self.get_state()

    @property
    def max_gap_s(self) -> float | None:
        return None

    @max_gap_s.setter
    def max_gap_s(self, value):
        if value is not None:
            raise UsageError(f"{self.name} is a peer: it handles gaps as its package does (no max_gap_s)")

    @property
    def diagnostics(self) -> dict:
        return {}

    def _to_geographic(self, q, has_mag: bool) -> np.ndarray:
        return quat_mul(declination_quat(self.declination), q) if self.params.use_mag and has_mag else q

    def update(self, gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None, *, dt: float) -> np.ndarray:
        """One sample (FRD, rad/s, m/s², the magnetometer None or NaN for "no new sample"):
        the attitude ``q_nb``. Only for peers with a per-sample API (``streaming``)."""
        if not self.streaming:
            raise UsageError(f"peer {self.name} has no per-sample API here; use run() over a recording")
        if self._stepper is None:
            self._require()
            self._stepper = self._stream(float(dt))
        mag = np.full(3, np.nan) if mag is None else np.asarray(mag, float)
        q = self._stepper.step(np.asarray(gyr, float), np.asarray(acc, float), mag, float(dt))
        self._qv = self._to_geographic(np.asarray(q, float), self.params.use_mag)
        return self._qv.copy()

    def run(
        self,
        rec: Recording | None = None,
        *,
        t: ArrayLike | None = None,
        gyr: ArrayLike | None = None,
        acc: ArrayLike | None = None,
        mag: ArrayLike | None = None,
        rate: float | None = None,
    ) -> FilterResult:
        """The peer over a whole recording (or arrays timed by ``t`` or ``rate``), from its own start."""
        if rec is not None:
            t, gyr, acc, mag = rec.t, rec.gyr, rec.acc, rec.mag
        t = sample_times(t, rate, gyr, self.name)
        gyr, acc = np.asarray(gyr, float), np.asarray(acc, float)
        mag = np.full((len(t), 3), np.nan) if mag is None else np.asarray(mag, float)
        mag = np.where(np.isfinite(mag).all(axis=1, keepdims=True), mag, np.nan)  # a bad row: no sample
        self._require()
        # the other packages take no unusable sample (vqf aborts the process on a zero interval):
        # they run on the usable rows, the attitude is held over the others, which are counted
        dt = sample_intervals(t)
        good = np.isfinite(dt) & (dt > 0) & np.isfinite(gyr).all(axis=1) & np.isfinite(acc).all(axis=1)
        q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
        if good.sum() >= 2:
            q[good] = self._usable_rows(t[good], gyr[good], acc[good], mag[good])
        held = np.maximum.accumulate(np.where(good, np.arange(len(t)), 0))
        return FilterResult(self.name, t, q[held], {}, self.params, skipped=int((~good).sum()))

    def _usable_rows(self, t, gyr, acc, mag) -> np.ndarray:
        """The peer's attitude on rows that are all usable (strictly increasing finite times)."""
        dt = sample_intervals(t)
        has_mag = bool(np.isfinite(mag[:, 0]).any())
        use = mag if self.params.use_mag and has_mag else None
        q = np.asarray(self._batch(dt, float(np.median(np.diff(t))), gyr, acc, use), float)
        return self._to_geographic(q, has_mag)


def held_mag(mag):
    """Magnetometer with NaN rows filled by the last sample (and the first one backwards)."""
    if mag is None:
        return None
    ok = np.isfinite(mag[:, 0])
    if not ok.any():
        return None
    idx = np.where(ok, np.arange(len(mag)), 0)
    np.maximum.accumulate(idx, out=idx)
    idx[: np.argmax(ok)] = np.argmax(ok)
    return mag[idx]


# -- VQF ----------------------------------------------------------------------------------------
def _flu(v):
    return np.ascontiguousarray(vec_frd_to_flu(v))


class Vqf(Peer):
    """VQF (Laidig & Seel 2023), the online filter."""

    name, package, streaming = "vqf", "vqf", True

    def _batch(self, dt, nominal, gyr, acc, mag):
        from vqf import VQF

        f = VQF(nominal)
        if mag is not None:
            return quat_enu_flu_to_ned_frd(f.updateBatch(_flu(gyr), _flu(acc), _flu(np.nan_to_num(mag)))["quat9D"])
        return quat_enu_flu_to_ned_frd(f.updateBatch(_flu(gyr), _flu(acc))["quat6D"])

    def _stream(self, dt):
        return _VqfStream(dt, self.params.use_mag)


class VqfOffline(Peer):
    """VQF's offline form (forward and backward over the whole recording)."""

    name, package, acausal = "vqf-offline", "vqf", True

    def _batch(self, dt, nominal, gyr, acc, mag):
        from vqf import offlineVQF

        # unlike VQF's online update, its offline form does not take a zero vector as "no sample":
        # a magnetometer slower than the IMU is held between its samples (heading 91° off otherwise)
        m = None if mag is None else _flu(held_mag(mag))
        out = offlineVQF(_flu(gyr), _flu(acc), m, nominal)
        return quat_enu_flu_to_ned_frd(out["quat9D"] if m is not None else out["quat6D"])


class _VqfStream:
    def __init__(self, dt, use_mag):
        from vqf import VQF

        self.f, self.use_mag = VQF(dt), use_mag

    def step(self, gyr, acc, mag, dt):
        if self.use_mag and np.isfinite(mag).all():
            self.f.update(_flu(gyr), _flu(acc), _flu(mag))
        else:
            self.f.update(_flu(gyr), _flu(acc))
        return quat_enu_flu_to_ned_frd(self.f.getQuat9D() if self.use_mag else self.f.getQuat6D())


# -- imufusion ----------------------------------------------------------------------------------
class Imufusion(Peer):
    """Madgwick's Fusion AHRS (``imufusion``)."""

    name, package, streaming = "imufusion", "imufusion", True

    def _batch(self, dt, nominal, gyr, acc, mag):
        stream = _FusionStream(nominal, mag is not None)
        mag = held_mag(mag)
        dt = np.where(np.isfinite(dt) & (dt > 0), dt, nominal)
        nan3 = np.full(3, np.nan)
        return np.array([stream.step(gyr[k], acc[k], nan3 if mag is None else mag[k], dt[k]) for k in range(len(dt))])

    def _stream(self, dt):
        return _FusionStream(dt, self.params.use_mag)


class _FusionStream:
    def __init__(self, dt, use_mag):
        import imufusion

        settings = imufusion.AhrsSettings()
        settings.convention = imufusion.CONVENTION_NED  # the constructor argument is ignored
        settings.sample_rate = 1.0 / dt
        self.ahrs, self.use_mag, self.mag = imufusion.Ahrs(), use_mag, None
        self.ahrs.set_settings(settings)

    def step(self, gyr, acc, mag, dt):
        self.ahrs.set_sample_period(dt)
        if self.use_mag and np.isfinite(mag).all():
            self.mag = np.array(mag, float)  # held between magnetometer samples
        if self.mag is not None:
            self.ahrs.update(np.degrees(gyr), acc / GRAVITY, self.mag)
        else:
            self.ahrs.update_no_magnetometer(np.degrees(gyr), acc / GRAVITY)
        return np.asarray(self.ahrs.get_quaternion(), float)


# -- ahrs ---------------------------------------------------------------------------------------
# The batch form (arrays in the constructor) is used: it is how ahrs is meant to run over a
# recording, and it initialises from the first samples (acc2q / ecompass) as the library does.
class AhrsMadgwick(Peer):
    name, package = "ahrs-madgwick", "ahrs"

    def _batch(self, dt, nominal, gyr, acc, mag):
        from ahrs.filters import Madgwick

        q = Madgwick(gyr=gyr, acc=acc, mag=held_mag(mag), frequency=1.0 / nominal).Q
        return quat_mul(Q_F, q)  # NWU -> NED (Q_F is its own inverse up to sign)


class AhrsMahony(Peer):
    name, package = "ahrs-mahony", "ahrs"

    def _batch(self, dt, nominal, gyr, acc, mag):
        from ahrs.filters import Mahony

        return quat_mul(Q_T, Mahony(gyr=gyr, acc=acc, mag=held_mag(mag), frequency=1.0 / nominal).Q)  # ENU -> NED


class AhrsEkf(Peer):
    name, package = "ahrs-ekf", "ahrs"

    def _batch(self, dt, nominal, gyr, acc, mag):
        from ahrs.filters import EKF

        # with frame='NED' ahrs's EKF takes the accelerometer as the gravity direction (+g down at
        # rest), i.e. the negated specific force; found on simulated flights, pinned by a test
        return EKF(gyr=gyr, acc=-acc, mag=held_mag(mag), frequency=1.0 / nominal, frame="NED").Q


class AhrsAqua(Peer):
    name, package = "ahrs-aqua", "ahrs"

    def _batch(self, dt, nominal, gyr, acc, mag):
        from ahrs.filters import AQUA

        q = AQUA(gyr=gyr, acc=acc, mag=held_mag(mag), frequency=1.0 / nominal).Q
        return quat_mul(Q_F, quat_conj(q))  # q_bn in NWU -> q_nb in NED


PEER_CLASSES = (Vqf, VqfOffline, Imufusion, AhrsMadgwick, AhrsMahony, AhrsEkf, AhrsAqua)
