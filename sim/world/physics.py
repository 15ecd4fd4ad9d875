"""The simulated world: a pymunk space in metres with robots driven along exact arcs.

The physical contract (DESIGN.md §4) in one place. Each step: sensors are read from the state at
the start (`read_all`), the caller computes motor commands, then `step` runs the motor model,
counts encoder ticks, turns wheel arcs into an exact-arc motion, cuts it where a wall or another
body is in the way, lets pymunk resolve contacts (a lone robot clear of every wall moves as pymunk
would move it, without pymunk: `kernels.motion.glide`), and measures the true motion (for the mouse) and
ground contact (for holes). The per-robot arithmetic runs in compiled kernels over all robots
at once (`sim.world.kernels`); pymunk does the geometry. Everything random draws from
per-sensor generators spawned from the world's seed.
"""

from __future__ import annotations

import math
import os
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pymunk

import sim
from bots.readings import SensorFrame, SensorLayout
from bots.spec import RobotSpec
from sim.kinematics import counts_per_metre
from sim.world import layout
from sim.world.bodies import BodyArrays
from sim.world.chassis_drive import ChassisDrive
from sim.world.compiling import compile_all
from sim.world.floor import FloorMap, rasterize
from sim.world.kernels.contacts import settle
from sim.world.kernels.grids import build_wall_grid
from sim.world.kernels.motion import glide, measure_all, plan
from sim.world.kernels.noise import ENCODER_DRAWS, add_rounded, draw_step, spurious_ticks
from sim.world.kernels.pick import pick_polygon
from sim.world.kernels.sensing import ir_rays, ir_values, read_sensors
from sim.world.noise import NormalBlocks
from sim.world.sensors import CNY70_MAX, LDR_MAX, IRCurve, gp2d12, load_ir_curve
from sim.world.spec import Start, WorldSpec
from sim.world.step import DEFAULT_DT, check_dt

SLOP = 0.0005
"""pymunk collision slop for a world in metres (its default 0.1 assumes pixels)."""
SWEEP_CLEARANCE = 1.5 * SLOP
"""A move is cut where the body would sink deeper than this into another body."""
SLIDE_MARGIN = 0.2 * SLOP
"""The sweep of a slide along a surface just touched uses a circle thinner by this (m)."""
IR_RAY_LENGTH = 0.85
"""How far an IR ray is cast (m), c't-Sim's pick distance; beyond it nothing is seen."""
MOVABLE_DAMPING = 0.05
"""Velocity fraction movable obstacles keep after a second: they slide a little and stop."""
ROBOT = 1
"""pymunk collision type of robot bodies (to count their contacts)."""


@dataclass(frozen=True)
class _Noisy:
    """The sensors of one kind that have noise: their rows in the kind's values, their standard
    deviations and their generators' normals."""

    rows: np.ndarray
    std: np.ndarray
    normals: NormalBlocks
    sensors: tuple[tuple[int, str], ...]
    """(robot index, sensor name) of each row of `normals`, to seed a robot's rows anew."""

    @classmethod
    def of(cls, items: list[tuple[int, Robot, str, float]]) -> _Noisy:
        """From (row, robot, sensor name, std) per noisy sensor."""
        return cls(
            rows=np.array([k for k, _, _, _ in items], dtype=np.int64),
            std=np.array([std for _, _, _, std in items], dtype=np.float64),
            normals=NormalBlocks([robot.rngs[name] for _, robot, name, _ in items]),
            sensors=tuple((robot.index, name) for _, robot, name, _ in items),
        )

    def reseed(self, robot: Robot) -> None:
        """Draw `robot`'s rows from its (new) generators from now on."""
        for k, (index, name) in enumerate(self.sensors):
            if index == robot.index:
                self.normals.restart(k, robot.rngs[name])

    def arguments(self) -> tuple[np.ndarray, ...]:
        """Its rows, standard deviations and normals as `kernels.noise` takes them."""
        return self.rows, self.std, self.normals.values, self.normals.used


class CommandError(ValueError):
    """A motor command that must not reach the physics (NaN, infinite, wrong shape)."""


def shared_folder() -> Path:
    """Where c't-Sim's own data files are looked for: the folder `CTSIM_SHARED` names, else
    `../shared` beside the repository (its `ctsim/characteristics` and `ctsim/parcours`)."""
    named = os.environ.get("CTSIM_SHARED")
    return Path(named) if named else Path(sim.__file__).resolve().parents[2] / "shared"


def find_shared_curves() -> Path | None:
    """c't-Sim's characteristics folder (`shared_folder()/ctsim/characteristics`), if it is there."""
    here = shared_folder() / "ctsim" / "characteristics"
    return here if here.is_dir() else None


def ir_curve_for(name: str | None, side: str) -> IRCurve:
    """The characteristic a sensor names: a file path, a file name in the shared c't-Sim folder,
    or (None) the c't-Bot's GP2D12 table for its side (`sensors.gp2d12`, shipped with ctsim)."""
    if name is None:
        return gp2d12(side)
    path = Path(name)
    if not path.is_file():
        shared = find_shared_curves()
        if shared is not None and (shared / name).is_file():
            path = shared / name
    return load_ir_curve(path)


def sensor_rng(seed: int, robot: int, sensor: str) -> np.random.Generator:
    """The generator of one sensor, keyed by robot index and sensor name, so that adding a sensor
    or a robot never changes another sensor's noise."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(robot, zlib.crc32(sensor.encode()))))


PHASES = "start phases"
"""The generator key of where a robot's counters stand within a count at the start."""


