"""The package version (read by setuptools at build time and by ``redundik --version``)."""

__version__ = "0.1.0"
