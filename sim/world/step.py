"""The simulation step: its default and the range the physics holds, in one place.

c't-Sim steps every 10 ms, and so does every ctsim run unless told otherwise. Below 0.1 ms a run
of minutes needs more steps than its arrays should hold; above 1 s a robot at full speed crosses a
wall's thickness in one step, which the contacts no longer catch.
"""

from __future__ import annotations

import math

from sim.errors import UserError

DEFAULT_DT = 0.01
"""The step (s) of a run, a world and the command line when none is given: c't-Sim's 10 ms."""
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
