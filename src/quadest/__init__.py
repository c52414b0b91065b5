"""quadest: quadcopter attitude and state estimation that keeps working when things go wrong.

Every array in quadest follows one convention, stated in :mod:`quadest.conventions`
(and docs/conventions.md): Hamilton quaternions ``[w, x, y, z]`` rotating body vectors
into the navigation frame, navigation frame north-east-down, body frame
forward-right-down, ZYX Euler angles, SI units.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("quadest")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from quadest.data.recording import Recording, load_recording, save_recording


def __getattr__(name: str):
    if name == "NUMBA_CACHE_DIR":  # where compiled code is cached (quadest._jit); None: the user's own
        from quadest import _jit

        return _jit.CACHE_DIR
    raise AttributeError(f"module 'quadest' has no attribute {name!r}")


__all__ = ["Recording", "load_recording", "save_recording", "__version__"]
