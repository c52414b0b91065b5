"""The estimators people already use, run on quadest's recordings with each one's own defaults
(``pip install quadest[peers]``; docs/readers.md, peers).

Every adapter takes a :class:`~quadest.data.Recording` (NED / FRD, rad/s, m/s², magnetometer in
any unit) and returns ``q_nb`` in quadest's convention, one row per sample. The frame changes
were found by running each library on simulated flights with truth and are pinned by tests:

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
Python filters that need one every step (ahrs), and given as zero (meaning "none") to VQF.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from quadest.conventions import GRAVITY
from quadest.rotation import quat_conj, quat_mul
from quadest.rotation.frames import quat_enu_flu_to_ned_frd, vec_frd_to_flu

Q_F = np.array([0.0, 1.0, 0.0, 0.0])  # NED <-> NWU: half turn about x
_S = np.sqrt(0.5)
Q_T = np.array([0.0, _S, _S, 0.0])  # ENU <-> NED

PEERS = ("vqf", "vqf-offline", "imufusion", "ahrs-madgwick", "ahrs-mahony", "ahrs-ekf", "ahrs-aqua")
PACKAGE = {
    "vqf": "vqf",
    "vqf-offline": "vqf",
    "imufusion": "imufusion",
    "ahrs-madgwick": "ahrs",
    "ahrs-mahony": "ahrs",
    "ahrs-ekf": "ahrs",
    "ahrs-aqua": "ahrs",
}


def available_peers() -> list[str]:
    """The peers whose package is installed."""
    return [p for p in PEERS if importlib.util.find_spec(PACKAGE[p]) is not None]


def _held_mag(rec):
    """Magnetometer with NaN rows filled by the last sample (and the first one backwards)."""
    m = rec.mag.copy()
    ok = np.isfinite(m[:, 0])
    if not ok.any():
        return None
    idx = np.where(ok, np.arange(len(m)), 0)
    np.maximum.accumulate(idx, out=idx)
    idx[: np.argmax(ok)] = np.argmax(ok)
    return m[idx]


def _dt(rec):
    return float(np.median(np.diff(rec.t))) if len(rec) > 1 else 0.01


# -- VQF ----------------------------------------------------------------------------------------
def _vqf_inputs(rec, use_mag):
    gyr = np.ascontiguousarray(vec_frd_to_flu(rec.gyr))
    acc = np.ascontiguousarray(vec_frd_to_flu(rec.acc))
    mag = None
    if use_mag and rec.has_mag:
        m = vec_frd_to_flu(np.nan_to_num(rec.mag, nan=0.0))
        mag = np.ascontiguousarray(m)
    return gyr, acc, mag


def _vqf_to_ned(q):
    """VQF's quaternion (FLU body in its ENU earth frame) -> quadest's q_nb."""
    return quat_enu_flu_to_ned_frd(q)


def run_vqf(rec, use_mag: bool = True):
    from vqf import VQF

    gyr, acc, mag = _vqf_inputs(rec, use_mag)
    f = VQF(_dt(rec))
    if mag is not None:
        out = f.updateBatch(gyr, acc, mag)
        return _vqf_to_ned(out["quat9D"])
    return _vqf_to_ned(f.updateBatch(gyr, acc)["quat6D"])


def run_vqf_offline(rec, use_mag: bool = True):
    from vqf import offlineVQF

    gyr, acc, mag = _vqf_inputs(rec, use_mag)
    out = offlineVQF(gyr, acc, mag, _dt(rec))
    return _vqf_to_ned(out["quat9D"] if mag is not None else out["quat6D"])


# -- imufusion ----------------------------------------------------------------------------------------
def run_imufusion(rec, use_mag: bool = True):
    import imufusion

    settings = imufusion.AhrsSettings()
    settings.convention = imufusion.CONVENTION_NED  # the constructor argument is ignored
    settings.sample_rate = 1.0 / _dt(rec)
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(settings)
    gyr = np.degrees(rec.gyr)
    acc = rec.acc / GRAVITY
    mag = _held_mag(rec) if use_mag else None
    dt = np.diff(rec.t, prepend=rec.t[0] - _dt(rec))
    out = np.empty((len(rec), 4))
    for k in range(len(rec)):
        ahrs.set_sample_period(dt[k])
        if mag is not None:
            ahrs.update(gyr[k], acc[k], mag[k])
        else:
            ahrs.update_no_magnetometer(gyr[k], acc[k])
        out[k] = ahrs.get_quaternion()
    return out


# -- ahrs --------------------------------------------------------------------------------------------
# The batch form (arrays in the constructor) is used: it is how ahrs is meant to run over a
# recording, and it initialises from the first samples (acc2q / ecompass) as the library does.
def run_ahrs_madgwick(rec, use_mag: bool = True):
    from ahrs.filters import Madgwick

    mag = _held_mag(rec) if use_mag else None
    q = Madgwick(gyr=rec.gyr, acc=rec.acc, mag=mag, frequency=1.0 / _dt(rec)).Q
    return quat_mul(Q_F, q)  # NWU -> NED (Q_F is its own inverse up to sign)


def run_ahrs_mahony(rec, use_mag: bool = True):
    from ahrs.filters import Mahony

    mag = _held_mag(rec) if use_mag else None
    q = Mahony(gyr=rec.gyr, acc=rec.acc, mag=mag, frequency=1.0 / _dt(rec)).Q
    return quat_mul(Q_T, q)  # ENU -> NED


def run_ahrs_ekf(rec, use_mag: bool = True):
    from ahrs.filters import EKF

    mag = _held_mag(rec) if use_mag else None
    # with frame='NED' ahrs's EKF takes the accelerometer as the gravity direction (+g down at
    # rest), i.e. the negated specific force; found on simulated flights, pinned by a test
    return EKF(gyr=rec.gyr, acc=-rec.acc, mag=mag, frequency=1.0 / _dt(rec), frame="NED").Q


def run_ahrs_aqua(rec, use_mag: bool = True):
    from ahrs.filters import AQUA

    mag = _held_mag(rec) if use_mag else None
    q = AQUA(gyr=rec.gyr, acc=rec.acc, mag=mag, frequency=1.0 / _dt(rec)).Q
    return quat_mul(Q_F, quat_conj(q))  # q_bn in NWU -> q_nb in NED


RUNNERS = {
    "vqf": run_vqf,
    "vqf-offline": run_vqf_offline,
    "imufusion": run_imufusion,
    "ahrs-madgwick": run_ahrs_madgwick,
    "ahrs-mahony": run_ahrs_mahony,
    "ahrs-ekf": run_ahrs_ekf,
    "ahrs-aqua": run_ahrs_aqua,
}


# -- streaming: one sample at a time, for the closed loop --------------------------------------------
STREAMING_PEERS = ("vqf", "imufusion")
"""The peers with a per-sample API (``quadest fly --estimator vqf``)."""


class _VqfStream:
    def __init__(self, dt, use_mag):
        from vqf import VQF

        self.f, self.use_mag = VQF(dt), use_mag

    def step(self, gyr, acc, mag):
        g, a = np.ascontiguousarray(vec_frd_to_flu(gyr)), np.ascontiguousarray(vec_frd_to_flu(acc))
        if self.use_mag and np.isfinite(mag).all():
            self.f.update(g, a, np.ascontiguousarray(vec_frd_to_flu(mag)))
        else:
            self.f.update(g, a)
        return _vqf_to_ned(self.f.getQuat9D() if self.use_mag else self.f.getQuat6D())


class _FusionStream:
    def __init__(self, dt, use_mag):
        import imufusion

        settings = imufusion.AhrsSettings()
        settings.convention = imufusion.CONVENTION_NED  # the constructor argument is ignored
        settings.sample_rate = 1.0 / dt
        self.ahrs, self.dt, self.use_mag, self.mag = imufusion.Ahrs(), dt, use_mag, None
        self.ahrs.set_settings(settings)
        self.ahrs.set_sample_period(dt)

    def step(self, gyr, acc, mag):
        if self.use_mag and np.isfinite(mag).all():
            self.mag = np.array(mag, float)  # held between magnetometer samples, as run_imufusion does
        if self.mag is not None:
            self.ahrs.update(np.degrees(gyr), acc / GRAVITY, self.mag)
        else:
            self.ahrs.update_no_magnetometer(np.degrees(gyr), acc / GRAVITY)
        return np.asarray(self.ahrs.get_quaternion(), float)


class PeerStream:
    """A peer fed one sample at a time (FRD, rad/s, m/s², a NaN magnetometer row for "no new
    sample"), returning quadest's geographic ``q_nb`` (turned by ``declination`` when the
    magnetometer is used), with the same frame changes as the batch adapters."""

    def __init__(self, name: str, dt: float, declination: float = 0.0, use_mag: bool = True):
        if name not in STREAMING_PEERS:
            raise ValueError(f"peer {name!r} has no per-sample API here; streaming peers: {', '.join(STREAMING_PEERS)}")
        try:
            self._s = (_VqfStream if name == "vqf" else _FusionStream)(float(dt), use_mag)
        except ImportError:
            raise ValueError(f"peer {name} needs the package {PACKAGE[name]!r}: pip install 'quadest[peers]'") from None
        self.name = name
        d = declination if use_mag else 0.0
        self._dq = np.array([np.cos(d / 2), 0.0, 0.0, np.sin(d / 2)])

    def update(self, gyr, acc, mag) -> np.ndarray:
        return quat_mul(self._dq, self._s.step(np.asarray(gyr, float), np.asarray(acc, float), np.asarray(mag, float)))


def stream_peer(name: str, dt: float, declination: float = 0.0, use_mag: bool = True) -> PeerStream:
    return PeerStream(name, dt, declination, use_mag)


def run_peer(name: str, rec, use_mag: bool = True, declination: float | None = None) -> np.ndarray:
    """``q_nb`` of peer ``name`` on ``rec``. With the magnetometer, the peers reference magnetic
    north; the heading is turned by the declination (default: the recording's, as for quadest's
    own filters) so that all estimates reference true north."""
    if name not in RUNNERS:
        raise ValueError(f"unknown peer {name!r}; peers: {', '.join(PEERS)}")
    try:
        q = np.asarray(RUNNERS[name](rec, use_mag), float)
        if use_mag and rec.has_mag:
            d = rec.declination if declination is None else declination
            q = quat_mul(np.array([np.cos(d / 2), 0.0, 0.0, np.sin(d / 2)]), q)
        return q
    except ImportError:
        raise ValueError(f"peer {name} needs the package {PACKAGE[name]!r}: pip install 'quadest[peers]'") from None
