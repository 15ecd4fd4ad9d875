"""Drawing robots on a general chassis: outline, each wheel (its rolling direction and steering) and the
ICR of the body's motion when it lies in view. One geometry for the recording and the window.

The recording draws the outline and the wheels in the body frame, under the entity that carries the
true pose: they cannot lag behind the robot, and the wheels are logged only when a steering angle
changes. The ICR is a point of the world, logged in the world frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.kinematics import relative_increment, wrap_angle
from sim.views import palette

EVERY = 5
"""The recording draws wheels and ICR every EVERY-th sample (50 ms at 10 ms steps): per-sample logs
would cost more than the simulation."""
WHEEL_RADIUS_M = 0.012
"""Half the drawn thickness of a wheel (m)."""


@dataclass(frozen=True)
class ChassisShapes:
    """World-frame drawing of one robot: outline (k, 2) closed, wheels (n, 2, 2) segments along each
    wheel's rolling direction (length 2 r, from back to front), icr (2,) or None when at infinity or
    out of `view`."""

    outline: np.ndarray
    wheels: np.ndarray
    icr: np.ndarray | None


def body_outline(spec: Any) -> np.ndarray:
    """A robot's outline in its body frame, closed (k + 1, 2): the chassis's polygon, else a circle of
    `body_radius`."""
    if spec.chassis is not None and spec.chassis.outline:
        body = np.asarray(spec.chassis.outline, dtype=float)
    else:
        a = np.linspace(0, 2 * np.pi, 37)[:-1]
        body = spec.body_radius * np.stack([np.cos(a), np.sin(a)], axis=1)
    return np.vstack([body, body[:1]])


def wheel_segments(chassis: Any, steering: np.ndarray) -> np.ndarray:
    """Body-frame segments (n, 2, 2) of the wheels with wheel-plane angles `steering` (rad), each from
    the back of the wheel to its front (the way it rolls at positive speed); the nominal angles when
    `steering` does not give one per wheel."""
    beta = steering if len(steering) == chassis.n else chassis.beta
    heading = chassis.alpha + beta - np.pi / 2
    half = chassis.radius[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    return np.stack([chassis.positions - half, chassis.positions + half], axis=1)


def steering_deflection(chassis: Any, steering: np.ndarray) -> np.ndarray:
    """How far each wheel is steered from straight (rad, counter-clockwise): its wheel-plane angle β
    from the readings against the chassis's nominal β, which for the car's right wheels is π."""
    return wrap_angle(np.asarray(steering) - chassis.beta)


def fault_text(chassis: Any, failure: Any) -> str:
    """A wheel fault (`sim.kinematics.chassis.Failure`) in words, naming the wheel."""
    name = chassis.names[failure.wheel]
    if failure.locked:
        return f"{name} locked"
    if failure.steering:
        return f"{name}: steering frozen" + (f" at {np.degrees(failure.frozen_beta):.0f}°" if failure.frozen_beta is not None else "")
    return f"{name} rolls free (drive lost)"


def step_icr(previous: np.ndarray, pose: np.ndarray) -> np.ndarray | None:
    """The world point (2,) that the rigid step from `previous` to `pose` turns about; None for a step
    without rotation (ICR at infinity)."""
    increment = relative_increment(previous, pose)
    if abs(increment[2]) <= 1e-12:
        return None
    # the fixed point c of the rigid step: (I − R(dθ)) c = d, c = ½(d_x − d_y cot h, d_y + d_x cot h)
    cot = 1.0 / np.tan(0.5 * increment[2])
    local = 0.5 * np.array([increment[0] - increment[1] * cot, increment[1] + increment[0] * cot])
    return to_world(previous, local[None])[0]


def in_view(point: np.ndarray | None, view: tuple[float, float, float, float]) -> np.ndarray | None:
    """`point` if it lies inside `view` (xmin, ymin, xmax, ymax), else None."""
    if point is None:
        return None
    xmin, ymin, xmax, ymax = view
    return point if xmin <= point[0] <= xmax and ymin <= point[1] <= ymax else None


def chassis_shapes(spec: Any, pose: np.ndarray, steering: np.ndarray, previous: np.ndarray,
                   view: tuple[float, float, float, float]) -> ChassisShapes:
    """World-frame shapes of a chassis robot (`RobotSpec` with `chassis`) at `pose` with wheel-plane
    angles `steering`; the ICR of its last step from the `previous` pose, kept if inside `view`."""
    wheels = wheel_segments(spec.chassis.chassis, steering)
    return ChassisShapes(to_world(pose, body_outline(spec)), to_world(pose, wheels.reshape(-1, 2)).reshape(wheels.shape),
                         in_view(step_icr(previous, pose), view))


def to_world(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Body-frame points (k, 2) of a robot at `pose` in the world frame."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return points @ np.array([[c, s], [-s, c]]) + pose[:2]


class ChassisLayer:
    """Recording of the chassis robots of a run, for `sim.views.recording.recorder.Recorder`: `log(path, data,
    static=True)` logs static data to every stream; `columns(path, times, columns)` sends columns to
    every stream. Wheels and ICR are buffered and leave with the recorder's chunk of the robot's
    poses (`flush`), so that a live view never shows them ahead of the body."""

    def __init__(self, log: Callable[..., None], columns: Callable[..., None], robots: list[int], timeline: str):
        self.log, self.columns, self.robots, self.timeline, self.samples = log, columns, robots, timeline, 0
        self.previous: dict[int, np.ndarray] = {}
        self.drawn: dict[int, tuple[np.ndarray, int]] = {}  # the wheels last drawn: angles, faults
        self.wheels: dict[str, list[tuple[float, np.ndarray, list]]] = {}  # name -> (time, segments, colours)
        self.icr: dict[str, list[tuple[float, np.ndarray | None]]] = {}  # name -> (time, ICR or None)

    @classmethod
    def for_world(cls, log: Callable[..., None], columns: Callable[..., None], world: Any, timeline: str) -> ChassisLayer | None:
        """A layer for the world's chassis robots, None if it has none."""
        robots = [r.index for r in world.robots if r.spec.chassis is not None]
        return cls(log, columns, robots, timeline) if robots else None

    def style(self, names: dict[int, str]) -> None:
        """Static sizes of each robot's wheels and ICR, and the ICR's colour (`names`: robot index ->
        name); wheels get their colours as they are drawn (static ones would hide those: a failed
        wheel turns red)."""
        import rerun as rr

        for i in self.robots:
            base = f"world/{names[i]}"
            self.log(f"{base}/body/wheels", rr.Arrows2D.from_fields(radii=WHEEL_RADIUS_M, draw_order=62), static=True)
            self.log(f"{base}/chassis/icr", rr.Points2D.from_fields(colors=palette.ICR, radii=-5.0, draw_order=64), static=True)

    def on_sample(self, world: Any, logs: list) -> None:
        """Every EVERY-th sample: the wheels if a steering angle or fault changed, the ICR of the last step."""
        self.samples += 1
        for i in self.robots:
            pose = logs[i].truth_array(slice(-1, None))[0]
            previous = self.previous.get(i, pose)
            self.previous[i] = pose
            if (self.samples - 1) % EVERY:
                continue
            name, steering, failures = logs[i].name, logs[i].latest.steering, logs[i].latest.failures
            drawn = self.drawn.get(i)
            if drawn is None or drawn[1] != len(failures) or not np.array_equal(steering, drawn[0]):
                self.drawn[i] = (steering.copy(), len(failures))
                chassis = logs[i].spec.chassis.chassis
                failed = {f.wheel for f in failures}
                colours = [palette.FAULT if k in failed else palette.WHEEL for k in range(chassis.n)]
                self.wheels.setdefault(name, []).append((world.time, wheel_segments(chassis, steering), colours))
            self.icr.setdefault(name, []).append((world.time, in_view(step_icr(previous, pose), world.spec.bounds)))

    def flush(self, name: str) -> None:
        """Send robot `name`'s buffered wheels and ICRs."""
        import rerun as rr

        base = f"world/{name}"
        wheels, self.wheels[name] = self.wheels.get(name, []), []
        if wheels:
            segments = np.concatenate([w[1] for w in wheels])
            self.columns(f"{base}/body/wheels", [rr.TimeColumn(self.timeline, duration=[w[0] for w in wheels])],
                         rr.Arrows2D.columns(origins=segments[:, 0], vectors=segments[:, 1] - segments[:, 0],
                                             colors=np.concatenate([w[2] for w in wheels])).partition([len(w[1]) for w in wheels]))
        icr, self.icr[name] = self.icr.get(name, []), []
        if icr:
            points = np.array([p for _, p in icr if p is not None]).reshape(-1, 2)
            self.columns(f"{base}/chassis/icr", [rr.TimeColumn(self.timeline, duration=[t for t, _ in icr])],
                         rr.Points2D.columns(positions=points).partition([int(p is not None) for _, p in icr]))
