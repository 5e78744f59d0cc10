"""The installed package's version (part of every cache key: a new version prepares anew)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("musclewrap")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

__all__ = ["__version__"]
