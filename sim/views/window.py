"""`ctsim play`: drive a robot by keyboard in a pygame-ce window, recorded like `ctsim run`.

The session is an ordinary run (`sim.run.loop.run`) with two extra observers: the window, which every
frame handles keys and the mouse (a click puts the robot where it points: a kidnapping), draws the
world with the robot, its IR rays, readings, odometry ghosts and a localiser's particles, and
paces the simulation to real time; and the recorder. Offscreen it runs with SDL_VIDEODRIVER=dummy,
a frame limit and injected events (tests).
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from bots.behaviours.motion import Teleop
from bots.odometry.user import beside_defaults, name_of
from bots.sensor_kinds import KINDS, SensorKind
from bots.spec import RobotSpec
from sim.run.ending import Quit
from sim.run.loop import RobotSetup, run
from sim.run.samples import RobotLog, RunResult
from sim.views import palette
from sim.views.chassis_view import (
    WHEEL_RADIUS_M,
    body_outline,
    chassis_shapes,
    steering_deflection,
    to_world,
)
from sim.views.particles import localisers, thinned
from sim.views.recording.recorder import Recorder
from sim.world import IR_RAY_LENGTH, World
from sim.world.spec import WorldSpec
from sim.world.step import DEFAULT_DT

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

FORWARD = 0.25
"""Teleop forward speed (m/s)."""
TURN_DEG_S = 143.0
"""Teleop turn rate (deg/s, 2.5 rad/s)."""
SESSION_LIMIT = 24 * 3600.0
"""Simulated seconds a session without a frame limit may last."""
WINDOW = (1000, 720)
PANEL = 320
TRAIL_POINTS = 2000
"""Most points drawn per trail each frame (a long session is thinned, not slowed)."""
DRAG_PX = 8
"""A press and release of the mouse button farther apart than this (px) turn the robot put down
the way the mouse moved; nearer, it keeps its heading."""
NOTE_S = 4.0
"""How long (wall-clock s) the panel shows what the last click did."""
NOTE_WIDTH = 40
"""Characters of the panel's lines for that note (the panel is PANEL px wide)."""


def _shown(kind: SensorKind, values: np.ndarray) -> str:
    """A kind's values on its line: integers as they are, others in its shown unit (mm, degrees),
    nothing in view as a dash."""
    if kind.dtype is not np.float64:
        return "  ".join(f"{int(v):5d}" for v in values)
    return "  ".join("  -  " if not np.isfinite(v) else f"{kind.scale * v:4.0f}" for v in values)


