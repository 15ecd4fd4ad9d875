"""Drawing robots on a general chassis: outline, each wheel (its rolling direction and steering) and the
ICR of the body's motion when it lies in view. One geometry function for the recording and the window.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

WHEEL_COLOUR = (40, 40, 40)
ICR_COLOUR = (230, 60, 200)
OUTLINE_COLOUR = (90, 160, 255)
EVERY = 5
"""The recording draws the chassis every EVERY-th sample (per-sample logs are slow; 50 ms at 10 ms steps)."""


@dataclass(frozen=True)
class ChassisShapes:
    """World-frame drawing of one robot: outline (k, 2) closed, wheels (n, 2, 2) segments along each
    wheel's rolling direction (length 2 r), icr (2,) or None when at infinity or out of `view`."""

    outline: np.ndarray
    wheels: np.ndarray
    icr: np.ndarray | None


def chassis_shapes(spec: Any, pose: np.ndarray, steering: np.ndarray, previous: np.ndarray,
                   view: tuple[float, float, float, float]) -> ChassisShapes:
    """Shapes of a chassis robot (`RobotSpec` with `chassis`) at `pose` with wheel-plane angles `steering`;
    the ICR of its last step from the `previous` pose, kept if inside `view` (bounds)."""
    from sim.kinematics import relative_increment

    c = spec.chassis.chassis
    cos, sin = np.cos(pose[2]), np.sin(pose[2])
    rot = np.array([[cos, -sin], [sin, cos]])
    if spec.chassis.outline:
        body = np.asarray(spec.chassis.outline)
    else:
        a = np.linspace(0, 2 * np.pi, 33)
        body = spec.body_radius * np.stack([np.cos(a), np.sin(a)], axis=1)
    outline = np.vstack([body, body[:1]]) @ rot.T + pose[:2]
    beta = steering if len(steering) == c.n else c.beta
    heading = c.alpha + beta - np.pi / 2
    half = c.radius[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    centre = c.positions
    wheels = np.stack([centre - half, centre + half], axis=1) @ rot.T + pose[:2]
    icr = None
    increment = relative_increment(previous, pose)
    if abs(increment[2]) > 1e-12:
        # the fixed point c of the rigid step: (I − R(dθ)) c = d, c = ½(d_x − d_y cot h, d_y + d_x cot h)
        h = 0.5 * increment[2]
        local = 0.5 * np.array([increment[0] - increment[1] / np.tan(h), increment[1] + increment[0] / np.tan(h)])
        c0, s0 = np.cos(previous[2]), np.sin(previous[2])
        point = np.array([c0 * local[0] - s0 * local[1], s0 * local[0] + c0 * local[1]]) + previous[:2]
        xmin, ymin, xmax, ymax = view
        if xmin <= point[0] <= xmax and ymin <= point[1] <= ymax:
            icr = point
    return ChassisShapes(outline, wheels, icr)


class ChassisLayer:
    """Recording of the chassis robots of a run (called by `sim.views.recording.Recorder`)."""

    def __init__(self, rec: Any, robots: list[int], timeline: str):
        self.rec, self.robots, self.timeline, self.samples = rec, robots, timeline, 0
        self.previous: dict[int, np.ndarray] = {}

    @classmethod
    def for_world(cls, rec: Any, world: Any, timeline: str) -> ChassisLayer | None:
        """A layer for the world's chassis robots, None if it has none."""
        robots = [r.index for r in world.robots if r.spec.chassis is not None]
        return cls(rec, robots, timeline) if robots else None

    def on_sample(self, world: Any, logs: list) -> None:
        """Draw every EVERY-th sample: outline, wheels, ICR of the last step."""
        import rerun as rr

        self.samples += 1
        for i in self.robots:
            pose = logs[i].truth_array()[-1]
            previous = self.previous.get(i, pose)
            self.previous[i] = pose
            if (self.samples - 1) % EVERY:
                continue
            shapes = chassis_shapes(logs[i].spec, pose, logs[i].latest.steering, previous, world.spec.bounds)
            self.rec.set_time(self.timeline, duration=world.time)
            base = f"world/{logs[i].name}/chassis"
            self.rec.log(f"{base}/outline", rr.LineStrips2D([shapes.outline], radii=0.004, colors=OUTLINE_COLOUR))
            self.rec.log(f"{base}/wheels", rr.LineStrips2D(list(shapes.wheels), radii=0.012, colors=WHEEL_COLOUR))
            points = [] if shapes.icr is None else [shapes.icr]
            self.rec.log(f"{base}/icr", rr.Points2D(points, radii=0.03, colors=ICR_COLOUR))