def start_phases(spec: RobotSpec, rng: np.random.Generator) -> np.ndarray:
    """(4,) the carries a robot's counters start with (encoder left, right; mouse forward, left, in
    counts): zero where the spec says 'zero' (c't-Sim), else uniform in [0, 1) (`start_phase`)."""
    phases = np.zeros(4)
    if spec.encoders.start_phase == "random":
        phases[:2] = rng.random(2)
    if spec.mouse is not None and spec.mouse.start_phase == "random":
        phases[2:] = rng.random(2)
    return phases


@dataclass
class Robot:
    """One robot in the world: its description, its pymunk body and its bookkeeping."""

    index: int
    name: str
    spec: RobotSpec
    body: pymunk.Body
    shape: pymunk.Circle | pymunk.Poly
    query_filter: pymunk.ShapeFilter
    ir_curves: tuple[IRCurve, ...]
    rngs: dict[str, np.random.Generator]
    phases: np.ndarray = field(default_factory=lambda: np.zeros(4))
    """Carries its encoders and mouse start with (`start_phases`)."""
    slot: int | None = None
    """The start slot it was placed at (None: an explicit pose); its goals are `spec.goals_of(slot)`."""
    fallen: bool = False
    """In a hole (c't-Sim's IN_HOLE): the last step's move was refused because a wheel or the skid
    would have been over a hole (`kernels.floor.hold_at_holes`); clears when a move is allowed again."""
    collisions: int = 0

    @property
    def pose(self) -> np.ndarray:
        """Ground-truth pose (x, y m; heading rad, continuous)."""
        p = self.body.position
        return np.array((p.x, p.y, self.body.angle))


