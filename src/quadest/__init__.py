"""quadest: quadcopter attitude and state estimation that keeps working when things go wrong.

In three lines (:mod:`quadest.api`)::

    import quadest
    rec = quadest.read("flight.ulg")
    est = quadest.estimate(rec)  # or quadest.estimate(gyr, acc, mag, rate=200.0)

Every array in quadest follows one convention, stated in :mod:`quadest.conventions`
(and docs/conventions.md): Hamilton quaternions ``[w, x, y, z]`` rotating body vectors
into the navigation frame, navigation frame north-east-down, body frame
forward-right-down, ZYX Euler angles, SI units. ``import quadest`` loads no compiler: the
names below that run estimators are loaded when first used.
"""

API = ("read", "estimate", "score")
FILTER_NAMES = ("make_filter", "ESTIMATORS", "FilterResult", "Robust", "Afckf", "Qukf", "Ekf", "Madgwick", "Mahony")
FILTER_NAMES += ("Valenti", "Roetenberg")


RECORDING_NAMES = ("Recording", "save_recording")


def _installed_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("quadest")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "0.0.0+unknown"


def __getattr__(name: str):
    # nothing is imported with the package itself: the command line's first lines (its Ctrl-C
    # guard) run before numpy is loaded
    if name == "__version__":
        globals()["__version__"] = _installed_version()
        return globals()["__version__"]
    if name in RECORDING_NAMES:
        import quadest.data as data

        return getattr(data, name)
    if name in API or name == "load_recording":  # load_recording: read's former name at the top level
        from quadest import api

        return getattr(api, "read" if name == "load_recording" else name)
    if name in FILTER_NAMES:
        from quadest import filters

        return getattr(filters, name)
    if name == "NUMBA_CACHE_DIR":  # where compiled code is cached (quadest._jit); None: nowhere writable
        from quadest import _jit

        return _jit.CACHE_DIR
    raise AttributeError(f"module 'quadest' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), "__version__", *RECORDING_NAMES, *API, *FILTER_NAMES])


__all__ = ["Recording", "save_recording", "__version__", *API, *FILTER_NAMES]
