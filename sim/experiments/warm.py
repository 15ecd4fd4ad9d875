"""Imported by the local engine's fork server only: one tiny run loads the compiled kernels (numba's
cache) and the built-in sensor curves there once, so that every worker forked from it starts warm."""

from sim.experiments.api import Bot, simulate

simulate("empty", Bot("wander"), duration=0.02)
