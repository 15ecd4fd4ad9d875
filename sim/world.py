"""The simulated world: a pymunk space in metres with robots driven along exact arcs.

The physical contract (DESIGN.md §4) in one place. Each step: sensors are read from the state at
the start (`read`), the caller computes motor commands, then `step` runs the motor model, counts
encoder ticks, turns wheel arcs into an exact-arc motion, limits it where a wall or another body
is in the way, lets pymunk resolve contacts, and measures the true motion (for the mouse) and
ground contact (for holes). Everything random draws from per-sensor generators spawned from the
world's seed.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pymunk

from bots.spec import RobotSpec
from sim.floor import FloorMap, rasterize
from sim.kinematics import (
    apply_increment,
    arc_increment,
    counts_per_metre,
    mouse_displacement_from_increment,
    quantize,
    relative_increment,
    wheel_arcs_to_arc,
)
from sim.readings import Readings
from sim.sensors import IRCurve, builtin_gp2d12, ldr_value, load_ir_curve
from sim.worldspec import Start, WorldSpec

SLOP = 0.0005
"""pymunk collision slop for a world in metres (its default 0.1 assumes pixels)."""
SWEEP_CLEARANCE = 2 * SLOP
"""A move is cut where the body would sink deeper than this into another body."""
IR_RAY_LENGTH = 0.85
"""How far an IR ray is cast (m), c't-Sim's pick distance; beyond it nothing is seen."""
MOVABLE_DAMPING = 0.05
"""Velocity fraction movable obstacles keep after a second: they slide a little and stop."""


class CommandError(ValueError):
    """A motor command that must not reach the physics (NaN, infinite, wrong shape)."""


def find_shared_curves() -> Path | None:
    """c't-Sim's characteristics folder beside the repository (`../shared/ctsim/characteristics`)."""
    here = Path(__file__).resolve().parents[2] / "shared" / "ctsim" / "characteristics"
    return here if here.is_dir() else None


def ir_curve_for(name: str | None, side: str) -> IRCurve:
    """The characteristic a sensor names: a file path, a file name in the shared c't-Sim folder,
    or (None) the built-in GP2D12 fit for its side."""
    if name is None:
        return builtin_gp2d12(side)
    path = Path(name)
    if not path.is_file():
        shared = find_shared_curves()
        if shared is not None and (shared / name).is_file():
            path = shared / name
    return load_ir_curve(path)


def _rng(seed: int, robot: int, sensor: str) -> np.random.Generator:
    """A generator for one sensor, keyed by robot index and sensor name, so that adding a sensor
    or a robot never changes another sensor's noise."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(robot, zlib.crc32(sensor.encode()))))


