"""The world's packed tables, each declared once: a row per field (name, width, unit, kind).

A kernel call costs tens of nanoseconds per argument, so a world's step passes its per-robot and
per-sensor values packed into a few tables, one numpy structured array each (MuJoCo's `mjModel`
and pymunk's `BodyFields` are the models: one declaration with meaning and shape). The compiled
kernels (`sim.world.kernels`) read a row's fields by name (`robots[i].mass`, `state[i].move[0]`),
the World (`sim.world.physics`) fills them by name (`robots["mass"] = ...`); ints stay int64 and
flags bool, so nothing is an offset typed by hand (`sim.kinematics.packed` declares them).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pymunk.batch

from sim.kinematics.packed import Field, Table

ROBOTS = Table(
    "per robot: what stays fixed once the robots are in",
    Field("command_max", 1, "motor command units"),
    Field("max_speed", 1, "rad/s, a wheel at command_max"),
    Field("lag", 1, "fraction of the way to the target speed per step"),
    Field("max_change", 1, "rad/s per step"),
    Field("ticks_per_rad", 1, "encoder ticks per wheel radian"),
    Field("real_radius", 2, "m, left and right wheel"),
    Field("track", 1, "m, the real track width"),
    Field("mount", 2, "m, the mouse's x, y in the body frame"),
    Field("counts_per_metre", 1, "mouse counts per m (0: no mouse)"),
    Field("max_step", 1, "m, the longest step the mouse tracks"),
    Field("sweep_radius", 1, "m, the body radius walls are swept with"),
    Field("apart_radius", 1, "m, the body radius robots keep apart by"),
    Field("mass", 1, "kg"),
    Field("moment", 1, "kg m^2"),
    Field("radius", 1, "m, the body radius"),
    Field("stops", 1, "c't-Sim's contact rule (`stop_at_contact`) rather than pymunk's", np.bool_),
)
STATE = Table(
    "per robot: what a step changes",
    Field("wheel_speed", 2, "rad/s, left and right at the end of the step"),
    Field("tick_carry", 2, "encoder ticks not yet counted"),
    Field("slip", 2, "sqrt m, this step's random slip per wheel"),
    Field("mouse_noise", 2, "counts per sqrt m, this step's mouse noise (x, y)"),
    Field("mouse_carry", 2, "mouse counts not yet counted"),
    Field("move", 2, "m, the step's planned world displacement"),
    Field("alpha", 1, "rad, the step's planned heading change"),
    Field("blocked", 1, "c't-Sim's contact rule refused the step's move", np.bool_),
)
TALLIES = Table(
    "per robot: the counts of the last step (the same bytes as `World.tallies`' (n, 4) int64)",
    Field("ticks", 2, "encoder ticks, left and right", np.int64),
    Field("counts", 2, "mouse counts, x and y", np.int64),
)
WORLD = Table(
    "the world's scalars, one row",
    Field("dt", 1, "s, the step: the kernels' one source of it"),
    Field("slide_margin", 1, "m, how much thinner the sweep of a slide is"),
    Field("robots_meet", 1, "robots see and stop each other", np.bool_),
    Field("streak", 1, "steps in a row that began with no robot touching a wall", np.int64),
    Field("quiet_after", 1, "such steps pymunk still takes (-1: every step is pymunk's)", np.int64),
)
SENSORS = Table(
    "per sensor of every robot: floor, then light, then IR sensors",
    Field("at", 2, "m, the mount in the body frame"),
    Field("height", 1, "m above the floor (floor, light)"),
    Field("direction", 1, "rad, the view in the body frame (light, IR)"),
    Field("opening", 1, "rad, the half opening (light) or cone (IR)"),
    Field("reach", 1, "m, the distance of full darkness (light)"),
    Field("pick", 1, "a light or IR sensor of the 'pick' view: lamps or walls seen as c't-Sim's Java3D pick", np.bool_),
    Field("owner", 1, "the robot's index", np.int64),
    Field("noise_row", 1, "the sensor's row of the IR noise (-1: none)", np.int64),
    Field("curve", 1, "the IR curve's index", np.int64),
)
CIRCLES = Table(
    "robots, then movable obstacles, as circles the IR sensors see",
    Field("x", 1, "m"),
    Field("y", 1, "m"),
    Field("radius", 1, "m"),
    Field("owner", 1, "the robot's index, GHOST for a robot no sensor sees, -1 for an obstacle", np.int64),
)
GHOST = -2
"""The owner of a robot's circle that no sensor sees (a world of robots that do not meet, `sense_ir`)."""
LIGHTS = Table("lamps", Field("x", 1, "m"), Field("y", 1, "m"), Field("height", 1, "m"), Field("radius", 1, "m"))
BOXES = Table("the walls' bounding boxes", Field("xmin", 1, "m"), Field("ymin", 1, "m"), Field("xmax", 1, "m"), Field("ymax", 1, "m"),
              Field("cylinder", 1, "the wall is a Java3D cylinder (`Wall.cylinder`)", np.bool_))
SPANS = Table("each wall's vertices", Field("start", 1, "the first vertex", np.int64), Field("end", 1, "one past the last", np.int64))
CURVE_ENDS = Table("each IR curve's table", Field("last", 1, "cm, its last entry", np.int64), Field("lowest", 1, "its lowest raw value", np.int64))
MOTION = Table(
    "per body of pymunk's walk: the fields of pymunk.batch.BodyFields that `sim.world.bodies` reads and writes, in their order",
    Field("velocity", 2, "m/s"),
    Field("angular_velocity", 1, "rad/s"),
    Field("force", 2, "N"),
    Field("torque", 1, "N m"),
)
MOTION_FIELDS = pymunk.batch.BodyFields.VELOCITY | pymunk.batch.BodyFields.ANGULAR_VELOCITY | pymunk.batch.BodyFields.FORCE | pymunk.batch.BodyFields.TORQUE
"""The pymunk fields of MOTION (pymunk walks them in the order of their flags)."""


