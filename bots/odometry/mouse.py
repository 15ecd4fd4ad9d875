"""The optical mouse's odometry through the inverse model of seed 002."""

from __future__ import annotations

from bots.odometry.base import ArcOdometry
from bots.odometry.steps import MOUSE, mouse_step, sigma_mouse, slide_block, turn_check, watch_slides
from bots.readings import Readings


class MouseOdometry(ArcOdometry):
    """The optical mouse through the inverse model (seed 002 §2.1): alpha = lateral/m_x,
    s = forward + alpha*m_y, at the dpi the robot believes (the nominal one). Covariance: each
    axis's reading has the mouse's count variance per step, and the resolution is unknown by its
    believed size (`bots.uncertainty`). Not modelled: a mouse too fast to track (reads zero).

    The resolution's error is carried by two sigma points (`ArcOdometry`); a slide along a wall,
    which the mouse reads as rotation, by the slide watch (`bots.odometry.steps.watch_slides`,
    which looks at the encoders' ticks only to widen the heading's variance, never to move the
    estimate). Not consistent once slides have turned its heading by more than about a quarter
    turn: no Gaussian then describes where it is (in the maze 3 of 40 runs end 88-138 degrees off
    and lift the mean NEES at the end to 25, docs/odometry.md)."""

    name = "mouse"
    uses_mouse = True
    sigma_count = 2

    def __init__(self) -> None:
        super().__init__()

    def step(self, readings: Readings) -> tuple[float, float]:
        forward, lateral = readings.mouse_counts.tolist()
        left, right = readings.encoder_ticks.tolist()
        sigma_mouse(self.params, self.sigmas, float(forward), float(lateral))
        s, alpha = mouse_step(self.params, float(self.pose[2]), self.errors, float(forward), float(lateral), self.work)
        s_enc, alpha_enc, var = turn_check(self.params, float(left), float(right), s, alpha)
        watch_slides(self.params, slide_block(self.state, MOUSE), self.errors, alpha - alpha_enc, var, alpha_enc, s_enc, float(readings.time))
        return s, alpha
