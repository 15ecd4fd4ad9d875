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
from dataclasses import dataclass
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
from sim.world.kernels.grids import gridded
from sim.world.kernels.motion import first_bad, glide, measure, plan
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

    @property
    def kernel(self) -> layout.Noise:
        """The standard deviations and normals as the IR kernel takes them."""
        return layout.Noise(self.std, self.normals.values, self.normals.used)

    def reseed(self, robot: Robot) -> None:
        """Draw `robot`'s rows from its (new) generators from now on."""
        for k, (index, name) in enumerate(self.sensors):
            if index == robot.index:
                self.normals.restart(k, robot.rngs[name])

    def add_rounded(self, values: np.ndarray, top: int) -> None:
        """Gaussian noise on the noisy sensors' integer `values`, rounded (half to even, as
        Python's round) into 0..top."""
        if len(self.rows):
            noise = 0.0 + self.std * self.normals.take(1)[:, 0]  # what rng.normal(0.0, std) gives
            values[self.rows] = np.clip(np.rint(values[self.rows] + noise), 0, top)


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
        self._walls = _walls(spec)
        """The walls for the kernels."""
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
        self._lights = layout.LIGHTS.new(len(spec.lights))
        for name, values in zip(("x", "y", "height", "radius"), zip(*((*light.position, light.height, light.radius) for light in spec.lights))):
            self._lights[name] = values
        self._world = layout.WORLD.new(1)
        """The world's scalars for the kernels (a WORLD row; writeable: numba types read-only
        arrays on a slow path)."""
        self._world["dt"], self._world["slide_margin"], self._world["robots_meet"] = dt, SLIDE_MARGIN, robots_meet
        self._state = _BatchState([], dt, [], robots_meet)
        self._bodies = BodyArrays(self.space, [])
        self._poses = np.zeros((0, 3))
        self._kernel_arguments()
        self._stale = False
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
        sensors = ["encoders", "mouse", "mouse2"] + [s.name for s in (*spec.ir, *spec.line, *spec.border, *spec.light)]
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
        st.reseed(robot)
        self._world["streak"] = 0
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
        st, walls, ir, floor = self._state, self._walls, self._state.ir, self.floor.kernel
        self._round_ir = self._round_bodies and len(ir.curve) > 0
        read = len(st.sensors) if self._round_ir else st.n_floor + st.n_light  # pymunk reads IR otherwise
        # quiet steps (`kernels.contacts.settle`, `kernels.motion.glide`) for one round robot and nothing else that
        # moves, whose contacts can only be with walls, met in their fixed order; the contacts of
        # several bodies come in the order of pymunk's tree of moving shapes, which a skipped step
        # would leave unchanged (the same physics, but other roundings later)
        alone = len(self.robots) == 1 and self._round_bodies and not self.movables
        self._world["streak"], self._world["quiet_after"] = 0, self.space.collision_persistence if alone else -1
        self._moved = (st.robots, st.state, st.tally_rows)
        """The tables `plan` and `measure` change a step's motion and counts in."""
        bodies = layout.Bodies(self._bodies.row_index, layout.motion_rows(self._bodies.motion))
        self._read_arguments = (layout.Sensing(st.sensors[:read], st.n_floor, self._lights), floor, walls, st.circles, ir.curves, ir.noise.kernel)
        self._settle_arguments = (st.robots, st.state, self._world, walls, floor, layout.Ground(st.contacts, st.anchored, st.fallen), bodies)
        self._glide_arguments = (st.robots, bodies, self._world)
        # the kernels each step calls, for the types they get then: C-ordered (n, 2) commands and
        # (n, 3) poses, int64 values and float believed distances (`compiling.compiled_for`; the largest last, see `compile_all`)
        pose, commands = self._poses, np.zeros((len(self.robots), 2))
        self._plan, self._glide, self._measure, self._settle, self._read_sensors = compile_all([
            (plan, (commands, *self._moved, pose, self._world)),
            (glide, (pose, *self._glide_arguments)),
            (measure, (pose, pose, *self._moved, floor)),
            (settle, (pose, *self._settle_arguments)),
            (read_sensors, (pose, *self._read_arguments, layout.Readout(np.empty(0, np.int64), np.empty(0)))),
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
                    st.circles["x"][k], st.circles["y"][k] = body.position
            self._read_sensors(pose, *self._read_arguments, layout.Readout(values, believed))
        else:  # without the IR rows: pymunk reads them below
            self._read_sensors(pose, *self._read_arguments, layout.Readout(values[:lights], believed[:0]))
        floor, light, ir_raw = values[: st.n_floor], values[st.n_floor : lights], values[lights:]
        if st.noisy_floor_or_light:
            st.floor_noise.add_rounded(floor, CNY70_MAX)
            st.light_noise.add_rounded(light, LDR_MAX)
        if not self._round_ir:
            self._read_ir_with_pymunk(pose, ir_raw, believed)
        frame = SensorFrame(self.time, tallies, ir_raw, believed, floor, light, st.layout)
        if self.chassis.drives:
            self.chassis.fill(frame)
        return frame

    def ray_distance(self, robot: Robot, origin, direction: float, length: float = IR_RAY_LENGTH, cone: float = 0.0, axis: bool = False) -> float:
        """Distance (m) from `origin` to the nearest point of any body other than the robot's own
        within `cone` (rad, half-angle) of world `direction` and within `length`; inf if none.
        With `axis`, walls are seen only where the axis meets them and at their corners inside
        the cone (`IRSensorSpec.view`); other bodies in the whole cone.

        A cone across a wall at a slant reads the cone's near edge, not the axis. Every body is
        convex, so its nearest point in the cone is its nearest point overall when that lies
        inside the cone, else where an edge ray first meets it: two rays and one nearest-point
        query are exact."""
        if cone <= 0.0:
            return self._cast(robot, origin, direction, length)
        c, s = math.cos(direction), math.sin(direction)
        cos_cone = math.cos(cone)
        if axis:
            best = min(self._cast(robot, origin, direction, length), self._wall_corner_in_cone(origin, c, s, cos_cone))
        else:
            best = min(self._cast(robot, origin, direction - cone, length), self._cast(robot, origin, direction + cone, length))
        for info in self.space.point_query((origin[0], origin[1]), min(best, length), robot.query_filter):
            dx, dy = info.point.x - origin[0], info.point.y - origin[1]
            if info.distance <= 0.0:
                return 0.0  # the sensor is inside another body
            if axis and info.shape.body.body_type == pymunk.Body.STATIC:
                continue  # a wall: seen on the axis and at its corners only
            if dx * c + dy * s >= cos_cone * info.distance:
                best = min(best, info.distance)
        return best if best <= length else math.inf

    def _wall_corner_in_cone(self, origin, c: float, s: float, cos_cone: float) -> float:
        """Distance to the nearest wall corner within the cone from `origin` about (c, s)."""
        corners = self._walls.vertices - np.asarray(origin, dtype=np.float64)
        distance = np.hypot(corners[:, 0], corners[:, 1])
        inside = corners[:, 0] * c + corners[:, 1] * s >= cos_cone * distance
        return float(distance[inside].min()) if inside.any() else math.inf

    def _cast(self, robot: Robot, origin, direction: float, length: float) -> float:
        """Distance (m) along one ray to the first body other than the robot's own; inf if none."""
        end = (origin[0] + length * math.cos(direction), origin[1] + length * math.sin(direction))
        hit = self.space.segment_query_first((origin[0], origin[1]), end, 0.0, robot.query_filter)
        return hit.alpha * length if hit is not None else math.inf

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
        sensors = st.sensors[st.n_floor + st.n_light :]
        origins, look, distance = np.empty((n, 2)), np.empty(n), np.empty(n)
        ir_rays(pose, sensors, origins, look)
        for k, (robot, sensor) in enumerate(st.ir_sensors):
            distance[k] = self.ray_distance(robot, origins[k], look[k], cone=sensor.cone, axis=sensor.view == "axis")
        ir_values(distance, sensors, ir.noise.kernel, ir.curves, raw, believed)

    # --- motion -----------------------------------------------------------------------------

    def step(self, commands: np.ndarray) -> None:
        """Advance the world by dt with signed motor commands (n_robots, 2) = (left, right); robots on
        a general chassis ignore theirs and drive what `self.chassis.command` set."""
        commands = np.ascontiguousarray(commands, dtype=np.float64)  # (the layout `_plan` was compiled for)
        if commands.shape != (len(self.robots), 2):
            raise CommandError(f"expected motor commands of shape ({len(self.robots)}, 2), got {commands.shape}")
        st = self._batch()
        before = self._poses
        bad = first_bad(commands) if st.noisy_encoders else -1  # a refused step draws no noise
        if bad < 0:
            if st.noisy_encoders:
                st.draw_encoder_noise()
            bad = self._plan(commands, *self._moved, before, self._world)
            if bad < 0 and st.noisy_encoders:
                st.add_spurious_ticks()
        if bad >= 0:
            names = [self.robots[i].name for i in np.unique(np.nonzero(~np.isfinite(commands))[0])]
            raise CommandError(f"non-finite motor command for {', '.join(names)} at step {self.steps}")
        if self.chassis.drives:
            self.chassis.drive(self.time, before, st.move, st.alpha)
        # cut each exact-arc move where the body would first sink deeper than SWEEP_CLEARANCE into
        # a wall or another robot, so that no speed the motors allow tunnels through anything
        # then hold robots at holes, and give pymunk the motion as forces (see `_apply_motion`)
        self._bodies.refresh()
        was_blocked = st.state["blocked"][st.stoppers] if len(st.stoppers) else None
        changed, quiet = self._settle(before, *self._settle_arguments)
        if was_blocked is not None:  # a robot newly stopped by c't-Sim's rule has met something
            for i in st.stoppers[st.state["blocked"][st.stoppers] & ~was_blocked]:
                self.robots[i].collisions += 1
        if changed:
            for robot in self.robots:
                robot.fallen = bool(st.fallen[robot.index])
        if quiet:  # nothing to collide: pymunk's motion without pymunk (a third of a bare robot's step)
            after = self._poses = self._glide(before, *self._glide_arguments)
            self._bodies.place(after)
        else:
            self._apply_motion()
            after = self._poses = self._bodies.poses()
        if len(st.noisy_mice.rows):
            st.draw_mouse_noise()
        self._measure(before, after, *self._moved, self.floor.kernel)
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
    """The side (m) of the wall grid's square cells for walls of BOXES `boxes`:
    cells of WALLS_PER_CELL walls' share of the walls' extent, so that the grid has about
    n / WALLS_PER_CELL cells whatever the world's size and a query meets the walls near it; at
    least 1/n of the extent's longer side (a thin extent has n cells at most along it)."""
    n = len(boxes)
    if n == 0:
        return 1.0
    width, height = boxes["xmax"].max() - boxes["xmin"].min(), boxes["ymax"].max() - boxes["ymin"].min()
    return max(math.sqrt(WALLS_PER_CELL * width * height / n), max(width, height) / n, 1e-9)


def _walls(spec: WorldSpec) -> layout.Walls:
    """The walls as flat arrays for the kernels: all vertices, each wall's SPANS of them, its BOXES
    and a uniform grid over the boxes (`kernels.grids.build_wall_grid`; walls are static, so it is
    built once)."""
    polygons = [np.asarray(w.vertices, dtype=np.float64) for w in spec.walls]
    spans, boxes = layout.SPANS.new(len(polygons)), layout.BOXES.new(len(polygons))
    spans["end"] = np.cumsum([len(p) for p in polygons], dtype=np.int64)
    spans["start"] = spans["end"] - np.array([len(p) for p in polygons], dtype=np.int64)
    for name, values in zip(("xmin", "ymin", "xmax", "ymax"), np.array([(*p.min(axis=0), *p.max(axis=0)) for p in polygons]).reshape(-1, 4).T):
        boxes[name] = values
    vertices = np.concatenate(polygons).reshape(-1, 2) if polygons else np.zeros((0, 2))
    return gridded(vertices, spans, boxes, wall_cell(boxes) if len(boxes) > WALL_GRID_ABOVE else math.inf)  # one cell: the plain loop


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


class _BatchState:
    """Per-robot parameters and state as arrays for the kernels (rebuilt when a robot joins):
    packed into a few 2-D arrays in the column layout of `sim.world.layout` (one argument each
    per kernel call), with named views of the columns the Python side uses."""

    def __init__(self, robots: list[Robot], dt: float, movable_shapes: list[pymunk.Circle], robots_meet: bool = True):
        n = len(robots)
        specs = [r.spec for r in robots]
        motor = [s.motor for s in specs]
        self.robots = p = layout.ROBOTS.new(n)
        p["command_max"] = [m.command_max for m in motor]
        p["max_speed"] = [m.max_wheel_speed for m in motor]
        p["lag"] = [1.0 - math.exp(-dt / m.time_constant) if m.time_constant > 0 else 1.0 for m in motor]
        p["max_change"] = [m.max_acceleration * dt for m in motor]
        p["ticks_per_rad"] = [s.encoders.ticks_per_rev / (2 * math.pi) for s in specs]
        p["real_radius"] = np.array([[s.wheel_radius * (1 + e) for e in s.encoders.diameter_error] for s in specs]).reshape(n, 2)
        p["track"] = [s.track_width * (1 + s.encoders.track_error) for s in specs]
        p["mount"] = np.array([s.mouse.mount if s.mouse else (0.0, 0.0) for s in specs], dtype=np.float64).reshape(n, 2)
        p["counts_per_metre"] = [counts_per_metre(s.mouse.dpi) * (1 + s.mouse.scale_error) if s.mouse else 0.0 for s in specs]
        p["max_step"] = [s.mouse.max_speed * dt if s.mouse else 0.0 for s in specs]
        p["sweep_radius"] = [s.body_radius - SWEEP_CLEARANCE for s in specs]
        p["apart_radius"] = [s.body_radius - SWEEP_CLEARANCE / 2 for s in specs]
        p["mass"] = [r.body.mass for r in robots]
        p["moment"] = [r.body.moment for r in robots]
        p["radius"] = [s.body_radius for s in specs]
        p["stops"] = [s.contact == "stop" for s in specs]
        self.stoppers = np.flatnonzero(p["stops"])
        """The robots with c't-Sim's contact rule (a refused move counts as a collision)."""
        self.contacts = _padded([_contacts(s)[0] for s in specs], np.float64, (2,))
        self.anchored = _padded([_contacts(s)[1] for s in specs], np.bool_)
        self.state = layout.STATE.new(n)
        self.slip, self.mouse_noise, self.move, self.alpha = (self.state[name] for name in ("slip", "mouse_noise", "move", "alpha"))
        self.tallies = np.zeros((n, 4), dtype=np.int64)
        """Encoder ticks then mouse counts of the last step (what `World.tallies` gives)."""
        self.tally_rows = layout.tally_rows(self.tallies)
        """The same as TALLIES rows, for the kernels."""
        self.fallen = np.array([r.fallen for r in robots], dtype=np.bool_)
        self.noisy_encoders = [(r.index, r.rngs["encoders"], r.spec.encoders) for r in robots if r.spec.encoders.slip_std or r.spec.encoders.tick_noise]
        self.noisy_mice = _Noisy.of([(r.index, r, "mouse", r.spec.mouse.noise_std) for r in robots if r.spec.mouse is not None and r.spec.mouse.noise_std])

        floor = [(r, s) for r in robots for s in (*r.spec.line, *r.spec.border)]
        light = [(r, s) for r in robots for s in r.spec.light]
        ir = [(r, s) for r in robots for s in r.spec.ir]
        self.ir_sensors = ir
        self.n_floor, self.n_light = len(floor), len(light)
        every = floor + light + ir
        self.sensors = layout.SENSORS.new(len(every))
        rows = self.sensors
        rows["at"] = np.array([s.position for _, s in every], dtype=np.float64).reshape(-1, 2)
        rows["height"][: len(floor) + len(light)] = [s.height for _, s in floor + light]
        rows["direction"][len(floor) :] = [s.direction for _, s in light + ir]
        rows["opening"][len(floor) :] = [s.opening / 2 for _, s in light] + [s.cone for _, s in ir]
        rows["reach"][len(floor) : len(floor) + len(light)] = [s.reach for _, s in light]
        rows["axis"][len(floor) + len(light) :] = [s.view == "axis" for _, s in ir]

        def noisy(items):
            return _Noisy.of([(k, robot, s.name, s.noise_std) for k, (robot, s) in enumerate(items) if s.noise_std])

        self.floor_noise = noisy(floor)
        self.light_noise = noisy(light)
        self.noisy_floor_or_light = len(self.floor_noise.rows) + len(self.light_noise.rows) > 0
        self.ir = _IRArrays.build(ir, noisy(ir))
        rows["owner"] = [r.index for r, _ in every]
        rows["noise_row"][len(floor) + len(light) :] = self.ir.noise_row
        rows["curve"][len(floor) + len(light) :] = self.ir.curve
        owners = [r.index if robots_meet else layout.GHOST for r in robots if isinstance(r.shape, pymunk.Circle)] + [-1] * len(movable_shapes)
        self.circles = layout.CIRCLES.new(len(owners))
        self.circles["radius"] = [r.shape.radius for r in robots if isinstance(r.shape, pymunk.Circle)] + [shape.radius for shape in movable_shapes]
        self.circles["owner"] = owners
        """Robots then movable obstacles as CIRCLES for the IR kernel; positions are filled in at each read."""
        self.layout = SensorLayout.of([(len(s.ir), len(s.line), len(s.border), len(s.light)) for s in specs])

    def reseed(self, robot: Robot) -> None:
        """Draw `robot`'s noise from its (new) generators from now on."""
        self.noisy_encoders = [(i, robot.rngs["encoders"] if i == robot.index else rng, enc) for i, rng, enc in self.noisy_encoders]
        for noisy in (self.noisy_mice, self.floor_noise, self.light_noise, self.ir.noise):
            noisy.reseed(robot)

    def draw_encoder_noise(self) -> None:
        """Random slip for this step of the robots whose encoders have it: each wheel's arc s is
        off by slip_std * sqrt(|s|) * N(0, 1) (`kernels.motion.drive`), a random walk in the distance rolled."""
        for i, rng, enc in self.noisy_encoders:
            if enc.slip_std:
                self.slip[i] = enc.slip_std * rng.standard_normal(2)

    def add_spurious_ticks(self) -> None:
        """Each tick counted this step is, with probability tick_noise, one too many or one too few
        (a light barrier's edge that bounces or is missed): a process in the ticks counted, so
        the same per wheel turn at any step."""
        for i, rng, enc in self.noisy_encoders:
            if enc.tick_noise:
                ticks = self.tally_rows["ticks"][i]
                wrong = rng.binomial(np.abs(ticks), enc.tick_noise)
                if wrong.any():
                    ticks += 2 * rng.binomial(wrong, 0.5) - wrong

    def draw_mouse_noise(self) -> None:
        """Count noise for the robots whose mouse has it, in counts per sqrt m of floor passed
        (`kernels.motion.measure` scales it by the step's distance): noise_std (sqrt m) at the counts'
        own scale."""
        mice = self.noisy_mice
        scale = mice.std * self.robots["counts_per_metre"][mice.rows]
        self.mouse_noise[mice.rows] = 0.0 + scale[:, None] * mice.normals.take(2)


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
    """Per curve: the last centimetre of its table and its lowest raw value (CURVE_ENDS)."""
    beyond: np.ndarray
    inverse: np.ndarray

    @property
    def curves(self) -> layout.Curves:
        """The curves as `kernels.sensing.ir_values` takes them."""
        return layout.Curves(IR_RAY_LENGTH, self.tables, self.curve_ends, self.beyond, self.inverse)

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
            curve_ends=_curve_ends([(len(t) - 1, table.raw_range()[0]) for t, (table, _, _) in zip(per_cm, chosen)]),
            beyond=np.array([table.beyond for table, _, _ in chosen], dtype=np.float32),
            inverse=inverses,
        )


def _curve_ends(ends: list[tuple[int, int]]) -> np.ndarray:
    """CURVE_ENDS rows of (last, lowest) pairs."""
    rows = layout.CURVE_ENDS.new(len(ends))
    if ends:
        rows["last"], rows["lowest"] = zip(*ends)
    return rows
