"""The one compiled extension of quadest (everything else is pyproject.toml): the streaming call
of the estimators in C (src/quadest/filters/_stream.c). Optional: where it cannot be built (no C
compiler) quadest installs without it and streams through Python (docs/developing.md, speed)."""

import numpy
from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "quadest.filters._stream",
            ["src/quadest/filters/_stream.c"],
            include_dirs=[numpy.get_include()],
            optional=True,
        )
    ]
)
