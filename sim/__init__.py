"""ctsim: a headless 2D simulator for c't-Bot style differential-drive robots."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("ctsim")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+source"