class World:
    """A pymunk world built from a `WorldSpec`, with robots added by `add_robot`."""

    def __init__(self, spec: WorldSpec, dt: float = DEFAULT_DT, seed: int = 0, floor_cell: float = 0.002, robots_meet: bool = True):
        """`robots_meet=False`: the robots pass through each other and no sensor sees another
        robot, as copies of one world that happen to share it (a batched Gymnasium env)."""
        check_dt(dt)
        self.spec = spec
        self.dt = dt
        self.seed = seed
        self.robots_meet = robots_meet
        self.time = 0.0
        self.steps = 0
        self.robots: list[Robot] = []
        self.floor: FloorMap = rasterize(spec, floor_cell)
        self.space = pymunk.Space()
        self.space.collision_slop = SLOP
        self.space.iterations = 10
        self._robot_of_shape: dict[pymunk.Shape, Robot] = {}
        self.space.on_collision(ROBOT, None, begin=self._count_contact)
        for wall in spec.walls:
            shape = pymunk.Poly(self.space.static_body, wall.vertices)
            shape.friction = 0.0
            self.space.add(shape)
        self._walls = WallArrays.build(spec)
        """The walls for the kernels; the grid's origin and cell are among `_scalars`."""
        self.movables: list[pymunk.Body] = []
        self._movable_shapes: list[pymunk.Circle] = []
        self._round_bodies = True
        """Whether every robot is a circle: then the IR kernel sees walls, robots and cans itself."""
        self._round_ir = False
        """Whether the IR kernel reads the IR sensors (there are some, and every robot is round)."""
        for item in spec.movables:
            body = pymunk.Body(item.mass, pymunk.moment_for_circle(item.mass, 0, item.radius))
            body.position = item.position
            body.velocity_func = _damped
            shape = pymunk.Circle(body, item.radius)
            shape.friction = 0.3
            self.space.add(body, shape)
            self.movables.append(body)
            self._movable_shapes.append(shape)
        self._lights = np.array([(*light.position, light.height, light.radius) for light in spec.lights], dtype=np.float64).reshape(-1, 4)
        self._scalars = np.array(
            (*self.floor.origin, self.floor.cell, self.floor.outside_is_hole, self.floor.outside_absorption, IR_RAY_LENGTH, SLIDE_MARGIN, dt,
             *self._walls.frame, float(robots_meet), self.floor.line_height),
            dtype=np.float64,
        )
        """The world's scalars for the kernels (`kernels.SCALARS`; writeable: numba types read-only
        arrays on a slow path)."""
        self._state = _BatchState([], dt, [], robots_meet)
        self._bodies = BodyArrays(self.space, [])
        self._poses = np.zeros((0, 3))
        self._stale = True  # the kernels are compiled (or loaded) at the first use, for the robots then in it
        self.chassis = ChassisDrive(dt)
        """The drive of robots on a general chassis (commands, faults; see `sim.world.chassis_drive`)."""

    # --- robots -----------------------------------------------------------------------------

    def add_robot(self, spec: RobotSpec, start: Start | tuple[float, float, float] | None = None, name: str | None = None,
                  seed: int | None = None) -> Robot:  # fmt: skip
        """Place a robot at `start` (default: the world's start slot for the next robot). Its
        sensors' noise comes from the world's seed, or from `seed` as for the first robot of a
        world of that seed."""
        index = len(self.robots)
        (x, y, heading), slot = self._start_pose(index, start)
        outline = spec.chassis.outline if spec.chassis is not None else ()
        if outline:
            body = pymunk.Body(spec.mass, pymunk.moment_for_poly(spec.mass, outline))
            shape = pymunk.Poly(body, outline)
        else:
            body = pymunk.Body(spec.mass, pymunk.moment_for_circle(spec.mass, 0, spec.body_radius))
            shape = pymunk.Circle(body, spec.body_radius)
        body.position = (x, y)
        body.angle = heading
        shape.friction = 0.0
        shape.filter = pymunk.ShapeFilter(group=index + 1 if self.robots_meet else 1)  # a robot's group passes through itself
        robot = Robot(
            index=index,
            name=name or (spec.name if index == 0 else f"{spec.name}{index}"),
            spec=spec,
            body=body,
            shape=shape,
            query_filter=shape.filter,
            ir_curves=tuple(ir_curve_for(s.curve, s.side) for s in spec.ir),
            rngs=self._sensor_rngs(spec, index, seed),
            slot=slot,
        )
        robot.phases = start_phases(spec, robot.rngs[PHASES])

        shape.collision_type = ROBOT
        self._round_bodies &= isinstance(shape, pymunk.Circle)
        self._robot_of_shape[shape] = robot
        self.space.add(body, shape)
        self.robots.append(robot)
        if spec.chassis is not None:
            self.chassis.add(robot)
        self._stale = True
        return robot

    def _start_pose(self, index: int, start: Start | tuple[float, float, float] | None) -> tuple[tuple[float, float, float], int | None]:
        """Robot `index`'s pose at `start` (default: its start slot) and the slot that is (None: a bare pose)."""
        if start is None:
            start = self.spec.start_for(index)
        return ((start.x, start.y, start.heading), start.slot) if isinstance(start, Start) else (tuple(start), None)

    def _sensor_rngs(self, spec: RobotSpec, index: int, seed: int | None) -> dict[str, np.random.Generator]:
        sensors = ["encoders", "mouse", "mouse2", PHASES] + [s.name for s in (*spec.ir, *spec.line, *spec.border, *spec.light)]
        if seed is None:
            return {n: sensor_rng(self.seed, index, n) for n in sensors}
        return {n: sensor_rng(seed, 0, n) for n in sensors}

    def reset_robot(self, index: int, start: Start | tuple[float, float, float] | None = None, seed: int | None = None) -> Robot:
        """Put robot `index` back as `add_robot` would put it into a new world: at `start`, at
        rest, its counters, carries and hole flag cleared, its contacts forgotten and its
        sensors' noise drawn afresh (from `seed` as in `add_robot`). The other robots go on as
        they were: with `robots_meet=False`, this is a new episode of one copy of the world."""
        robot = self.robots[index]
        if robot.spec.chassis is not None:
            raise ValueError(f"{robot.name}: a robot on a general chassis cannot be reset in place")
        st = self._batch()
        (x, y, heading), robot.slot = self._start_pose(index, start)
        self.space.remove(robot.shape)  # pymunk forgets the shape's contacts (its arbiters) with it
        body = robot.body
        body.position, body.angle = (x, y), heading
        body.velocity, body.angular_velocity, body.force, body.torque = (0.0, 0.0), 0.0, (0.0, 0.0), 0.0
        self.space.add(robot.shape)
        self._poses[index] = (x, y, heading)
        robot.fallen, robot.collisions = False, 0
        st.state[index], st.tallies[index], st.fallen[index] = 0.0, 0, False
        robot.rngs = self._sensor_rngs(robot.spec, index, seed)
        robot.phases = start_phases(robot.spec, robot.rngs[PHASES])
        st.start_counters(robot)
        st.reseed(robot)
        self._quiet[layout.STREAK] = 0
        return robot

    @property
    def tallies(self) -> np.ndarray:
        """(n, 4) per robot: encoder ticks (left, right) and mouse counts (forward, left) of the
        last step, as `read_all` gives them (a view, overwritten by the next step)."""
        return self._batch().tallies

    def _batch(self) -> _BatchState:
        """The kernels' arrays, rebuilt once after robots joined (not once per robot added: a
        thousand robots would cost a million rows)."""
        if self._stale:
            self._state = _BatchState(self.robots, self.dt, self._movable_shapes, self.robots_meet)
            self._bodies = BodyArrays(self.space, [r.body for r in self.robots])
            self._poses = self._bodies.poses()
            self._kernel_arguments()
            self._stale = False
        return self._state

    def _kernel_arguments(self) -> None:
        """The arrays the per-step kernels take besides the poses and the step's outputs, gathered
        once into tuples, and the kernels' compiled entry points for their types."""
        st, walls, ir = self._state, self._walls, self._state.ir
        self._round_ir = self._round_bodies and len(ir.curve) > 0
        read = len(st.sensors) if self._round_ir else st.n_floor + st.n_light  # pymunk reads IR otherwise
        # quiet steps (`kernels.contacts.settle`, `kernels.motion.glide`) for one round robot and nothing else that
        # moves, whose contacts can only be with walls, met in their fixed order; the contacts of
        # several bodies come in the order of pymunk's tree of moving shapes, which a skipped step
        # would leave unchanged (the same physics, but other roundings later)
        alone = len(self.robots) == 1 and self._round_bodies and not self.movables
        self._quiet = np.array((0, self.space.collision_persistence if alone else -1), dtype=np.int64)
        self._read_arguments = (
            st.sensors[:read], st.index[:read], st.n_floor, self.floor.ground, self.floor.lines, self._scalars, self._lights, walls.vertices,
            walls.ranges, walls.boxes, walls.cells, st.circles, ir.noise.std, ir.noise.normals.values, ir.noise.normals.used, ir.tables,
            ir.curve_ends, ir.beyond, ir.inverse,
        )  # fmt: skip
        self._step_noise_arguments = (*st.step_noise.arguments(), len(st.tick_noise), st.slip, st.tick_uniforms, st.mouse_noise)
        self._tick_noise_arguments = (st.step_noise.rows[: len(st.tick_noise)], st.tick_noise, st.tick_uniforms, st.tallies[:, layout.TICKS : layout.TICKS + 2])
        self._floor_and_light_arguments = (*st.floor_and_light_noise.arguments(), st.floor_and_light_top)
        self._settle_arguments = (
            st.params, st.state, self._scalars, walls.vertices, walls.ranges, walls.boxes, walls.cells, st.contacts, st.anchored, self.floor.hole,
            st.fallen, self._bodies.row_index, self._bodies.motion, self._quiet, st.circles,
        )  # fmt: skip
        # the kernels each step calls, for the types they get then: C-ordered (n, 2) commands and
        # (n, 3) poses, int64 values and float believed distances (`compiling.compiled_for`; the largest last, see `compile_all`)
        pose, commands = self._poses, np.zeros((len(self.robots), 2))
        (self._draw_step_noise, self._spurious_ticks, self._floor_and_light_noise,
         self._plan, self._glide, self._measure, self._settle, self._read_sensors) = compile_all([
            (draw_step, (commands, *self._step_noise_arguments)),
            (spurious_ticks, self._tick_noise_arguments),
            (add_rounded, (np.empty(len(st.sensors), np.int64), *self._floor_and_light_arguments)),
            (plan, (commands, st.params, st.state, st.tallies, pose, self.dt)),
            (glide, (pose, st.params, self._bodies.motion, self._bodies.row_index, self.dt)),
            (measure_all, (pose, pose, st.params, st.state, st.tallies, self.floor.hole, self._scalars)),
            (settle, (pose, *self._settle_arguments)),
            (read_sensors, (pose, *self._read_arguments, np.empty(0, np.int64), np.empty(0))),
        ])  # fmt: skip

    def poses(self) -> np.ndarray:
        """(n, 3) ground-truth poses of all robots (a copy)."""
        self._batch()
        return self._poses.copy()

    # --- sensors ----------------------------------------------------------------------------

    def sensor_rows(self) -> dict[str, np.dtype]:
        """The arrays `read_all` fills each step, as row types (numpy subarray dtypes): `values`
        int64 (every floor, light and raw IR value), `believed` float64 (every IR distance, m),
        `tallies` int64 (robots, 4). A run keeps one row of each per sample (`readings_columns`
        reads a robot's fields back out of them)."""
        st = self._batch()
        return {"values": np.dtype((np.int64, (len(st.sensors),))), "believed": np.dtype((np.float64, (len(st.ir.curve),))),
                "tallies": np.dtype((np.int64, st.tallies.shape))}  # fmt: skip

    def readings_columns(self, index: int, values: np.ndarray, believed: np.ndarray, tallies: np.ndarray) -> dict[str, np.ndarray]:
        """Robot `index`'s readings fields (Readings' names, each (samples, width)) out of samples of
        `sensor_rows`' arrays, each with a leading sample axis (views, no copies). A general chassis's
        per-wheel encoders, steering and second mouse are not among them (`ChassisDrive.fill`)."""
        st = self._batch()
        ir, line, border, light = st.layout.slices[index]
        lights = st.n_floor + st.n_light
        return {
            "encoder_ticks": tallies[:, index, :2], "mouse_counts": tallies[:, index, 2:],
            "ir_raw": values[:, lights + ir.start : lights + ir.stop], "ir_distance": believed[:, ir],
            "line": values[:, line], "border": values[:, border], "light": values[:, st.n_floor + light.start : st.n_floor + light.stop],
        }  # fmt: skip

    def read_all(self, rows: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> SensorFrame:
        """Every robot's sensor readings from the current state (the start of the next step):
        `frame[i]` is robot i's `Readings`. `rows`: one row of each of `sensor_rows`' arrays
        (values, believed, tallies) to read into, in place of new arrays: the frame's views then
        point into them."""
        st = self._batch()
        pose = self._poses
        if rows is None:
            values, believed, tallies = np.empty(len(st.sensors), dtype=np.int64), np.empty(len(st.ir.curve)), st.tallies.copy()
        else:
            values, believed, tallies = rows
            tallies[:] = st.tallies
        lights = st.n_floor + st.n_light  # the end of the light rows, where the IR rows start
        if self._round_ir:
            if len(st.ir.noise.rows):
                st.ir.noise.normals.reserve(1)
            if self.movables:  # (checked first: starting an empty loop costs more than the check)
                for k, body in enumerate(self.movables, start=len(pose)):
                    st.circles[k, 0], st.circles[k, 1] = body.position
            self._read_sensors(pose, *self._read_arguments, values, believed)
        else:  # without the IR rows: pymunk reads them below
            self._read_sensors(pose, *self._read_arguments, values[:lights], believed[:0])
        floor, light, ir_raw = values[: st.n_floor], values[st.n_floor : lights], values[lights:]
        if st.floor_and_light_noise.sensors:
            st.floor_and_light_noise.normals.reserve(1)
            self._floor_and_light_noise(values, *self._floor_and_light_arguments)
        if not self._round_ir:
            self._read_ir_with_pymunk(pose, ir_raw, believed)
        frame = SensorFrame(self.time, tallies, ir_raw, believed, floor, light, st.layout)
        if self.chassis.drives:
            self.chassis.fill(frame)
        return frame

    def ray_distance(self, robot: Robot, origin, direction: float, length: float = IR_RAY_LENGTH, cone: float = 0.0, pick: bool = False) -> float:
        """Distance (m) from `origin` to the nearest point of any body other than the robot's own
        within `cone` (rad, half-angle) of world `direction` and within `length`; inf if none.
        With `pick`, walls are seen as c't-Sim's Java3D pick sees them (`IRSensorSpec.view`,
        `kernels.pick.pick_polygon`); other bodies in the whole cone.

        A cone across a wall at a slant reads the cone's near edge, not the axis. Every body is
        convex, so its nearest point in the cone is its nearest point overall when that lies
        inside the cone, else where an edge ray first meets it: two rays and one nearest-point
        query are exact."""
        if cone <= 0.0:
            return self._cast(robot, origin, direction, length)
        c, s = math.cos(direction), math.sin(direction)
        cos_cone = math.cos(cone)
        if pick:
            walls = self._walls
            best = min((pick_polygon(origin[0], origin[1], c, s, length, math.tan(cone), walls.vertices, a, b) for a, b in walls.ranges), default=math.inf)
            best = min(best, self._cast(robot, origin, direction - cone, length, moving=True), self._cast(robot, origin, direction + cone, length, moving=True))
            limit = length / cos_cone  # a rim point near the segment's end lies that far
        else:
            best = min(self._cast(robot, origin, direction - cone, length), self._cast(robot, origin, direction + cone, length))
            limit = length
        for info in self.space.point_query((origin[0], origin[1]), min(best, length), robot.query_filter):
            if pick and info.shape.body.body_type == pymunk.Body.STATIC:
                continue  # a wall: seen as the pick sees it
            dx, dy = info.point.x - origin[0], info.point.y - origin[1]
            if info.distance <= 0.0:
                return 0.0  # the sensor is inside another body
            if dx * c + dy * s >= cos_cone * info.distance:
                best = min(best, info.distance)
        return best if best <= limit else math.inf

    def _cast(self, robot: Robot, origin, direction: float, length: float, moving: bool = False) -> float:
        """Distance (m) along one ray to the first body other than the robot's own (`moving`: the
        first that is not a wall); inf if none."""
        end = (origin[0] + length * math.cos(direction), origin[1] + length * math.sin(direction))
        if not moving:
            hit = self.space.segment_query_first((origin[0], origin[1]), end, 0.0, robot.query_filter)
            return hit.alpha * length if hit is not None else math.inf
        hits = self.space.segment_query((origin[0], origin[1]), end, 0.0, robot.query_filter)
        return min((hit.alpha * length for hit in hits if hit.shape.body.body_type != pymunk.Body.STATIC), default=math.inf)

    def _read_ir_with_pymunk(self, pose: np.ndarray, raw: np.ndarray, believed: np.ndarray) -> None:
        """Raw values and believed distances of every IR sensor in a world with a robot of polygon
        outline, whose true distances pymunk's queries give (they see every shape), then noise and
        the curves (`kernels.sensing.ir_values`)."""
        st = self._batch()
        ir = st.ir
        n = len(ir.curve)
        if n == 0:
            return
        if len(ir.noise.rows):
            ir.noise.normals.reserve(1)
        first = st.n_floor + st.n_light
        mounts, owner = st.sensors[first:], st.index[first:, layout.OWNER]
        origins, look, distance = np.empty((n, 2)), np.empty(n), np.empty(n)
        ir_rays(pose, mounts[:, layout.AT : layout.AT + 2], owner, mounts[:, layout.DIRECTION], origins, look)
        for k, (robot, sensor) in enumerate(st.ir_sensors):
            distance[k] = self.ray_distance(robot, origins[k], look[k], cone=sensor.cone, pick=sensor.view == "pick")
        ir_values(distance, ir.noise_row, ir.noise.std, ir.noise.normals.values, ir.noise.normals.used, *ir.curves, raw, believed)

    # --- motion -----------------------------------------------------------------------------

    def step(self, commands: np.ndarray) -> None:
        """Advance the world by dt with signed motor commands (n_robots, 2) = (left, right); robots on
        a general chassis ignore theirs and drive what `self.chassis.command` set."""
        commands = np.ascontiguousarray(commands, dtype=np.float64)  # (the layout `_plan` was compiled for)
        if commands.shape != (len(self.robots), 2):
            raise CommandError(f"expected motor commands of shape ({len(self.robots)}, 2), got {commands.shape}")
        st = self._batch()
        before = self._poses
        bad = -1
        if st.step_noise.sensors:  # (a refused step draws no noise)
            st.step_noise.normals.reserve(ENCODER_DRAWS)
            bad = self._draw_step_noise(commands, *self._step_noise_arguments)
        if bad < 0:
            bad = self._plan(commands, st.params, st.state, st.tallies, before, self.dt)
            if bad < 0 and st.spurious_ticks:
                self._spurious_ticks(*self._tick_noise_arguments)
        if bad >= 0:
            names = [self.robots[i].name for i in np.unique(np.nonzero(~np.isfinite(commands))[0])]
            raise CommandError(f"non-finite motor command for {', '.join(names)} at step {self.steps}")
        if self.chassis.drives:
            self.chassis.drive(self.time, before, st.move, st.alpha)
        # cut each exact-arc move where the body would first sink deeper than SWEEP_CLEARANCE into
        # a wall or another robot, so that no speed the motors allow tunnels through anything
        # then hold robots at holes, and give pymunk the motion as forces (see `_apply_motion`)
        self._bodies.refresh()
        if len(st.stoppers) and self.movables:  # c't-Sim's contact rule meets the cans where they stand
            for k, body in enumerate(self.movables, start=len(st.circles) - len(self.movables)):
                st.circles[k, 0], st.circles[k, 1] = body.position
        was_blocked = st.state[st.stoppers, layout.BLOCKED] if len(st.stoppers) else None
        changed, quiet = self._settle(before, *self._settle_arguments)
        if was_blocked is not None:  # a robot newly stopped by c't-Sim's rule has met something
            for i in st.stoppers[(st.state[st.stoppers, layout.BLOCKED] > 0) & (was_blocked == 0)]:
                self.robots[i].collisions += 1
        if changed:
            for robot in self.robots:
                robot.fallen = bool(st.fallen[robot.index])
        if quiet:  # nothing to collide: pymunk's motion without pymunk (a third of a bare robot's step)
            after = self._poses = self._glide(before, st.params, self._bodies.motion, self._bodies.row_index, self.dt)
            self._bodies.place(after)
        else:
            self._apply_motion()
            after = self._poses = self._bodies.poses()
        self._measure(before, after, st.params, st.state, st.tallies, self.floor.hole, self._scalars)
        if self.chassis.drives:
            self.chassis.after_step(before, after, self.floor)
        self.steps += 1
        self.time = self.steps * self.dt

    def _apply_motion(self) -> None:
        """Make each body's velocity after pymunk's velocity phase move/dt and alpha/dt (the forces
        `kernels.contacts.settle` wrote), step pymunk and move the robots.

        pymunk moves bodies *before* it solves contacts, with the velocity they have; a velocity
        set before `space.step` would push the body into a wall unchecked. So the body enters the
        step at rest (it does not move then), a force gives it the planned velocity in the
        velocity phase (v = f dt / m), the contact solver corrects it, and the position is
        integrated after the step (`BodyArrays.move`): the same order as setting the velocity
        inside `velocity_func`, without a Python callback per body."""
        self._bodies.send()
        self.space.step(self.dt)
        self._bodies.move(self.dt)

    def _count_contact(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data) -> None:  # noqa: ANN001
        """A robot started touching something: one more collision for it (for both, robot on robot)."""
        for shape in arbiter.shapes:
            robot = self._robot_of_shape.get(shape)
            if robot is not None:
                robot.collisions += 1


def _damped(body: pymunk.Body, gravity, damping: float, dt: float) -> None:  # noqa: ANN001 (pymunk callback)
    """Movable obstacles lose speed on the floor; robots are not damped (their velocity is set)."""
    pymunk.Body.update_velocity(body, gravity, MOVABLE_DAMPING**dt, dt)


WALL_GRID_ABOVE = 128
"""Walls a world has before the kernels look them up in a grid: up to this many, one cell holds
them all, as checking every wall's box (a compiled loop, a fraction of a nanosecond a box) costs
no more than finding the cells. Measured with one c't-Bot reading every sensor in generated
mazes: a step costs the same either way at 82 and 133 walls; the grid saves about 5% at 329
walls, 10-15% at 934 and 40% at 3,780, where its step costs what one among 22 walls does."""
WALLS_PER_CELL = 2.0
"""The wall grid's cells hold this many walls on average (`wall_cell`)."""


def wall_cell(boxes: np.ndarray) -> float:
    """The side (m) of the wall grid's square cells for walls of bounding boxes `boxes` (n, 4):
    cells of WALLS_PER_CELL walls' share of the walls' extent, so that the grid has about
    n / WALLS_PER_CELL cells whatever the world's size and a query meets the walls near it; at
    least 1/n of the extent's longer side (a thin extent has n cells at most along it)."""
    n = len(boxes)
    if n == 0:
        return 1.0
    width, height = boxes[:, 2].max() - boxes[:, 0].min(), boxes[:, 3].max() - boxes[:, 1].min()
    return max(math.sqrt(WALLS_PER_CELL * width * height / n), max(width, height) / n, 1e-9)


@dataclass(frozen=True)
class WallArrays:
    """The walls as flat arrays for the kernels: all vertices, each wall's slice of them, its
    bounding box (xmin, ymin, xmax, ymax) and a uniform grid over the boxes (`kernels.grids.build_wall_grid`;
    walls are static, so it is built once): its origin and cell size (`frame`) and its cells."""

    vertices: np.ndarray
    ranges: np.ndarray
    boxes: np.ndarray
    frame: np.ndarray
    cells: np.ndarray

    @classmethod
    def build(cls, spec: WorldSpec) -> WallArrays:
        polygons = [np.asarray(w.vertices, dtype=np.float64) for w in spec.walls]
        ends = np.cumsum([len(p) for p in polygons], dtype=np.int64)
        starts = ends - np.array([len(p) for p in polygons], dtype=np.int64)
        boxes = np.array([(*p.min(axis=0), *p.max(axis=0)) for p in polygons]).reshape(-1, 4)
        frame, cells = build_wall_grid(boxes, wall_cell(boxes) if len(boxes) > WALL_GRID_ABOVE else math.inf)  # one cell: the plain loop
        return cls(
            vertices=np.concatenate(polygons).reshape(-1, 2) if polygons else np.zeros((0, 2)),
            ranges=np.stack((starts, ends), axis=1).reshape(-1, 2),
            boxes=boxes,
            frame=frame,
            cells=cells,
        )


def _contacts(spec: RobotSpec) -> tuple[np.ndarray, np.ndarray]:
    """The ground contacts the hole rule checks (body frame, m) and which of them c't-Sim checks at
    the robot's old position: the c't-Bot's wheels (old position) and skid (new position); every
    wheel of a general chassis (new position)."""
    if spec.chassis is None:
        points = np.array(((0.0, spec.track_width / 2), (0.0, -spec.track_width / 2), spec.skid))
        return points, np.array((True, True, False))
    points = np.asarray(spec.chassis.chassis.positions, dtype=np.float64)
    return points, np.zeros(len(points), dtype=bool)


def _padded(rows: list[np.ndarray], dtype: type, tail: tuple[int, ...] = ()) -> np.ndarray:
    """Per-robot contact arrays stacked to the longest one, each padded by repeating its own rows."""
    width = max((len(r) for r in rows), default=1)
    return np.array([r[np.arange(width) % len(r)] for r in rows], dtype=dtype).reshape(len(rows), width, *tail)


def _columns(array: np.ndarray, start: int, width: int = 2) -> np.ndarray:
    """A named view of a packed array's columns: one column (width 1) or `width` of them."""
    return array[:, start] if width == 1 else array[:, start : start + width]


class _BatchState:
    """Per-robot parameters and state as arrays for the kernels (rebuilt when a robot joins):
    packed into a few 2-D arrays in the column layout of `sim.world.layout` (one argument each
    per kernel call), with named views of the columns the Python side uses."""

    def __init__(self, robots: list[Robot], dt: float, movable_shapes: list[pymunk.Circle], robots_meet: bool = True):
        n = len(robots)
        specs = [r.spec for r in robots]
        motor = [s.motor for s in specs]
        self.params = np.zeros((n, layout.PARAMS))
        p = self.params
        p[:, layout.COMMAND_MAX] = [m.command_max for m in motor]
        p[:, layout.MAX_SPEED] = [m.max_wheel_speed for m in motor]
        p[:, layout.LAG] = [1.0 - math.exp(-dt / m.time_constant) if m.time_constant > 0 else 1.0 for m in motor]
        p[:, layout.MAX_CHANGE] = [m.max_acceleration * dt for m in motor]
        p[:, layout.TICKS_PER_RAD] = [s.encoders.ticks_per_rev / (2 * math.pi) for s in specs]
        _columns(p, layout.REAL_RADIUS)[:] = np.array([[s.wheel_radius * (1 + e) for e in s.encoders.diameter_error] for s in specs]).reshape(n, 2)
        p[:, layout.TRACK] = [s.track_width * (1 + s.encoders.track_error) for s in specs]
        _columns(p, layout.MOUNT)[:] = np.array([s.mouse.mount if s.mouse else (0.0, 0.0) for s in specs], dtype=np.float64).reshape(n, 2)
        p[:, layout.COUNTS_PER_METRE] = [counts_per_metre(s.mouse.dpi) * (1 + s.mouse.scale_error) if s.mouse else 0.0 for s in specs]
        p[:, layout.MAX_STEP] = [s.mouse.max_speed * dt if s.mouse else 0.0 for s in specs]
        p[:, layout.SWEEP_RADIUS] = [s.body_radius - SWEEP_CLEARANCE for s in specs]
        p[:, layout.APART_RADIUS] = [s.body_radius - SWEEP_CLEARANCE / 2 for s in specs]
        p[:, layout.MASS] = [r.body.mass for r in robots]
        p[:, layout.MOMENT] = [r.body.moment for r in robots]
        p[:, layout.RADIUS] = [s.body_radius for s in specs]
        p[:, layout.STOPS] = [s.contact == "stop" for s in specs]
        self.stoppers = np.flatnonzero(p[:, layout.STOPS])
        """The robots with c't-Sim's contact rule (a refused move counts as a collision)."""
        self.contacts = _padded([_contacts(s)[0] for s in specs], np.float64, (2,))
        self.anchored = _padded([_contacts(s)[1] for s in specs], np.bool_)
        self.state = np.zeros((n, layout.STATE))
        for robot in robots:
            self.start_counters(robot)
        self.slip = _columns(self.state, layout.SLIP)
        self.mouse_noise = _columns(self.state, layout.MOUSE_NOISE)
        self.move = _columns(self.state, layout.MOVE)
        self.alpha = _columns(self.state, layout.ALPHA, 1)
        self.tallies = np.zeros((n, layout.TALLIES), dtype=np.int64)
        """Encoder ticks then mouse counts of the last step."""
        self.fallen = np.array([r.fallen for r in robots], dtype=np.bool_)
        encoders = [r for r in robots if r.spec.encoders.slip_std or r.spec.encoders.tick_noise]
        mice = [r for r in robots if r.spec.mouse is not None and r.spec.mouse.noise_std]
        self.step_noise = _Noisy.of([(r.index, r, "encoders", r.spec.encoders.slip_std) for r in encoders]
                                    + [(r.index, r, "mouse", r.spec.mouse.noise_std * p[r.index, layout.COUNTS_PER_METRE]) for r in mice])
        """What a step draws before it moves (`kernels.noise.draw_step`): rows of the robots whose
        encoders slip or miscount (std: their slip_std), then of those whose mouse has count noise
        (std: noise_std (sqrt m) at the counts' own scale, counts per sqrt m)."""
        self.tick_noise = np.array([r.spec.encoders.tick_noise for r in encoders], dtype=np.float64)
        self.tick_uniforms = np.zeros((len(encoders), 4))
        """The step's uniforms of each noisy encoder's spurious ticks."""
        self.spurious_ticks = bool(self.tick_noise.any())

        floor = [(r, s) for r in robots for s in (*r.spec.line, *r.spec.border)]
        light = [(r, s) for r in robots for s in r.spec.light]
        ir = [(r, s) for r in robots for s in r.spec.ir]
        self.ir_sensors = ir
        self.n_floor, self.n_light = len(floor), len(light)
        every = floor + light + ir
        self.sensors = np.zeros((len(every), layout.SENSOR))
        self.sensors[:, layout.AT : layout.AT + 2] = np.array([s.position for _, s in every], dtype=np.float64).reshape(-1, 2)
        self.sensors[: len(floor) + len(light), layout.HEIGHT] = [s.height for _, s in floor + light]
        self.sensors[len(floor) :, layout.DIRECTION] = [s.direction for _, s in light + ir]
        self.sensors[len(floor) :, layout.OPENING] = [s.opening / 2 for _, s in light] + [s.cone for _, s in ir]
        self.sensors[len(floor) : len(floor) + len(light), layout.REACH] = [s.reach for _, s in light]
        self.sensors[len(floor) + len(light) :, layout.PICK] = [s.view == "pick" for _, s in ir]

        def noisy(items):
            return _Noisy.of([(k, robot, s.name, s.noise_std) for k, (robot, s) in enumerate(items) if s.noise_std])

        self.floor_and_light_noise = noisy(floor + light)
        """The noisy floor (line, border) and light sensors: their rows in the values of both."""
        self.floor_and_light_top = np.where(self.floor_and_light_noise.rows < len(floor), CNY70_MAX, LDR_MAX).astype(np.int64)
        """Each one's highest value (`kernels.noise.add_rounded`)."""
        self.ir = _IRArrays.build(ir, noisy(ir))
        self.index = np.zeros((len(every), layout.INDEX), dtype=np.int64)
        self.index[:, layout.OWNER] = [r.index for r, _ in every]
        self.index[len(floor) + len(light) :, layout.NOISE_ROW] = self.ir.noise_row
        self.index[len(floor) + len(light) :, layout.CURVE] = self.ir.curve
        self.circles = np.array(
            [(0.0, 0.0, r.shape.radius, r.index if robots_meet else layout.GHOST) for r in robots if isinstance(r.shape, pymunk.Circle)]
            + [(0.0, 0.0, shape.radius, -1) for shape in movable_shapes],
            dtype=np.float64,
        ).reshape(-1, 4)
        """Robots then movable obstacles as circles (x, y, radius, robot index, GHOST for a robot
        no other sees, or -1) for the IR kernel; positions are filled in at each read."""
        self.layout = SensorLayout.of([(len(s.ir), len(s.line), len(s.border), len(s.light)) for s in specs])

    def start_counters(self, robot: Robot) -> None:
        """`robot`'s counters' carries at their start phases."""
        self.state[robot.index, layout.TICK_CARRY : layout.TICK_CARRY + 2] = robot.phases[:2]
        self.state[robot.index, layout.MOUSE_CARRY : layout.MOUSE_CARRY + 2] = robot.phases[2:]

    def reseed(self, robot: Robot) -> None:
        """Draw `robot`'s noise from its (new) generators from now on."""
        for noisy in (self.step_noise, self.floor_and_light_noise, self.ir.noise):
            noisy.reseed(robot)


@dataclass(frozen=True)
class _IRArrays:
    """The IR sensors' noise and curves as arrays for the kernels: each distinct (curve, range)'s
    tables padded into one 2-D array per kind (the mounts are in `_BatchState.sensors`)."""

    noise: _Noisy
    noise_row: np.ndarray
    """Each sensor's row in `noise` (-1: none)."""
    curve: np.ndarray
    """Each sensor's index into the tables below."""
    tables: np.ndarray
    curve_ends: np.ndarray
    """Per curve: the last centimetre of its table and its lowest raw value."""
    beyond: np.ndarray
    inverse: np.ndarray

    @property
    def curves(self) -> tuple[np.ndarray, ...]:
        """The curve arguments of `kernels.sensing.ir_values` (curve .. lowest)."""
        return self.curve, self.tables, self.curve_ends[:, 0], self.beyond, self.inverse, self.curve_ends[:, 1]

    @classmethod
    def build(cls, ir: list[tuple[Robot, object]], noise: _Noisy) -> _IRArrays:
        n = len(ir)
        index: dict[tuple, int] = {}
        chosen: list[tuple[IRCurve, float, float]] = []
        curve = np.empty(n, dtype=np.int64)
        for k, (robot, sensor) in enumerate(ir):
            table = robot.ir_curves[robot.spec.ir.index(sensor)]
            key = (id(table), sensor.min_range, sensor.max_range)
            if key not in index:
                index[key] = len(chosen)
                chosen.append((table, sensor.min_range, sensor.max_range))
            curve[k] = index[key]
        per_cm = [table.per_cm for table, _, _ in chosen]
        inverse = [table.inverse_table(low, high) for table, low, high in chosen]
        tables = np.zeros((len(chosen), max((len(t) for t in per_cm), default=1)), dtype=np.float32)
        inverses = np.zeros((len(chosen), max((len(t) for t in inverse), default=1)))
        for c, (t, v) in enumerate(zip(per_cm, inverse)):
            tables[c, : len(t)] = t
            inverses[c, : len(v)] = v
        noise_row = np.full(n, -1, dtype=np.int64)
        noise_row[noise.rows] = np.arange(len(noise.rows))
        return cls(
            noise=noise,
            noise_row=noise_row,
            curve=curve,
            tables=tables,
            curve_ends=np.array([(len(t) - 1, table.raw_range()[0]) for t, (table, _, _) in zip(per_cm, chosen)], dtype=np.int64).reshape(-1, 2),
            beyond=np.array([table.beyond for table, _, _ in chosen], dtype=np.float32),
            inverse=inverses,
        )
