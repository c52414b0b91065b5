"""The ``quadest`` command line."""
