"""Imported by a sweep's workers before their first run (`engines.PRELOAD`: a fork server, each
forked worker, a Dask worker): one tiny run loads the compiled kernels (numba's cache) and the
built-in sensor curves once, so that no run of the sweep pays for them."""

from sim.experiments.api import Bot, simulate

simulate("empty", Bot("wander"), duration=0.02)
