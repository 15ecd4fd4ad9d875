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
import zlib
from dataclasses import dataclass, field

import numpy as np
import pymunk

from bots.ir_curve import IRCurve, ir_curve_for
from bots.readings import ARRAYS, SensorFrame, frozen_copy
from bots.sensor_kinds import sections
from bots.spec import RobotSpec
from sim.world import layout
from sim.world.bodies import BodyArrays
from sim.world.bounds_tree import BoundsTree
from sim.world.chassis_drive import ChassisDrive
from sim.world.compiling import compile_all
from sim.world.floor import FloorMap, rasterize
from sim.world.kernels.contacts import settle, settle_meeting
from sim.world.kernels.motion import glide, measure, plan
from sim.world.kernels.noise import ENCODER_DRAWS, add_rounded, draw_step, spurious_ticks
from sim.world.kernels.pick import move_robot_leaves, pick_tree, pick_wall
from sim.world.kernels.sensing import CIRCLE_GRID_ABOVE, ir_rays, ir_values, read_sensors
from sim.world.spec import Start, WorldSpec
from sim.world.step import DEFAULT_DT, check_dt
from sim.world.tables import IR_RAY_LENGTH, SLIDE_MARGIN, SLOP, RobotTables, walls_of

MOVABLE_DAMPING = 0.05
"""Velocity fraction movable obstacles keep after a second: they slide a little and stop."""


ROBOT = 1
"""pymunk collision type of robot bodies (to count their contacts)."""
CTSIM_CONTACT = 1 << 1
"""pymunk category of the bodies of robots under c't-Sim's contact rule, which do not collide with
each other in pymunk: c't-Sim's rule meets another bot at its parts' boxes, which let two bots
mouth to mouth come 106.7 mm near, within their circles' 120 mm."""


class CommandError(ValueError):
    """A motor command that must not reach the physics (NaN, infinite, wrong shape)."""


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
    puts: int = 0
    """Times it was put down where its motion did not take it (`World.put_robot`, `reset_robot`):
    its true path breaks there (`RobotLog.puts`)."""

    @property
    def pose(self) -> np.ndarray:
        """Ground-truth pose (x, y m; heading rad, continuous)."""
        p = self.body.position
        return np.array((p.x, p.y, self.body.angle))


