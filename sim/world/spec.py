"""A world as plain data: what a world file describes, before any physics is built from it.

Everything is in metres and radians, world frame x right, y up. Loaders (`sim.world.files`) produce a
`WorldSpec`; `sim.world` turns one into a pymunk space. Colours are RGB triples in 0..1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

Point = tuple[float, float]
Colour = tuple[float, float, float]

DEFAULT_FLOOR: Colour = (0x60 / 255, 0x60 / 255, 0x60 / 255)  # c't-Sim's normal floor, #606060
BLACK: Colour = (0.0, 0.0, 0.0)
WHITE: Colour = (1.0, 1.0, 1.0)


class WorldFileError(Exception):
    """A user mistake in a world file; `str()` reads `file:line: problem` for the command line."""

    def __init__(self, path: str | Path | None, line: int | None, problem: str):
        self.path = str(path) if path is not None else "<world>"
        self.line = line
        self.problem = problem
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")


@dataclass(frozen=True)
class Wall:
    """A static obstacle: a convex polygon (counter-clockwise vertices, m)."""

    vertices: tuple[Point, ...]
    colour: Colour = (0.6, 0.6, 0.6)


@dataclass(frozen=True)
class FloorRegion:
    """A convex floor patch of one colour; later regions paint over earlier ones."""

    vertices: tuple[Point, ...]
    colour: Colour


@dataclass(frozen=True)
class FloorLine:
    """A painted line on the floor: a polyline of `width` metres (c't-Sim: 2.4 cm, black)."""

    points: tuple[Point, ...]
    width: float = 0.024
    colour: Colour = BLACK


@dataclass(frozen=True)
class Hole:
    """A convex hole in the floor; a robot with a wheel or its skid over it falls in."""

    vertices: tuple[Point, ...]


@dataclass(frozen=True)
class Light:
    """A point light source (position m, height above the floor m)."""

    position: Point
    height: float = 0.5


@dataclass(frozen=True)
class Start:
    """A start pose (x, y m; heading rad, counter-clockwise from +x). `slot` 0 is the default slot."""

    x: float
    y: float
    heading: float
    slot: int = 0


@dataclass(frozen=True)
class Goal:
    """A goal area: convex polygon; a robot whose centre is inside has reached it."""

    vertices: tuple[Point, ...]


@dataclass(frozen=True)
class Movable:
    """A movable round obstacle (a c't-Sim 'can'): centre (m), radius (m), mass (kg)."""

    position: Point
    radius: float = 0.025
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
    source: str | None = None
    description: str = ""

    def start_for(self, index: int) -> Start:
        """The start pose for the `index`-th robot (0-based): slot index+1 if the world names one,
        else the default slot, else the first start; c't-Sim's rule."""
        by_slot = {s.slot: s for s in self.starts}
        if not self.starts:
            raise WorldFileError(self.source, None, "the world has no start pose")
        return by_slot.get(index + 1) or by_slot.get(0) or self.starts[0]


def box(xmin: float, ymin: float, xmax: float, ymax: float) -> tuple[Point, ...]:
    """The counter-clockwise corners of an axis-aligned box."""
    return ((xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax))