class Window:
    """Run observer drawing the world every `steps_per_frame` samples, `fps` frames per second of
    wall-clock time, so that simulated time runs `speed` times real time."""

    def __init__(self, drive: Teleop, fps: float, steps_per_frame: int, speed: float, scale: float | None, events: dict[int, list[Any]]):
        self.drive, self.fps, self.steps_per_frame, self.speed = drive, fps, steps_per_frame, speed
        self.scale, self.events = scale, events
        self.frame = 0
        self.snapshot: Path | None = None
        """Where to save the last frame as an image when the window closes (None: nowhere)."""
        self.quit = False
        self._samples = 0
        self._pressed: tuple[int, int] | None = None
        """Where the mouse button went down on the map (px), until it comes up."""
        self._note: tuple[str, int] | None = None
        """What the last click did, and the frame until which the panel shows it."""

    def on_start(self, world: World, logs: list[RobotLog]) -> None:
        import pygame

        pygame.display.init()
        pygame.font.init()
        xmin, ymin, xmax, ymax = world.spec.bounds
        if self.scale is None:
            self.scale = min((WINDOW[0] - PANEL - 20) / (xmax - xmin), (WINDOW[1] - 20) / (ymax - ymin))
        self.origin = (xmin, ymax)
        size = (int((xmax - xmin) * self.scale) + PANEL + 20, max(int((ymax - ymin) * self.scale) + 20, 480))
        self.screen = pygame.display.set_mode(size)
        pygame.display.set_caption(f"ctsim play: {world.spec.name}")
        self.font = pygame.font.Font(None, 20)
        self.clock = pygame.time.Clock()
        self.map = self._draw_map(world.spec, size)
        self.world = world

    def on_sample(self, world: World, logs: list[RobotLog]) -> None:
        self._samples += 1
        if (self._samples - 1) % self.steps_per_frame:
            return
        self._handle_events()
        self._draw(world, logs)
        self.clock.tick(self.fps)
        self.frame += 1
        if self.quit:
            raise Quit

    def on_end(self, result: RunResult) -> None:
        import pygame

        if self.snapshot is not None and self.frame:
            pygame.image.save(self.screen, str(self.snapshot))
        pygame.quit()

    # --- drawing ------------------------------------------------------------------------------

    def px(self, x: float, y: float) -> tuple[int, int]:
        """World metres to window pixels (y up on screen)."""
        return int(10 + (x - self.origin[0]) * self.scale), int(10 + (self.origin[1] - y) * self.scale)

    def metres(self, point: tuple[int, int]) -> tuple[float, float]:
        """Window pixels to world metres (`px`'s inverse, to the pixel's centre)."""
        return self.origin[0] + (point[0] + 0.5 - 10) / self.scale, self.origin[1] - (point[1] + 0.5 - 10) / self.scale

    def _polygon(self, surface, colour, vertices, width: int = 0) -> None:
        import pygame

        pygame.draw.polygon(surface, colour, [self.px(*v) for v in vertices], width)

    def _draw_map(self, spec: WorldSpec, size: tuple[int, int]):
        """The static map, drawn once: the same shapes as the figures and the recording."""
        import pygame

        from sim.views.map_image import map_surface

        surface = pygame.Surface(size)
        surface.fill(palette.BACKGROUND)
        xmin, _, _, ymax = spec.bounds
        surface.blit(map_surface(spec, self.scale), self.px(xmin, ymax))
        return surface

    def _draw(self, world: World, logs: list[RobotLog]) -> None:
        import pygame

        self.screen.blit(self.map, (0, 0))
        left = self.screen.get_width() - PANEL
        self.screen.set_clip((0, 0, left - 10, self.screen.get_height()))  # (what lies past the map, particles too, stays off the panel)
        lines: list[tuple[str, tuple[int, int, int]]] = [(f"t = {world.time:7.2f} s   speed x{self.speed:g}", palette.ROBOT_EDGE)]
        for robot, log in zip(world.robots, logs):
            pose = robot.pose
            truth, estimates = log.truth_array(), log.estimate_arrays()
            self._trail(truth, palette.TRUTH, 3, log.puts)
            for name, poses in estimates.items():
                self._trail(poses, palette.estimate_colour(name, list(estimates)), 1)
            for sensor, distance in zip(robot.spec.ir, log.latest.ir_distance):
                c, s = math.cos(pose[2]), math.sin(pose[2])
                x, y = sensor.position
                origin = np.array((pose[0] + c * x - s * y, pose[1] + s * x + c * y))
                direction = pose[2] + sensor.direction
                reach = distance if np.isfinite(distance) else IR_RAY_LENGTH
                end = origin + reach * np.array((math.cos(direction), math.sin(direction)))
                pygame.draw.line(self.screen, palette.RAY, self.px(*origin), self.px(*end), 1)
                if np.isfinite(distance):
                    pygame.draw.circle(self.screen, palette.HIT, self.px(*end), 3)
            for localiser in localisers(log.estimators):
                where, colours = thinned(localiser.particles, localiser.likelihood, palette.estimate_colour(name_of(localiser), list(estimates)))
                for (x, y), colour in zip(where.tolist(), colours.tolist()):
                    pygame.draw.circle(self.screen, colour, self.px(x, y), 2)
            outline = body_outline(robot.spec)
            for name, poses in estimates.items():
                self._body(poses[-1], 0.6 * outline, palette.estimate_colour(name, list(estimates)), 1)
            if robot.spec.chassis is not None:
                self._chassis(robot.spec, truth, log.latest, world.spec.bounds)
            self._body(pose, outline, palette.TRUTH, 2)
            lines += self._readout(log, robot, pose, estimates)
        self.screen.set_clip(None)
        if self._note is not None and self.frame <= self._note[1]:
            lines += [("", palette.ROBOT_EDGE), *((text, palette.ROBOT_EDGE) for text in textwrap.wrap(self._note[0], NOTE_WIDTH))]
        self._scale_bar()
        for k, (text, colour) in enumerate(lines):
            if colour != palette.ROBOT_EDGE:
                pygame.draw.rect(self.screen, colour, (left, 14 + 18 * k, 10, 10))
            self.screen.blit(self.font.render(text, True, palette.ROBOT_EDGE), (left + 16 * (colour != palette.ROBOT_EDGE), 12 + 18 * k))
        for k, help_line in enumerate(("arrows/WASD drive   space stop   Esc/q quit", "click: put the robot there (drag: turn it)")):
            self.screen.blit(self.font.render(help_line, True, palette.ROBOT_EDGE), (left, self.screen.get_height() - 42 + 18 * k))
        pygame.display.flip()

    def _readout(self, log: RobotLog, robot, pose: np.ndarray, estimates: dict[str, np.ndarray]) -> list[tuple[str, tuple[int, int, int]]]:
        """The robot's pose, each estimate's error (its colour as the key) and the sensors in their units."""
        readings = log.latest
        lines = [
            ("", palette.ROBOT_EDGE),
            (f"{log.name}: x {pose[0]:6.3f} m  y {pose[1]:6.3f} m", palette.ROBOT_EDGE),
            (f"heading {math.degrees(pose[2]):7.1f} deg  collisions {robot.collisions}", palette.ROBOT_EDGE),
            ("truth", palette.TRUTH),
        ]
        for name, poses in estimates.items():
            error = 1000 * math.hypot(*(poses[-1, :2] - pose[:2]))
            lines.append((f"{name:<9} error {error:6.1f} mm", palette.estimate_colour(name, list(estimates))))
        for localiser in localisers(log.estimators):
            lines.append((f"{name_of(localiser):<9} {'LOST: searching the map' if localiser.lost else 'on the map'}", palette.estimate_colour(name_of(localiser), list(estimates))))
        for kind in KINDS:  # (the sensor registry's, those the robot has)
            if kind.present(robot.spec):
                values = getattr(readings, kind.field)
                if kind.angle:
                    values = steering_deflection(robot.spec.chassis.chassis, values)
                lines.append((f"{kind.window:<17}{_shown(kind, values)}", palette.ROBOT_EDGE))
        return lines

    def _trail(self, poses: np.ndarray, colour, width: int, breaks: list[int] | tuple = ()) -> None:
        """The path so far, thinned to at most TRAIL_POINTS points, in pieces split before the
        samples `breaks` (the truth's: where the robot was put down, `RobotLog.puts`; an estimate's
        jump is its own path, drawn as it went: `Recorder._send_trails`)."""
        import pygame

        step = max(1, len(poses) // TRAIL_POINTS)
        for piece in np.split(poses[:, :2], breaks):
            if len(piece) > 1:
                points = [self.px(x, y) for x, y in piece[::step].tolist()] + [self.px(*piece[-1])]
                pygame.draw.lines(self.screen, colour, False, points, width)

    def _body(self, pose: np.ndarray, outline: np.ndarray, colour, width: int) -> None:
        """A robot as its outline (body frame, closed) with a line to the front beyond its edge (the
        heading)."""
        import pygame

        reach = outline[:, 0].max()
        tip = pose[:2] + 1.35 * reach * np.array([math.cos(pose[2]), math.sin(pose[2])])
        pygame.draw.lines(self.screen, colour, True, [self.px(*p) for p in to_world(pose, outline[:-1])], width)
        pygame.draw.line(self.screen, colour, self.px(*pose[:2]), self.px(*tip), width + 1)

    def _chassis(self, spec: RobotSpec, truth: np.ndarray, readings, view: tuple[float, float, float, float]) -> None:
        """Each wheel along the way it rolls (an arrow head at its front, so steering shows; red once
        it failed), and the ICR of the last step when it lies in the world."""
        import pygame

        shapes = chassis_shapes(spec, truth[-1], readings.steering, truth[-2] if len(truth) > 1 else truth[-1], view)
        thick = max(3, round(2 * WHEEL_RADIUS_M * self.scale))
        failed = {f.wheel for f in readings.failures}
        for k, (back, front) in enumerate(shapes.wheels):
            colour = palette.FAULT if k in failed else palette.WHEEL
            along = front - back
            side = np.array([-along[1], along[0]]) * 0.35
            pygame.draw.line(self.screen, colour, self.px(*back), self.px(*front), thick)
            head = [front + 0.3 * along, front - 0.2 * along + side, front - 0.2 * along - side]
            pygame.draw.polygon(self.screen, colour, [self.px(*p) for p in head])
        if shapes.icr is not None:
            centre = self.px(*shapes.icr)
            pygame.draw.line(self.screen, palette.ICR, centre, self.px(*truth[-1, :2]), 1)
            pygame.draw.circle(self.screen, palette.ICR, centre, 5)

    def _scale_bar(self) -> None:
        """A bar of a round length (about 100 px) at the panel's foot, above the keys: drawn on the
        map it hid what lay in the corner (a lamp of the maze)."""
        import pygame

        metres = next(m for m in (0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0) if m * self.scale >= 80 or m == 50.0)
        x, y = self.screen.get_width() - PANEL, self.screen.get_height() - 56
        pygame.draw.line(self.screen, palette.SCALE_BAR, (x, y), (x + int(metres * self.scale), y), 3)
        label = f"{metres * 100:g} cm" if metres < 1 else f"{metres:g} m"
        self.screen.blit(self.font.render(label, True, palette.SCALE_BAR), (x, y - 17))

    def _handle_events(self) -> None:
        import pygame

        for event in self.events.get(self.frame, ()):
            pygame.event.post(event)
        for event in pygame.event.get():
            if event.type == pygame.QUIT or (event.type == pygame.KEYDOWN and event.key in (pygame.K_ESCAPE, pygame.K_q)):
                self.quit = True
            elif event.type == pygame.KEYDOWN and event.key == pygame.K_SPACE:
                self.drive.set_keys(())
            elif event.type == pygame.KEYDOWN:
                self.drive.press(pygame.key.name(event.key))
            elif event.type == pygame.KEYUP:
                self.drive.release(pygame.key.name(event.key))
            elif event.type == pygame.MOUSEBUTTONDOWN and event.button == 1:
                self._pressed = event.pos
            elif event.type == pygame.MOUSEBUTTONUP and event.button == 1 and self._pressed is not None:
                self._put(self._pressed, event.pos)
                self._pressed = None

    def _put(self, down: tuple[int, int], up: tuple[int, int]) -> None:
        """Put the robot where the mouse went down, turned the way it was dragged (else as it was):
        a kidnapping, which its odometry does not see (`World.put_robot`); where it cannot stand,
        the panel says why."""
        robot = self.world.robots[0]
        x, y = self.metres(down)
        dx, dy = up[0] - down[0], down[1] - up[1]  # (screen y points down)
        heading = math.atan2(dy, dx) if math.hypot(dx, dy) > DRAG_PX else float(robot.pose[2])
        try:
            self.world.put_robot(robot.index, (x, y, heading))
            note = f"put {robot.name} at ({x:.2f}, {y:.2f}), {math.degrees(heading):.0f} deg"
        except ValueError as err:
            note = str(err)
        self._note = (note, self.frame + int(NOTE_S * self.fps))


def play(
    world: WorldSpec,
    spec: RobotSpec,
    recording: str | Path | None,
    seed: int = 0,
    dt: float = DEFAULT_DT,
    fps: float = 60.0,
    speed: float = 1.0,
    frames: int | None = None,
    scale: float | None = None,
    live: bool = False,
    connect: str | None = None,
    events: dict[int, Iterable[Any]] | None = None,
    snapshot: str | Path | None = None,
    estimators: Iterable[Any] = (),
) -> RunResult:
    """Open the window and run until it is closed (or for `frames` frames); each frame advances
    `speed`/fps of simulated time, shown 1/fps of a second: simulated time runs `speed` times
    real time (up to about `fps` frames per second). `events` maps a frame number to pygame events
    posted before it; `snapshot` saves the last frame there (PNG). `estimators` join the
    robot's defaults (as `simulate`'s: "localiser", or estimator objects)."""
    drive = Teleop(speed_m_s=FORWARD, turn_deg_s=TURN_DEG_S)
    steps_per_frame = max(1, round(speed / (fps * dt)))
    duration = frames * steps_per_frame * dt if frames is not None else SESSION_LIMIT
    window = Window(drive, speed / (steps_per_frame * dt), steps_per_frame, speed, scale, {k: list(v) for k, v in (events or {}).items()})
    window.snapshot = Path(snapshot) if snapshot is not None else None
    setup = RobotSetup(spec, drive, controller_name="teleop", extra_estimators=beside_defaults(spec, estimators))
    result = run(world, [setup], duration, dt=dt, seed=seed, observers=(Recorder(recording, live=live, connect=connect), window))
    return result
