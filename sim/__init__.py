"""ctsim: a headless 2D simulator for c't-Bot style differential-drive robots."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("ctsim")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+source"

from sim.kernel_cache import keep_true  # noqa: E402 (after the version, which it does not need)

keep_true()  # (before any kernel of sim or bots loads from numba's cache: sim/kernel_cache.py)
