"""A world as plain data: what a world file describes, before any physics is built from it.

Everything is in metres and radians, world frame x right, y up. Loaders (`sim.world.files`) produce a
`WorldSpec`; `sim.world` turns one into a pymunk space. Colours are RGB triples in 0..1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from bots.schema import FileError

Point = tuple[float, float]
Colour = tuple[float, float, float]

DEFAULT_FLOOR: Colour = (0x60 / 255, 0x60 / 255, 0x60 / 255)  # c't-Sim's normal floor, #606060
BLACK: Colour = (0.0, 0.0, 0.0)
WHITE: Colour = (1.0, 1.0, 1.0)


class WorldFileError(FileError):
    """A user mistake in a world file; `str()` reads `file:line: problem` for the command line."""

    def __init__(self, path: str | Path | None, line: int | None, problem: str):
        super().__init__(path if path is not None else "<world>", line, problem)


@dataclass(frozen=True)
class Wall:
    """A static obstacle: a convex polygon (counter-clockwise vertices, m). `cylinder`: the
    polygon is a Java3D cylinder's cross-section (c't-Sim's lamp pillar, `sim.world.files.grid`),
    which c't-Sim's contact test meets at the box round its corners and its IR sensors see as the
    triangle strip of its side (`sim.world.kernels.pick`)."""

    vertices: tuple[Point, ...]
    colour: Colour = (0.6, 0.6, 0.6)
    cylinder: bool = False


@dataclass(frozen=True)
class FloorRegion:
    """A convex floor patch of one colour; later regions paint over earlier ones."""

    vertices: tuple[Point, ...]
    colour: Colour


@dataclass(frozen=True)
class FloorLine:
    """A painted line on the floor: a polyline of `width` metres (c't-Sim: 2.4 cm, black).
    `flat`: each segment ends square at its end points (c't-Sim's line tiles, which end at their
    cell's edge); otherwise the ends and joints are round, half the width past the points."""

    points: tuple[Point, ...]
    width: float = 0.024
    colour: Colour = BLACK
    flat: bool = False


@dataclass(frozen=True)
class Hole:
    """A convex hole in the floor. As in c't-Sim a robot never drives over it: a move that would
    bring its skid or a wheel over it is refused (see `kernels.floor.hold_at_holes`)."""

    vertices: tuple[Point, ...]


@dataclass(frozen=True)
class Light:
    """A lamp: a sphere of `radius` (m) whose centre is `height` m above `position` (m); c't-Sim's
    lamps are 7 cm spheres 0.5 m up, and its light sensors measure to their surface."""

    position: Point
    height: float = 0.5
    radius: float = 0.07


@dataclass(frozen=True)
class Start:
    """A start pose (x, y m; heading rad, counter-clockwise from +x). `slot` 0 is the default slot."""

    x: float
    y: float
    heading: float
    slot: int = 0


@dataclass(frozen=True)
class Goal:
    """A goal area: convex polygon; a robot whose centre is inside has reached it. `slot` 0 is
    every robot's goal; a goal of slot k only that of the robot that started from slot k (a
    contest world gives each side its own)."""

    vertices: tuple[Point, ...]
    slot: int = 0
    box: tuple[float, float, float, float] = field(init=False, repr=False, compare=False)
    """(xmin, ymin, xmax, ymax): most points the run loop asks about are outside it."""

    def __post_init__(self) -> None:
        xs, ys = [v[0] for v in self.vertices], [v[1] for v in self.vertices]
        object.__setattr__(self, "box", (min(xs), min(ys), max(xs), max(ys)))

    def contains(self, x: float, y: float) -> bool:
        """Whether (x, y) is inside or on the edge (the point is on one side of every edge; plain
        floats: the run loop asks every step, where numpy's per-call cost would dominate)."""
        xmin, ymin, xmax, ymax = self.box
        if not (xmin <= x <= xmax and ymin <= y <= ymax):
            return False
        above = below = False
        vertices = self.vertices
        for k, (ax, ay) in enumerate(vertices):
            bx, by = vertices[k + 1 - len(vertices)]
            cross = (bx - ax) * (y - ay) - (by - ay) * (x - ax)
            above |= cross > 0
            below |= cross < 0
        return not (above and below)


@dataclass(frozen=True)
class SceneShape:
    """One shape of c't-Sim's Java3D scene as its bounds tree holds it (`sim.world.bounds_tree`):
    its bounding box (m) in Java3D's world frame, where c't-Sim's floor lies at z = -2
    (`JAVA3D_FLOOR`), computed in the float arithmetic c't-Sim builds it with; `face` is the
    wall vertex that starts the wall edge this shape is the upright face of (an index into the
    world's wall vertices, in `WorldSpec.walls` order), or the first vertex of the pillar whose
    side it is; -1 for any other shape (floor, lines, lamps, wall tops). `lamp`: the index (in
    `WorldSpec.lights`) of the lamp whose sphere it is, -1 for any other shape."""

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]
    face: int = -1
    lamp: int = -1


JAVA3D_FLOOR = -2.0
"""m: z of c't-Sim's floor in its Java3D world (its World's worldTG moves the scene 2 m down)."""


@dataclass(frozen=True)
class Movable:
    """A movable round obstacle (a c't-Sim 'can', 30 mm across): centre (m), radius (m), mass (kg)."""

    position: Point
    radius: float = 0.015
    mass: float = 0.05


FAULT_KINDS = ("lock", "free", "steering")
"""lock: the wheel seizes (φ̇ = 0); free: its drive fails and it rolls free; steering: its steering
freezes where it stands (thesis 2.2.2.2, failure table; lock per its note 906)."""


@dataclass(frozen=True)
class WheelFault:
    """A wheel of a general chassis fails at `time` (s): "lock" (seizes), "free" (its drive fails and it
    rolls free) or "steering" (its steering freezes); `robot` is the robot's index in the world (0-based)."""

    time: float
    wheel: int
    kind: str
    robot: int = 0


@dataclass(frozen=True)
class WorldSpec:
    """A complete world. `bounds` = (xmin, ymin, xmax, ymax); outside it the floor is a hole when
    `outside_is_hole` (c't-Sim worlds) and plain floor otherwise."""

    name: str
    bounds: tuple[float, float, float, float]
    walls: tuple[Wall, ...] = ()
    floor: tuple[FloorRegion, ...] = ()
    lines: tuple[FloorLine, ...] = ()
    holes: tuple[Hole, ...] = ()
    lights: tuple[Light, ...] = ()
    starts: tuple[Start, ...] = ()
    goals: tuple[Goal, ...] = ()
    movables: tuple[Movable, ...] = ()
    faults: tuple[WheelFault, ...] = ()
    floor_colour: Colour = DEFAULT_FLOOR
    outside_is_hole: bool = False
    scene: tuple[SceneShape, ...] = ()
    """c't-Sim's Java3D scene of a parcours in the order Java3D's bounds tree takes its shapes
    (bots aside); empty for any other world. The IR pick of a bridge robot walks the tree built
    from it (`sim.world.bounds_tree`)."""
    line_height: float = 0.0
    """How far (m) the painted lines' top stands above the floor: c't-Sim's line tiles lie 1 mm
    above its floor tiles, so a floor sensor's slanted rays meet a line nearer the mount point
    than the floor (`kernels.sample_floor`); 0 is paint."""
    source: str | None = None
    description: str = ""
    notes: tuple[str, ...] = ()
    """What the loader read past but a user should hear of (an unknown XML tag: a misspelt `<line>`
    drops a map row); `world_warnings` lists them first."""

    def start_order(self) -> list[Start]:
        """The starts in the order robots take them, as c't-Sim hands out its slots: slots 1, 2,
        ... that the world names, then the default slot 0 (per slot the last start counts)."""
        by_slot = {s.slot: s for s in self.starts}
        return [by_slot[k] for k in sorted(by_slot) if k > 0] + ([by_slot[0]] if 0 in by_slot else [])

    def in_goal(self, x: float, y: float, slot: int | None = None) -> bool:
        """Whether (x, y) is in a goal area of the robot from start `slot` (goals of slot 0 and
        of `slot`; None: any goal)."""
        for goal in self.goals:  # (a loop, not any(): the run loop asks every step)
            if (slot is None or goal.slot in (0, slot)) and goal.contains(x, y):
                return True
        return False

    def goals_of(self, slot: int | None) -> tuple[Goal, ...]:
        """The goal areas of the robot from start `slot` (as `in_goal` counts them)."""
        return tuple(goal for goal in self.goals if slot is None or goal.slot in (0, slot))

    def start_for(self, index: int) -> Start:
        """The start pose of the `index`-th robot (0-based) from `start_order`. Where the world
        has no start left, c't-Sim would put the robot on top of another one: refused."""
        order = self.start_order()
        if not order:
            raise WorldFileError(self.source, None, "the world has no start pose")
        if index >= len(order):
            raise WorldFileError(
                self.source, None,
                f"no start for robot {index + 1}: the world has {len(order)} start slot(s) and c't-Sim would put "
                "this robot on top of another; add a start (slot 1, 2, ...) to the world or give the robot a start pose",
            )  # fmt: skip
        return order[index]


def box(xmin: float, ymin: float, xmax: float, ymax: float) -> tuple[Point, ...]:
    """The counter-clockwise corners of an axis-aligned box."""
    return ((xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax))