@dataclass(frozen=True)
class ReadingsPlan:
    """Where one robot's readings fields lie in the rows of `World.sensor_rows`' arrays: per field
    of ARRAYS, (array name, its slice) or (None, ...) for a field not read so; `tallies` the
    width of a tallies row. Plain data, so that a run's result keeps it without the world (a
    pickled result sent to another process)."""

    fields: tuple
    tallies: int

    def columns(self, values: np.ndarray, believed: np.ndarray, tallies: np.ndarray) -> dict[str, np.ndarray]:
        """The robot's readings fields (Readings' names, each (samples, width)) out of samples of
        the three arrays, each with a leading sample axis (views, no copies). A general chassis's
        per-wheel encoders, steering and second mouse are not among them (`ChassisDrive.fill`)."""
        rows = {"values": values, "believed": believed, "tallies": tallies.reshape(len(tallies), self.tallies)}  # (a run of no sample has rows of it too)
        return {field: rows[row][:, cut] for field, (row, cut) in zip(ARRAYS, self.fields) if row is not None}


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
        self.puts = 0
        """Robots put down where their motion did not take them so far, all robots' `Robot.puts`:
        one number for the run loop to watch per step."""
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
        self._walls = walls_of(spec)
        """The walls for the kernels."""
        self._bounds_tree = BoundsTree.of_scene(spec.scene) if spec.scene else None
        """Java3D's bounds tree over a c't-Sim parcours, which its picks walk (`sim.world.bounds_tree`); None for other worlds."""
        self._pick_tree = self._bounds_tree.kernel(0, self._walls.spans) if self._bounds_tree is not None else None
        """That tree as the kernels take it (`layout.BoundsTree`), None for other worlds."""
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
        self._state = RobotTables([], dt, [], robots_meet)
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
        query_filter = shape.filter
        if spec.contact == "stop" and self.robots_meet:  # two c't-Sim bots meet by c't-Sim's contact rule alone (`stop_at_contact`), not pymunk's circles
            shape.filter = pymunk.ShapeFilter(group=index + 1, categories=CTSIM_CONTACT, mask=pymunk.ShapeFilter.ALL_MASKS() ^ CTSIM_CONTACT)
        robot = Robot(
            index=index,
            name=name or (spec.name if index == 0 else f"{spec.name}{index}"),
            spec=spec,
            body=body,
            shape=shape,
            query_filter=query_filter,
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
        if self._bounds_tree is not None:  # c't-Sim's bot joins its scene's bounds tree where it starts
            self._bounds_tree.insert_robot(index, (x, y, heading))
            self._pick_tree = self._bounds_tree.kernel(len(self.robots), self._walls.spans)
        self._stale = True
        return robot

    def _start_pose(self, index: int, start: Start | tuple[float, float, float] | None) -> tuple[tuple[float, float, float], int | None]:
        """Robot `index`'s pose at `start` (default: its start slot) and the slot that is (None: a bare pose)."""
        if start is None:
            start = self.spec.start_for(index)
        return ((start.x, start.y, start.heading), start.slot) if isinstance(start, Start) else (tuple(start), None)

    def _sensor_rngs(self, spec: RobotSpec, index: int, seed: int | None) -> dict[str, np.random.Generator]:
        sensors = ["encoders", "mouse", "mouse2", PHASES] + [s.name for section in sections() for s in getattr(spec, section)]
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
        pose, robot.slot = self._start_pose(index, start)
        self._place(robot, pose)
        robot.collisions = 0
        st.state[index], st.tallies[index] = 0.0, 0
        robot.rngs = self._sensor_rngs(robot.spec, index, seed)
        robot.phases = start_phases(robot.spec, robot.rngs[PHASES])
        st.start_counters(robot)
        st.reseed(robot)
        return robot

    def put_robot(self, index: int, pose: tuple[float, float, float]) -> Robot:
        """Pick robot `index` up and put it down at `pose` (x, y m, heading rad) at rest, as a hand
        does (a kidnapping): its counters, motors and sensors' noise go on as they were (lifted,
        its wheels and mouse count nothing). ValueError where it would stand outside the world
        or overlap a wall or another body."""
        robot = self.robots[index]
        if robot.spec.chassis is not None:
            raise ValueError(f"{robot.name}: a robot on a general chassis cannot be put elsewhere in place")
        x, y, heading = (float(v) for v in pose)
        xmin, ymin, xmax, ymax = self.spec.bounds
        radius = robot.spec.body_radius
        if not (xmin + radius <= x <= xmax - radius and ymin + radius <= y <= ymax - radius and math.isfinite(heading)):
            raise ValueError(f"{robot.name} cannot stand at ({x:.3f}, {y:.3f}): outside the world")
        near = self.space.point_query_nearest((x, y), radius, robot.query_filter)  # (its own shape passes its filter)
        if near is not None:
            what = "a wall" if near.shape.body.body_type == pymunk.Body.STATIC else "another body"
            raise ValueError(f"{robot.name} cannot stand at ({x:.3f}, {y:.3f}): it would overlap {what}")
        self._batch()
        self._place(robot, (x, y, heading))
        return robot

    def _place(self, robot: Robot, pose: tuple[float, float, float]) -> None:
        """Move a robot's body to `pose` at rest, its contacts and hole flag forgotten, counted as a put."""
        x, y, heading = pose
        self.space.remove(robot.shape)  # pymunk forgets the shape's contacts (its arbiters) with it
        body = robot.body
        body.position, body.angle = (x, y), heading
        body.velocity, body.angular_velocity, body.force, body.torque = (0.0, 0.0), 0.0, (0.0, 0.0), 0.0
        self.space.add(robot.shape)
        self._poses[robot.index] = (x, y, heading)
        robot.fallen = False
        self._state.fallen[robot.index] = False
        self._world["streak"] = 0
        robot.puts += 1
        self.puts += 1

    @property
    def tallies(self) -> np.ndarray:
        """(n, 4) per robot: encoder ticks (left, right) and mouse counts (forward, left) of the
        last step, as `read_all` gives them (a view, overwritten by the next step)."""
        return self._batch().tallies

    def _batch(self) -> RobotTables:
        """The kernels' arrays, rebuilt once after robots joined (not once per robot added: a
        thousand robots would cost a million rows)."""
        if self._stale:
            self._state = RobotTables(self.robots, self.dt, self._movable_shapes, self.robots_meet)
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
        self._measure_arguments = (*self._moved, floor)
        self._flat_tallies = st.tallies.reshape(-1)
        """`tallies` flat (a view): a frame's copy of it is flat already."""
        self._stoppers = st.stoppers if len(st.stoppers) else None
        """The robots under c't-Sim's contact rule, None for none (the common case, checked every step)."""
        bodies = layout.Bodies(self._bodies.row_index, layout.motion_rows(self._bodies.motion), st.circles)
        # what a world of one c't-Bot in a maze does not need (a crowd's circle grid, cylinder walls,
        # c't-Sim's pick, robots keeping apart, c't-Sim's contact rule) is left out of its kernels:
        # numba prunes it (`read_sensors`' rare_parts None) or it has a kernel of its own
        # (`settle_meeting`), and a first run of the main job does not compile it
        rare_parts = True if len(st.circles) > CIRCLE_GRID_ABOVE or walls.boxes["cylinder"].any() or st.sensors["pick"].any() else None
        settling = settle_meeting if len(st.stoppers) or (len(self.robots) > 1 and self.robots_meet) else settle
        self._read_arguments = (layout.Sensing(st.sensors[:read], st.n_floor, self._lights, st.circles, self._pick_tree), floor, walls, ir.curves, ir.noise.kernel,
                                rare_parts)  # fmt: skip
        self._settle_arguments = (st.robots, st.state, self._world, walls, floor, layout.Ground(st.contacts, st.anchored, st.fallen), bodies)
        self._glide_arguments = (st.robots, bodies, self._world)
        self._step_noise_arguments = (st.step_noise.kernel, st.encoders, st.state, st.tick_uniforms)
        self._tick_noise_arguments = (st.step_noise.rows[: st.encoders], st.tick_noise, st.tick_uniforms, st.tally_rows)
        self._floor_and_light_arguments = (st.floor_and_light_noise.kernel, st.floor_and_light_top)
        # the kernels each step calls, for the types they get then: C-ordered (n, 2) commands and
        # (n, 3) poses, int64 values and float believed distances (`compiling.compiled_for`; the largest last, see `compile_all`)
        pose, commands = self._poses, np.zeros((len(self.robots), 2))
        (self._draw_step_noise, self._spurious_ticks, self._floor_and_light_noise,
         self._plan, self._glide, self._measure, self._settle, self._read_sensors) = compile_all([
            (draw_step, (commands, *self._step_noise_arguments)),
            (spurious_ticks, self._tick_noise_arguments),
            (add_rounded, (np.empty(len(st.sensors), np.int64), *self._floor_and_light_arguments)),
            (plan, (commands, *self._moved, pose, self._world)),
            (glide, (pose, *self._glide_arguments)),
            (measure, (pose, pose, *self._moved, floor)),
            (settling, (pose, *self._settle_arguments)),
            (read_sensors, (pose, *self._read_arguments, layout.Readout(np.empty(0, np.int64), np.empty(0)))),
        ])  # fmt: skip

    def poses(self) -> np.ndarray:
        """(n, 3) ground-truth poses of all robots (a copy)."""
        self._batch()
        return self._poses.copy()

    def poses_view(self) -> np.ndarray:
        """`poses` without the copy, for a caller that only reads them before the next step (which
        replaces them): the run loop, every step."""
        self._batch()
        return self._poses

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
        """Robot `index`'s readings fields out of samples of `sensor_rows`' arrays (`ReadingsPlan.columns`)."""
        return self.readings_plan(index).columns(values, believed, tallies)

    def readings_plan(self, index: int) -> ReadingsPlan:
        """Where robot `index`'s readings fields lie in the rows of `sensor_rows`' arrays."""
        st = self._batch()
        return ReadingsPlan(st.layout.plans[index], st.tallies.size)

    def read_all(self, rows: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> SensorFrame:
        """Every robot's sensor readings from the current state (the start of the next step):
        `frame[i]` is robot i's `Readings`. `rows`: one row of each of `sensor_rows`' arrays
        (values, believed, tallies) to read into, in place of new arrays: the frame then holds
        immutable copies of them (`frozen_copy`), never views into them."""
        st = self._batch()
        pose = self._poses
        if rows is None:
            values, believed, tallies = np.empty(len(st.sensors), dtype=np.int64), np.empty(len(st.ir.curve)), self._flat_tallies.copy()
        else:
            values, believed, tallies = rows
            tallies[...] = st.tallies  # (`[...]`: numpy's fast path; `[:]` makes a view first, twice the cost)
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
        if st.floor_and_light_noise.sensors:
            st.floor_and_light_noise.normals.reserve(1)
            self._floor_and_light_noise(values, *self._floor_and_light_arguments)
        if not self._round_ir:
            self._read_ir_with_pymunk(pose, values[lights:], believed)
        if rows is not None:
            values, believed, tallies = frozen_copy(values), frozen_copy(believed), frozen_copy(tallies)  # (flat copies)
        frame = SensorFrame(self.time, {"values": values, "believed": believed, "tallies": tallies}, st.layout)
        if self.chassis.drives:
            self.chassis.fill(frame)
        return frame

    def ray_distance(self, robot: Robot, origin, direction: float, length: float = IR_RAY_LENGTH, cone: float = 0.0, pick: bool = False) -> float:
        """Distance (m) from `origin` to the nearest point of any body other than the robot's own
        within `cone` (rad, half-angle) of world `direction` and within `length`; inf if none.
        With `pick`, walls are seen as c't-Sim's Java3D pick sees them (`IRSensorSpec.view`,
        `kernels.pick.pick_wall`, through Java3D's bounds tree in a c't-Sim parcours); other bodies
        in the whole cone.

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
            spans = zip(walls.spans["start"], walls.spans["end"], walls.boxes["cylinder"])
            if self._pick_tree is not None:
                move_robot_leaves(self._pick_tree, self.poses_view())
                best = pick_tree((origin[0], origin[1], c, s, length), math.tan(cone), walls, self._pick_tree)
            else:
                best = min((pick_wall((origin[0], origin[1], c, s, length), math.tan(cone), walls.vertices, a, b, round_) for a, b, round_ in spans), default=math.inf)
            best = min(best, self._cast(robot, origin, direction - cone, length, moving=True), self._cast(robot, origin, direction + cone, length, moving=True))
            limit = math.inf  # a find past the segment's end (a rim point, a pillar's far side) counts, as in the kernel
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
        sensors = st.sensors[st.n_floor + st.n_light :]
        origins, look, distance = np.empty((n, 2)), np.empty(n), np.empty(n)
        ir_rays(pose, sensors, origins, look)
        for k, (robot, sensor) in enumerate(st.ir_sensors):
            distance[k] = self.ray_distance(robot, origins[k], look[k], cone=sensor.cone, pick=sensor.view == "pick")
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
        bad = -1
        if st.step_noise.sensors:  # (a refused step draws no noise)
            st.step_noise.normals.reserve(ENCODER_DRAWS)
            bad = self._draw_step_noise(commands, *self._step_noise_arguments)
        if bad < 0:
            bad = self._plan(commands, *self._moved, before, self._world)
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
        stoppers = self._stoppers
        if stoppers is not None:
            if self.movables:  # c't-Sim's contact rule meets the cans where they stand
                for k, body in enumerate(self.movables, start=len(st.circles) - len(self.movables)):
                    st.circles["x"][k], st.circles["y"][k] = body.position
            was_blocked = st.state["blocked"][stoppers]
        changed, quiet = self._settle(before, *self._settle_arguments)
        if stoppers is not None:  # a robot newly stopped by c't-Sim's rule has met something
            for i in stoppers[st.state["blocked"][stoppers] & ~was_blocked]:
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
        self._measure(before, after, *self._measure_arguments)
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
        self._bodies.step(self.dt)
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
