"""The simulation step: the range the physics holds and its one check (the default, c't-Sim's 10 ms,
is the core's `sim.kinematics.step.DEFAULT_DT`, shared with a robot's own code). Below 0.1 ms a run
of minutes needs more steps than its arrays should hold; above 1 s a robot at full speed crosses a
wall's thickness in one step, which the contacts no longer catch.
"""

from __future__ import annotations

import math

from sim.errors import UserError
from sim.kinematics.step import DEFAULT_DT

__all__ = ["DEFAULT_DT", "DT_RANGE", "StepError", "check_dt"]

DT_RANGE = (1e-4, 1.0)
"""The steps (s) a run may take, both ends included."""


class StepError(UserError):
    """A step outside DT_RANGE (or not a number)."""


def check_dt(dt: float) -> float:
    """`dt` as given, or StepError naming it and the range: the one check of a step."""
    lo, hi = DT_RANGE
    if isinstance(dt, bool) or not isinstance(dt, int | float) or not (math.isfinite(dt) and lo <= dt <= hi):
        raise StepError(f"the step dt must be between {lo:g} and {hi:g} s, got {dt!r}")
    return dt