def motion_rows(floats: np.ndarray) -> np.ndarray:
    """pymunk's (bodies, 6) motion floats seen as MOTION rows (the same memory)."""
    return floats.view(MOTION.dtype).reshape(len(floats))


def tally_rows(tallies: np.ndarray) -> np.ndarray:
    """The (n, 4) int64 tallies seen as TALLIES rows (the same memory)."""
    return tallies.view(TALLIES.dtype).reshape(len(tallies))


GRID = Table(
    "the wall grid's frame, one row (its cells: the starts of each cell's list, rows x columns + 1, then the members, then a buffer)",
    Field("x", 1, "m, the grid's origin"),
    Field("y", 1, "m"),
    Field("cell", 1, "m, a cell's side"),
    Field("columns", 1, "cells along x", np.int64),
    Field("rows", 1, "cells along y", np.int64),
)


class BoundsTree(NamedTuple):
    """Java3D's bounds tree over c't-Sim's scene for the compiled pick (`sim.world.bounds_tree`),
    the root first: each node's box (m, Java3D's world frame: the floor at z -2), its children
    (right, left; -1 for a leaf), its parent (-1 for the root), the wall vertex whose edge's face
    (or pillar) a leaf is and that wall's index (-1: none), the lamp whose sphere a leaf is (-1:
    none), and each robot's leaves (robots, shapes; -1: none)."""

    lower: np.ndarray
    upper: np.ndarray
    kids: np.ndarray
    parent: np.ndarray
    face: np.ndarray
    wall: np.ndarray
    lamp: np.ndarray
    robot_leaves: np.ndarray


class Walls(NamedTuple):
    """The walls for the kernels: convex polygons vertices[spans[w].start:spans[w].end], their
    bounding boxes, and the uniform grid over the boxes (`kernels.grids.build_wall_grid`). (The
    bounds tree c't-Sim's picks walk is `Sensing.tree`: the contact kernels, which take the walls
    every step, would pay for its eight arrays on every call.)"""

    vertices: np.ndarray
    spans: np.ndarray
    boxes: np.ndarray
    frame: np.ndarray
    cells: np.ndarray


class Floor(NamedTuple):
    """The floor raster for the kernels (`sim.world.floor.FloorMap`): the ground's absorption
    without its lines, the lines' own (NaN off every line; their top `line_height` m above the
    ground), the holes."""

    ground: np.ndarray
    lines: np.ndarray
    hole: np.ndarray
    origin: np.ndarray
    cell: float
    outside_absorption: float
    outside_is_hole: bool
    line_height: float


class Ground(NamedTuple):
    """The ground contacts the hole rule checks: body-frame points (n, m, 2), which of them c't-Sim
    checks at the old position (n, m), and whether each robot is held over a hole now (n,)."""

    contacts: np.ndarray
    anchored: np.ndarray
    fallen: np.ndarray


class Bodies(NamedTuple):
    """The robots' rows in pymunk's walk over the bodies, the walk's MOTION rows, and the robots
    then movable obstacles as CIRCLES (the cans where they stand, for c't-Sim's contact rule)."""

    rows: np.ndarray
    motion: np.ndarray
    circles: np.ndarray


class Sensing(NamedTuple):
    """The sensors to read (SENSORS rows: the first `floor` ones floor sensors, then light, then
    IR sensors), the lamps the light sensors see, the CIRCLES the IR sensors see (robots first,
    their positions taken from the poses) and the bounds tree over a c't-Sim parcours that the
    picks walk (`BoundsTree`; None in other worlds, whose kernels numba then compiles without the
    tree's code and which pass none of its arrays)."""

    sensors: np.ndarray
    floor: int
    lights: np.ndarray
    circles: np.ndarray
    tree: BoundsTree | None


class Curves(NamedTuple):
    """The IR sensors' curves: how far a ray is cast (m), each distinct (curve, range)'s per-cm
    float32 table padded into one array, its CURVE_ENDS, the value beyond it and its inverse per
    raw value."""

    length: float
    tables: np.ndarray
    ends: np.ndarray
    beyond: np.ndarray
    inverse: np.ndarray


class Noise(NamedTuple):
    """Noisy sensors of one kind: each one's row among the kind's values (or its robot), standard
    deviation (or scale) and its generator's normals, each row's next one at `used`."""

    rows: np.ndarray
    std: np.ndarray
    normals: np.ndarray
    used: np.ndarray


class Rays(NamedTuple):
    """IR rays: world origins (m, 2), view directions (m,), cones (half-angle, m,), the robot each
    belongs to (m,), and whether it sees walls as c't-Sim's cone pick does (m,)."""

    origins: np.ndarray
    look: np.ndarray
    cone: np.ndarray
    owner: np.ndarray
    pick: np.ndarray


class ScanModel(NamedTuple):
    """A map-aided localiser's model of one IR scan (`sim.world.localising`): how far a ray is cast
    (m), each sensor's raw value's distance intervals (sensors, INTERVALS, 2; m, nan-padded), the
    standard deviation (m) and outlier mass per sensor, and the radius (m) a particle's body keeps
    clear of walls."""

    length: float
    intervals: np.ndarray
    sigma: np.ndarray
    outlier: np.ndarray
    radius: float


class Readout(NamedTuple):
    """Where the sensors' readings go: every row's integer value, and every IR sensor's believed distance (m)."""

    values: np.ndarray
    believed: np.ndarray
