"""`ctsim play`: drive a robot by keyboard in a pygame-ce window, recorded like `ctsim run`.

The session is an ordinary run (`sim.run.run`) with two extra observers: the window, which every
frame handles keys, draws the world with the robot, its IR rays, readings and odometry ghosts,
and paces the simulation to real time; and the recorder. Offscreen it runs with
SDL_VIDEODRIVER=dummy, a frame limit and injected events (tests).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from bots.behaviours.motion import Teleop
from bots.spec import RobotSpec
from sim.run import RobotLog, RobotSetup, RunResult, run
from sim.views.recording import Recorder
from sim.world import IR_RAY_LENGTH, World
from sim.world.spec import WorldSpec

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

FORWARD = 0.25
"""Teleop forward speed (m/s)."""
TURN_DEG_S = 143.0
"""Teleop turn rate (deg/s, 2.5 rad/s)."""
SESSION_LIMIT = 24 * 3600.0
"""Simulated seconds a session without a frame limit may last."""
WINDOW = (900, 700)
PANEL = 300
ESTIMATE_COLOURS = ((230, 120, 20), (40, 110, 220), (170, 60, 190), (20, 160, 150), (200, 40, 60))


class _Quit(KeyboardInterrupt):
    """The window was closed or Esc pressed: the run loop ends the run as interrupted."""


class Window:
    """Run observer drawing the world every `steps_per_frame` samples, paced to `fps`."""

    def __init__(self, drive: Teleop, fps: float, steps_per_frame: int, scale: float | None, events: dict[int, list[Any]]):
        self.drive, self.fps, self.steps_per_frame = drive, fps, steps_per_frame
        self.scale, self.events = scale, events
        self.frame = 0
        self.quit = False
        self._samples = 0

    def on_start(self, world: World, logs: list[RobotLog]) -> None:
        import pygame

        pygame.display.init()
        pygame.font.init()
        xmin, ymin, xmax, ymax = world.spec.bounds
        if self.scale is None:
            self.scale = min((WINDOW[0] - PANEL - 20) / (xmax - xmin), (WINDOW[1] - 20) / (ymax - ymin))
        self.origin = (xmin, ymax)
        size = (int((xmax - xmin) * self.scale) + PANEL + 20, max(int((ymax - ymin) * self.scale) + 20, 420))
        self.screen = pygame.display.set_mode(size)
        pygame.display.set_caption(f"ctsim play: {world.spec.name}")
        self.font = pygame.font.Font(None, 20)
        self.clock = pygame.time.Clock()
        self.map = self._draw_map(world.spec, size)

    def on_sample(self, world: World, logs: list[RobotLog]) -> None:
        self._samples += 1
        if (self._samples - 1) % self.steps_per_frame:
            return
        self._handle_events()
        self._draw(world, logs)
        self.clock.tick(self.fps)
        self.frame += 1
        if self.quit:
            raise _Quit

    def on_end(self, result: RunResult) -> None:
        import pygame

        pygame.quit()

    # --- drawing ------------------------------------------------------------------------------

    def px(self, x: float, y: float) -> tuple[int, int]:
        """World metres to window pixels (y up on screen)."""
        return int(10 + (x - self.origin[0]) * self.scale), int(10 + (self.origin[1] - y) * self.scale)

    def _polygon(self, surface, colour, vertices, width: int = 0) -> None:
        import pygame

        pygame.draw.polygon(surface, colour, [self.px(*v) for v in vertices], width)

    def _draw_map(self, spec: WorldSpec, size: tuple[int, int]):
        import pygame

        surface = pygame.Surface(size)
        surface.fill((235, 235, 235))
        xmin, ymin, xmax, ymax = spec.bounds
        rgb = lambda c, light=0.0: tuple(int(255 * (v + (1 - v) * light)) for v in c)  # noqa: E731
        self._polygon(surface, rgb(spec.floor_colour, 0.7), ((xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)))
        for region in spec.floor:
            self._polygon(surface, rgb(region.colour, 0.3), region.vertices)
        for line in spec.lines:
            pygame.draw.lines(surface, rgb(line.colour), False, [self.px(*p) for p in line.points], max(1, int(line.width * self.scale)))
        for hole in spec.holes:
            self._polygon(surface, (0, 0, 0), hole.vertices)
        for goal in spec.goals:
            self._polygon(surface, (120, 225, 140), goal.vertices)
        for wall in spec.walls:
            self._polygon(surface, (80, 80, 80), wall.vertices)
        for light in spec.lights:
            pygame.draw.circle(surface, (255, 215, 30), self.px(*light.position), 7)
        return surface

    def _draw(self, world: World, logs: list[RobotLog]) -> None:
        import pygame

        self.screen.blit(self.map, (0, 0))
        text = ["arrows/WASD drive, space stop, Esc quit", f"t = {world.time:.2f} s"]
        for robot, log in zip(world.robots, logs):
            pose, r = robot.pose, robot.spec.body_radius
            for (name, poses), colour in zip(log.estimates.items(), ESTIMATE_COLOURS):
                ghost = poses[-1]
                pygame.draw.circle(self.screen, colour, self.px(*ghost[:2]), int(r * self.scale), 2)
                tip = ghost[:2] + r * np.array([math.cos(ghost[2]), math.sin(ghost[2])])
                pygame.draw.line(self.screen, colour, self.px(*ghost[:2]), self.px(*tip), 2)
                text.append(f"{name:<9} error {1000 * math.hypot(*(ghost[:2] - pose[:2])):7.1f} mm")
            for sensor in robot.spec.ir:
                c, s = math.cos(pose[2]), math.sin(pose[2])
                x, y = sensor.position
                origin = np.array((pose[0] + c * x - s * y, pose[1] + s * x + c * y))
                direction = pose[2] + sensor.direction
                reach = min(world.ray_distance(robot, origin, direction), IR_RAY_LENGTH)
                end = origin + reach * np.array((math.cos(direction), math.sin(direction)))
                pygame.draw.line(self.screen, (220, 40, 40), self.px(*origin), self.px(*end), 1)
            centre = self.px(*pose[:2])
            pygame.draw.circle(self.screen, (40, 150, 70), centre, int(r * self.scale))
            tip = pose[:2] + r * np.array([math.cos(pose[2]), math.sin(pose[2])])
            pygame.draw.line(self.screen, (255, 255, 255), centre, self.px(*tip), 3)
            readings = log.readings[-1]
            text += [
                f"{log.name}: x {pose[0]:.3f}  y {pose[1]:.3f}  th {math.degrees(pose[2]):.1f} deg",
                f"IR raw {readings.ir_raw.tolist()}  d {np.round(readings.ir_distance, 3).tolist()}",
                f"encoders {readings.encoder_ticks.tolist()}  mouse {readings.mouse_counts.tolist()}",
                f"line {readings.line.tolist()}  border {readings.border.tolist()}",
                f"light {readings.light.tolist()}  collisions {robot.collisions}",
            ]
        left = self.screen.get_width() - PANEL
        for k, line in enumerate(text):
            self.screen.blit(self.font.render(line, True, (20, 20, 20)), (left, 10 + 18 * k))
        pygame.display.flip()

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


def play(
    world: WorldSpec,
    spec: RobotSpec,
    recording: str | Path | None,
    seed: int = 0,
    dt: float = 0.01,
    fps: float = 60.0,
    frames: int | None = None,
    scale: float | None = None,
    live: bool = False,
    connect: str | None = None,
    events: dict[int, Iterable[Any]] | None = None,
) -> RunResult:
    """Open the window and run until it is closed (or for `frames` frames); each frame advances
    1/fps of simulated time. `events` maps a frame number to pygame events posted before it."""
    drive = Teleop(speed_m_s=FORWARD, turn_deg_s=TURN_DEG_S)
    steps_per_frame = max(1, round(1.0 / (fps * dt)))
    duration = frames * steps_per_frame * dt if frames is not None else SESSION_LIMIT
    window = Window(drive, fps, steps_per_frame, scale, {k: list(v) for k, v in (events or {}).items()})
    setup = RobotSetup(spec, drive, controller_name="teleop")
    result = run(world, [setup], duration, dt=dt, seed=seed, observers=(Recorder(recording, live=live, connect=connect), window))
    if window.quit:
        result.reason, result.error = "duration", None
    return result
