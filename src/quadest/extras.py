"""quadest's optional dependencies: the extra that brings each one, and one line that says which
to install when a command or function needs a package that is not there (docs/developing.md)."""

from __future__ import annotations

import importlib

EXTRAS = {
    "pyulog": "logs",
    "pymavlink": "logs",
    "rosbags": "logs",
    "h5py": "logs",
    "matplotlib": "plot",
    "bokeh": "report",
    "dask": "cluster",
    "distributed": "cluster",
    "pooch": "data",
    "vqf": "peers",
    "imufusion": "peers",
    "ahrs": "peers",
    "rotorpy": "crosscheck",
    "pandas": "pandas",
}
"""Package (as imported) → the extra of quadest that installs it (``pip install 'quadest[logs]'``)."""


class MissingExtra(ImportError):
    """A package from one of quadest's extras is not installed; the message says which extra."""


def install_hint(package: str) -> str:
    """``pip install 'quadest[EXTRA]'`` for the extra that brings ``package`` (from a clone,
    ``pip install '.[EXTRA]'``)."""
    extra = EXTRAS[package.split(".")[0]]
    return f"pip install 'quadest[{extra}]' (from a clone: pip install '.[{extra}]')"


def need(module: str, purpose: str):
    """Import ``module`` (``"pyulog"``, ``"bokeh.plotting"``) or raise :class:`MissingExtra` with
    one line: ``purpose`` needs the package, and the extra that installs it. An import error from
    inside an installed package (a broken install) is passed on unchanged."""
    top = module.split(".")[0]
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if exc.name is None or exc.name.split(".")[0] != top:
            raise
        extra = EXTRAS[top]
        raise MissingExtra(f"{purpose} needs {top}, in quadest's [{extra}] extra: {install_hint(top)}") from None
