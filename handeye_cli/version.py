"""The version of handeye, in one place: the package metadata (``pyproject.toml`` reads it from
here), ``handeye --version``, every result document and report, and the batch cache key."""
__version__ = "0.1.0"