def _rotate(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Body-frame points (..., k, 2) to world points for poses (..., 3)."""
    c, s = np.cos(pose[..., 2])[..., None], np.sin(pose[..., 2])[..., None]
    x, y = points[..., 0], points[..., 1]
    return np.stack((pose[..., 0, None] + c * x - s * y, pose[..., 1, None] + s * x + c * y), axis=-1)


@dataclass
class Robot:
    """One robot in the world: its description, its pymunk body and its sensors' state."""

    index: int
    name: str
    spec: RobotSpec
    body: pymunk.Body
    shape: pymunk.Circle
    query_filter: pymunk.ShapeFilter
    ir_curves: tuple[IRCurve, ...]
    rngs: dict[str, np.random.Generator]
    wheel_speed: np.ndarray = field(default_factory=lambda: np.zeros(2))
    tick_carry: np.ndarray = field(default_factory=lambda: np.zeros(2))
    mouse_carry: np.ndarray = field(default_factory=lambda: np.zeros(2))
    ticks: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    counts: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    velocity: tuple[float, float] = (0.0, 0.0)
    angular_velocity: float = 0.0
    fallen: bool = False
    blocked: bool = False
    collisions: int = 0

    @property
    def pose(self) -> np.ndarray:
        """Ground-truth pose (x, y m; heading rad, continuous)."""
        return np.array([*self.body.position, self.body.angle])


class World:
    """A pymunk world built from a `WorldSpec`, with robots added by `add_robot`."""

    def __init__(self, spec: WorldSpec, dt: float = 0.01, seed: int = 0, floor_cell: float = 0.002):
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"the step dt must be a positive number of seconds, got {dt!r}")
        self.spec = spec
        self.dt = dt
        self.seed = seed
        self.time = 0.0
        self.steps = 0
        self.robots: list[Robot] = []
        self.floor: FloorMap = rasterize(spec, floor_cell)
        self.space = pymunk.Space()
        self.space.collision_slop = SLOP
        self.space.iterations = 10
        self.space.damping = MOVABLE_DAMPING
        for wall in spec.walls:
            shape = pymunk.Poly(self.space.static_body, wall.vertices)
            shape.friction = 0.0
            self.space.add(shape)
        self.movables: list[pymunk.Body] = []
        for item in spec.movables:
            body = pymunk.Body(item.mass, pymunk.moment_for_circle(item.mass, 0, item.radius))
            body.position = item.position
            shape = pymunk.Circle(body, item.radius)
            shape.friction = 0.3
            self.space.add(body, shape)
            self.movables.append(body)
        self._lights = np.array([(*light.position, light.height) for light in spec.lights]).reshape(-1, 3)

    # --- robots -----------------------------------------------------------------------------

    def add_robot(self, spec: RobotSpec, start: Start | tuple[float, float, float] | None = None, name: str | None = None) -> Robot:
        """Place a robot at `start` (default: the world's start slot for the next robot)."""
        index = len(self.robots)
        if start is None:
            start = self.spec.start_for(index)
        x, y, heading = (start.x, start.y, start.heading) if isinstance(start, Start) else start
        body = pymunk.Body(spec.mass, pymunk.moment_for_circle(spec.mass, 0, spec.body_radius))
        body.position = (x, y)
        body.angle = heading
        shape = pymunk.Circle(body, spec.body_radius)
        shape.friction = 0.0
        shape.filter = pymunk.ShapeFilter(group=index + 1)
        robot = Robot(
            index=index,
            name=name or f"{spec.name}{index}" if index else (name or spec.name),
            spec=spec,
            body=body,
            shape=shape,
            query_filter=shape.filter,
            ir_curves=tuple(ir_curve_for(s.curve, s.side) for s in spec.ir),
            rngs={},
        )
        sensor_names = ["encoders", "mouse"] + [s.name for s in (*spec.ir, *spec.line, *spec.border, *spec.light)]
        robot.rngs = {n: _rng(self.seed, index, n) for n in sensor_names}

        def set_velocity(body: pymunk.Body, gravity, damping, dt) -> None:  # noqa: ANN001 (pymunk callback)
            body.velocity = robot.velocity
            body.angular_velocity = robot.angular_velocity

        def hold_position(body: pymunk.Body, dt: float) -> None:
            """Robots move after the contact solve (see `step`), not before it as pymunk would."""

        body.velocity_func = set_velocity
        body.position_func = hold_position
        self.space.add(body, shape)
        self.robots.append(robot)
        return robot

    # --- sensors ----------------------------------------------------------------------------

    def read(self, robot: Robot) -> Readings:
        """The robot's sensor readings from the current state (the start of the next step)."""
        spec = robot.spec
        pose = robot.pose
        ir_raw, ir_distance = self._read_ir(robot, pose)
        floor_points = _rotate(np.array([s.position for s in (*spec.line, *spec.border)]).reshape(-1, 2), pose)
        floor_values = self.floor.sample(floor_points)
        floor_values = self._noisy(robot, (*spec.line, *spec.border), floor_values, 1023)
        n_line = len(spec.line)
        return Readings(
            time=self.time,
            encoder_ticks=robot.ticks.copy(),
            mouse_counts=robot.counts.copy(),
            ir_raw=ir_raw,
            ir_distance=ir_distance,
            line=floor_values[:n_line],
            border=floor_values[n_line:],
            light=self._read_light(robot, pose),
        )

    def _noisy(self, robot: Robot, sensors, values: np.ndarray, top: int) -> np.ndarray:
        if not any(s.noise_std for s in sensors):
            return values
        noise = [robot.rngs[s.name].normal(0.0, s.noise_std) if s.noise_std else 0.0 for s in sensors]
        return np.clip(np.rint(values + np.array(noise)), 0, top).astype(np.int64)

    def ray_distance(self, robot: Robot, origin: np.ndarray, direction: float, length: float = IR_RAY_LENGTH) -> float:
        """Distance (m) from `origin` along world `direction` to the first body other than the
        robot's own; inf if nothing within `length`."""
        end = (origin[0] + length * math.cos(direction), origin[1] + length * math.sin(direction))
        hit = self.space.segment_query_first(tuple(origin), end, 0.0, robot.query_filter)
        return hit.alpha * length if hit is not None else math.inf

    def _read_ir(self, robot: Robot, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sensors = robot.spec.ir
        if not sensors:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        origins = _rotate(np.array([s.position for s in sensors]), pose)
        raw = np.empty(len(sensors), dtype=np.int64)
        distance = np.empty(len(sensors))
        for k, (sensor, curve) in enumerate(zip(sensors, robot.ir_curves)):
            d = self.ray_distance(robot, origins[k], pose[2] + sensor.direction)
            if sensor.noise_std and math.isfinite(d):
                d = max(0.0, d + robot.rngs[sensor.name].normal(0.0, sensor.noise_std))
            raw[k] = curve.lookup(d)
            distance[k] = curve.distance_from_raw(raw[k], sensor.min_range, sensor.max_range)
        return raw, distance

    def _read_light(self, robot: Robot, pose: np.ndarray) -> np.ndarray:
        sensors = robot.spec.light
        if not sensors:
            return np.zeros(0, dtype=np.int64)
        origins = _rotate(np.array([s.position for s in sensors]), pose)
        nearest = np.full(len(sensors), np.inf)
        if len(self._lights):
            offset = self._lights[None, :, :2] - origins[:, None, :]
            distance = np.sqrt(np.sum(offset**2, axis=-1) + self._lights[None, :, 2] ** 2)
            look = pose[2] + np.array([s.direction for s in sensors])
            bearing = np.arctan2(offset[..., 1], offset[..., 0]) - look[:, None]
            off_axis = np.abs((bearing + np.pi) % (2 * np.pi) - np.pi)
            half_opening = np.array([s.opening / 2 for s in sensors])[:, None]
            nearest = np.min(np.where(off_axis <= half_opening, distance, np.inf), axis=1)
        values = np.array([ldr_value(d, s.reach) for d, s in zip(nearest, sensors)], dtype=np.int64)
        return self._noisy(robot, sensors, values, 1023)

    # --- motion -----------------------------------------------------------------------------

    def _motor(self, robot: Robot, command: np.ndarray) -> np.ndarray:
        """Wheel angular speeds (rad/s) at the end of the step for a signed motor command."""
        motor = robot.spec.motor
        target = np.clip(command, -motor.command_max, motor.command_max) / motor.command_max * motor.max_wheel_speed
        speed = robot.wheel_speed
        if motor.time_constant > 0:
            target = speed + (target - speed) * (1.0 - math.exp(-self.dt / motor.time_constant))
        if math.isfinite(motor.max_acceleration):
            limit = motor.max_acceleration * self.dt
            target = speed + np.clip(target - speed, -limit, limit)
        return target

    def _wheel_arcs(self, robot: Robot, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(encoder ticks, ground arc lengths of the wheels in m) for wheel rotations (rad)."""
        enc = robot.spec.encoders
        rng = robot.rngs["encoders"]
        ticks, robot.tick_carry = quantize(rotation / (2 * math.pi) * enc.ticks_per_rev, robot.tick_carry)
        if enc.tick_noise:
            ticks = ticks + (rng.random(2) < enc.tick_noise) * rng.choice((-1, 1), size=2)
        real_radius = robot.spec.wheel_radius * (1.0 + np.asarray(enc.diameter_error))
        arcs = rotation * real_radius
        if enc.slip_std:
            arcs = arcs * (1.0 + rng.normal(0.0, enc.slip_std, size=2))
        return ticks, arcs

    def _plan_motion(self, robot: Robot, arcs: np.ndarray) -> None:
        """Set the body velocity so an unobstructed step lands exactly on the arc's end pose:
        velocity = chord/dt, angular velocity = alpha/dt; cut the translation where a swept
        circle would first sink more than SWEEP_CLEARANCE into something (no tunnelling)."""
        if robot.fallen:
            robot.velocity, robot.angular_velocity = (0.0, 0.0), 0.0
            return
        track = robot.spec.track_width * (1.0 + robot.spec.encoders.track_error)
        s, alpha = wheel_arcs_to_arc(arcs[0], arcs[1], track)
        pose = robot.pose
        end = apply_increment(pose, arc_increment(s, alpha))
        move = end[:2] - pose[:2]
        robot.blocked = False
        if move @ move > 0:
            hit = self.space.segment_query_first(
                tuple(pose[:2]), tuple(end[:2]), robot.spec.body_radius - SWEEP_CLEARANCE, robot.query_filter
            )
            if hit is not None:
                move = move * hit.alpha
                robot.blocked = True
        robot.velocity = (move[0] / self.dt, move[1] / self.dt)
        robot.angular_velocity = float(alpha) / self.dt

    def step(self, commands: np.ndarray) -> None:
        """Advance the world by dt with signed motor commands (n_robots, 2) = (left, right)."""
        commands = np.asarray(commands, dtype=np.float64)
        if commands.shape != (len(self.robots), 2):
            raise CommandError(f"expected motor commands of shape ({len(self.robots)}, 2), got {commands.shape}")
        if not np.all(np.isfinite(commands)):
            bad = [self.robots[i].name for i in np.unique(np.nonzero(~np.isfinite(commands))[0])]
            raise CommandError(f"non-finite motor command for {', '.join(bad)} at step {self.steps}")
        before = [robot.pose for robot in self.robots]
        for robot, command in zip(self.robots, commands):
            robot.wheel_speed = self._motor(robot, command)
            robot.ticks, arcs = self._wheel_arcs(robot, robot.wheel_speed * self.dt)
            self._plan_motion(robot, arcs)
        self.space.step(self.dt)
        for robot, start in zip(self.robots, before):
            pymunk.Body.update_position(robot.body, self.dt)
            self._after_motion(robot, start)
        self.steps += 1
        self.time = self.steps * self.dt

    def _after_motion(self, robot: Robot, start: np.ndarray) -> None:
        """Mouse counts from the true motion, contact with the floor, collision bookkeeping."""
        spec = robot.spec
        pose = robot.pose
        if not robot.fallen:
            contacts = _rotate(
                np.array([(0.0, spec.track_width / 2), (0.0, -spec.track_width / 2), spec.skid]), pose
            )
            robot.fallen = bool(self.floor.is_hole(contacts).any())
            if robot.fallen:
                robot.body.velocity, robot.body.angular_velocity = (0.0, 0.0), 0.0
        touching = robot.blocked or any(True for _ in _arbiters(robot.body))
        robot.collisions += touching and not getattr(robot, "_touching", False)
        robot._touching = touching
        mouse = spec.mouse
        if mouse is None:
            return
        increment = relative_increment(start, pose)
        metres = mouse_displacement_from_increment(increment, np.asarray(mouse.mount))
        if self.floor.is_hole(_rotate(np.asarray([mouse.mount]), pose))[0] or np.hypot(*metres) > mouse.max_speed * self.dt:
            metres = np.zeros(2)
        counts = metres * counts_per_metre(mouse.dpi) * (1.0 + mouse.scale_error)
        if mouse.noise_std:
            counts = counts + robot.rngs["mouse"].normal(0.0, mouse.noise_std, size=2)
        robot.counts, robot.mouse_carry = quantize(counts, robot.mouse_carry)


def _arbiters(body: pymunk.Body):
    """The contacts a body is in after the last step."""
    found = []
    body.each_arbiter(found.append)
    return found
