"""The version of vidtrack: one number for the package metadata, ``vidtrack --version`` and run records.

It lives in a module of its own that imports nothing, so every layer may read
it without importing the root package (``pyproject.toml`` reads it too).
"""

__version__ = "0.1.0"
