"""The optical mouse's odometry through the inverse model of seed 002."""

from __future__ import annotations

from bots.odometry.base import ArcOdometry
from bots.odometry.steps import mouse_step
from bots.readings import Readings


class MouseOdometry(ArcOdometry):
    """The optical mouse through the inverse model (seed 002 §2.1): alpha = lateral/m_x,
    s = forward + alpha*m_y, at the dpi the robot believes (the nominal one). Covariance: each
    axis's reading has the mouse's count variance per step, and the resolution is unknown by its
    believed size (`bots.uncertainty`). Not modelled: a mouse too fast to track (reads zero).

    Not consistent where the resolution's belief turns into large heading errors: 3.75 % of a
    full turn is 13.5 degrees, and the position error then bends away from the direction the
    first-order covariance gives it (over-confident across the track; tests/test_uncertainty.py's
    Monte Carlo with systematic errors drawn, docs/odometry.md)."""

    name = "mouse"
    uses_mouse = True

    def __init__(self) -> None:
        super().__init__()

    def step(self, readings: Readings) -> tuple[float, float]:
        forward, lateral = readings.mouse_counts.tolist()
        return mouse_step(self.params, float(self.pose[2]), self.errors, float(forward), float(lateral), self.work)
