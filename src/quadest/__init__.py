"""quadest: quadcopter attitude and state estimation that keeps working when things go wrong.

Every array in quadest follows one convention, stated in :mod:`quadest.conventions`
(and docs/conventions.md): Hamilton quaternions ``[w, x, y, z]`` rotating body vectors
into the navigation frame, navigation frame north-east-down, body frame
forward-right-down, ZYX Euler angles, SI units.
"""
from importlib.metadata import PackageNotFoundError, version as _version

from quadest import _cache

NUMBA_CACHE_DIR = _cache.configure()
"""Where compiled code is cached: a folder per hash of quadest's source (:mod:`quadest._cache`),
or None when ``NUMBA_CACHE_DIR`` was set by the user."""

try:
    __version__ = _version("quadest")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from quadest.data.recording import Recording, load_recording, save_recording  # noqa: E402

__all__ = ["Recording", "load_recording", "save_recording", "__version__"]
