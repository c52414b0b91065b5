"""Sphinx configuration of quadest's API reference (``make api``: built with warnings as errors)."""

project = "quadest"
author = "the quadest developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
default_role = "code"  # ``x`` and `x` both read as code: quadest's docstrings write math inline
exclude_patterns = ["_build"]
html_theme = "alabaster"
nitpicky = False
