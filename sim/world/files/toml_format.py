"""ctsim's native world format: TOML a student can write by hand, in metres (worlds/README.md).

Every key of every table is declared once in FIELDS (type, unit, range; `bots.schema.Field`).
tomllib reports line numbers for syntax errors only, so `bots.schema.Locator` finds the line of
the N-th `[[wall]]` header or of a key inside it by scanning the text; every user mistake becomes
a WorldFileError(path, line, problem), never a traceback.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any, NoReturn

from bots.schema import MIN_LENGTH, MIN_MASS, WORLD_EXTENT, Field, Locator, Problem, read_toml
from sim.world.spec import (
    BLACK,
    DEFAULT_FLOOR,
    FAULT_KINDS,
    Colour,
    FloorLine,
    FloorRegion,
    Goal,
    Hole,
    Light,
    Movable,
    Point,
    Start,
    Wall,
    WheelFault,
    WorldFileError,
    WorldSpec,
)

from .geometry import bbox, convex_ccw, segment_box
from .grid import DEFAULT_CELL, KNOWN_TILES, GridPieces, build_grid

ARRAYS = ("wall", "floor", "line", "hole", "light", "start", "goal", "movable", "fault")
_REQUIRED: Any = object()
_POINT = Field("pair", "m", -WORLD_EXTENT, WORLD_EXTENT)
_AREA = {"box": Field("box", "m", -WORLD_EXTENT, WORLD_EXTENT), "polygon": Field("points", "m", -WORLD_EXTENT, WORLD_EXTENT, minimum=3)}
_SIZE = {"unit": "m", "low": MIN_LENGTH, "high": 10.0}
_SLOT = Field("integer", "start slot", 0, 10_000)
FIELDS: dict[str | None, dict[str, Field]] = {
    None: {"name": Field("text"), "description": Field("text"), "bounds": _AREA["box"], "floor_colour": Field("colour"),
           "outside_is_hole": Field("boolean"), "grid": Field("table"), **{name: Field("tables") for name in ARRAYS}},
    "wall": {**_AREA, "from": _POINT, "to": _POINT, "thickness": Field("number", **_SIZE), "colour": Field("colour")},
    "floor": {**_AREA, "colour": Field("colour")},
    "line": {"points": Field("points", "m", -WORLD_EXTENT, WORLD_EXTENT, minimum=2), "width": Field("number", **_SIZE), "colour": Field("colour")},
    "hole": _AREA,
    "light": {"position": _POINT, "height": Field("number", "m", 0.0, 100.0, above=True)},
    "start": {"position": _POINT, "heading_deg": Field("number", "deg", -3600.0, 3600.0), "heading": Field("number", "rad", -20 * math.pi, 20 * math.pi), "slot": _SLOT},
    "goal": {**_AREA, "slot": _SLOT},
    "movable": {"position": _POINT, "radius": Field("number", **_SIZE), "mass": Field("number", "kg", MIN_MASS, 10_000.0)},
    "fault": {"time": Field("number", "s", 0.0, 1e9), "robot": Field("integer", "index", 0, 1_000_000), "wheel": Field("integer", "index", 0, 1000),
              "kind": Field("text", choices=FAULT_KINDS)},
    "grid": {"cell": Field("number", **_SIZE), "origin": _POINT, "rows": Field("text"), "colours": Field("table")},
    "grid.colours": {tile: Field("colour") for tile in KNOWN_TILES},
}
"""Every key of a world file by table (None: the top level; `[[wall]]` tables under "wall"):
its type, unit and range."""
_WALL_COLOUR = Wall(()).colour


class _Table:
    """One TOML table with typed, located accessors: each bad value names its file and line."""

    def __init__(self, path: Path, where: Locator, name: str | None, index: int | None, data: dict):
        self.path, self.where, self.name, self.index, self.data = path, where, name, index, data

    @property
    def label(self) -> str:
        if self.name is None:
            return "top level"
        return f"[[{self.name}]] #{self.index + 1}" if self.index is not None else f"[{self.name}]"

    def line(self, key: str | None = None) -> int | None:
        return self.where.line(self.name, self.index, key)

    def fail(self, problem: str, key: str | None = None) -> NoReturn:
        raise WorldFileError(self.path, self.line(key), f"{self.label}: {problem}")

    def check_keys(self, allowed: Iterable[str]) -> None:
        allowed = tuple(allowed)
        for key in self.data:
            if key not in allowed:
                close = difflib.get_close_matches(key, allowed, n=1)
                hint = f"; did you mean `{close[0]}`?" if close else f"; expected one of {', '.join(allowed)}"
                self.fail(f"unknown key `{key}`{hint}", key)

    def raw(self, key: str, default: Any = _REQUIRED) -> Any:
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            self.fail(f"missing `{key}`")
        return default

    def value(self, key: str, default: Any = _REQUIRED) -> Any:
        """The key's value checked against its declared Field (FIELDS), or `default` when absent."""
        if key not in self.data:
            return self.raw(key, default)
        try:
            return FIELDS[self.name][key].check(self.data[key])
        except Problem as problem:
            self.fail(f"`{key}` {problem.message}", key)

    def check_declared(self) -> None:
        """Unknown keys refused, with the closest declared one."""
        self.check_keys(FIELDS[self.name])

    def area(self, *, segment: bool = False) -> tuple[Point, ...]:
        """A convex polygon from exactly one of `box`, `polygon` (or, for walls, `from`/`to`)."""
        given = [k for k in ("box", "polygon", "from") if k in self.data]
        options = "`box`, `polygon` or `from`/`to`" if segment else "`box` or `polygon`"
        if len(given) != 1:
            self.fail(f"give exactly one of {options}", given[1] if len(given) > 1 else None)
        if given[0] == "box":
            x0, y0, x1, y1 = self.value("box")
            if not (x0 < x1 and y0 < y1):
                self.fail("`box` is [xmin, ymin, xmax, ymax] with xmin < xmax and ymin < ymax", "box")
            return ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
        if given[0] == "polygon":
            ccw = convex_ccw(self.value("polygon"))
            if ccw is None:
                self.fail("`polygon` must be convex with a non-zero area", "polygon")
            return ccw
        p, q = self.value("from"), self.value("to")
        thickness = self.value("thickness", 0.02)
        if math.dist(p, q) == 0:
            self.fail("the wall has no length: `from` and `to` are the same point", "to")
        return segment_box(p, q, thickness)

    def child(self, key: str, data: Any, index: int | None = None) -> _Table:
        name = key if self.name is None else f"{self.name}.{key}"
        return _Table(self.path, self.where, name, index, data)


def load_toml(path: Path) -> WorldSpec:
    """Load a native TOML world file."""
    data, where = read_toml(path, WorldFileError)
    top = _Table(path, where, None, None, data)
    top.check_declared()
    name = top.value("name", path.stem)
    description = top.value("description", "").strip()
    outside_is_hole = top.value("outside_is_hole", False)
    tables = {name: _array(top, name) for name in ARRAYS}
    floor_colour = top.value("floor_colour", DEFAULT_FLOOR)
    grid = _grid(top.child("grid", top.data["grid"]), floor_colour) if "grid" in top.data else None

    walls = [Wall(t.area(segment=True), t.value("colour", _WALL_COLOUR)) for t in _keys(tables["wall"])]  # fmt: skip
    floor = [FloorRegion(t.area(), t.value("colour")) for t in _keys(tables["floor"])]  # fmt: skip
    lines = [_line(t) for t in _keys(tables["line"])]
    holes = [Hole(t.area()) for t in _keys(tables["hole"])]
    lights = [Light(t.value("position"), t.value("height", 0.5)) for t in _keys(tables["light"])]  # fmt: skip
    starts = [_start(t) for t in _keys(tables["start"])]
    goals = [Goal(t.area(), t.value("slot", 0)) for t in _keys(tables["goal"])]
    movables = [Movable(t.value("position"), t.value("radius", 0.025), t.value("mass", 0.05)) for t in _keys(tables["movable"])]  # fmt: skip
    faults = [_fault(t) for t in _keys(tables["fault"])]
    if grid is not None:
        walls[:0], floor[:0], lines[:0] = grid.walls, grid.floor, grid.lines
        holes[:0], lights[:0], starts[:0] = grid.holes, grid.lights, grid.starts
        goals[:0], movables[:0] = grid.goals, grid.movables
    if not starts:
        raise WorldFileError(path, None, "the world has no start pose: add a [[start]] or a start tile (0, 1, 2) to the grid")

    bounds = top.value("bounds", None)
    if bounds is None:
        bounds = _content_bounds(walls, floor, lines, holes, goals, starts, lights, movables, grid)
        if bounds is None:
            raise WorldFileError(path, None, "cannot work out the world's extent: give `bounds = [xmin, ymin, xmax, ymax]`")
    elif not (bounds[0] < bounds[2] and bounds[1] < bounds[3]):
        top.fail("`bounds` is [xmin, ymin, xmax, ymax] with xmin < xmax and ymin < ymax", "bounds")
    return WorldSpec(
        name=name,
        bounds=bounds,
        walls=tuple(walls),
        floor=tuple(floor),
        lines=tuple(lines),
        holes=tuple(holes),
        lights=tuple(lights),
        starts=tuple(starts),
        goals=tuple(goals),
        movables=tuple(movables),
        faults=tuple(faults),
        floor_colour=floor_colour,
        outside_is_hole=outside_is_hole,
        source=str(path),
        description=description,
    )


def _array(top: _Table, name: str) -> list[_Table]:
    value = top.data.get(name, [])
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        top.fail(f"`{name}` must be written as [[{name}]] tables", name)
    return [top.child(name, v, i) for i, v in enumerate(value)]


def _keys(tables: list[_Table]) -> list[_Table]:
    for t in tables:
        t.check_declared()
    return tables


def _fault(t: _Table) -> WheelFault:
    """A scheduled wheel fault of a robot on a general chassis (`sim.world.chassis_drive`)."""
    return WheelFault(t.value("time"), t.value("wheel"), t.value("kind"), t.value("robot", 0))


def _line(t: _Table) -> FloorLine:
    points = t.value("points")
    if all(p == points[0] for p in points):
        t.fail("the line has no length: all its points are the same", "points")
    return FloorLine(points, t.value("width", 0.024), t.value("colour", BLACK))


def _start(t: _Table) -> Start:
    """`heading_deg` in degrees or `heading` in radians (not both), counter-clockwise from +x."""
    if "heading" in t.data and "heading_deg" in t.data:
        t.fail("give `heading` (radians) or `heading_deg` (degrees), not both", "heading")
    heading = math.radians(t.value("heading_deg", 0.0)) if "heading" not in t.data else t.value("heading")
    x, y = t.value("position")
    return Start(x, y, heading, t.value("slot", 0))


def _grid(t: _Table, floor_colour: Colour) -> GridPieces:
    """The `[grid]` shorthand: c't-Sim tiles; the plain-floor tile takes the world's floor colour."""
    if not isinstance(t.data, dict):
        raise WorldFileError(t.path, t.where.line(None, None, "grid"), "`grid` must be a [grid] table")
    t.check_declared()
    rows_text = t.value("rows")
    rows = rows_text.split("\n")
    if rows and not rows[-1].strip():
        rows.pop()  # the line holding the closing quotes
    if not rows:
        t.fail("`rows` is empty", "rows")
    key_line = t.line("rows")
    after_key = t.where.lines[key_line - 1].split("=", 1)[1].strip() if key_line else ""
    first = key_line + 1 if key_line and after_key in ('"""', "'''") else key_line
    colours = {" ": floor_colour}
    if "colours" in t.data:
        ct = t.child("colours", t.data["colours"])
        if not isinstance(ct.data, dict):
            t.fail("`colours` must be a table of tile = \"#rrggbb\"", "colours")
        for tile in ct.data:
            if len(tile) != 1 or tile not in KNOWN_TILES:
                ct.fail(f"`{tile}` is not a grid tile", tile)
            colours[tile] = ct.value(tile, floor_colour)
    return build_grid(
        rows,
        cell=t.value("cell", DEFAULT_CELL),
        origin=t.value("origin", (0.0, 0.0)),
        colours=colours,
        row_lines=[first + i if first else None for i in range(len(rows))],
        path=t.path,
    )


def _content_bounds(walls, floor, lines, holes, goals, starts, lights, movables, grid) -> tuple | None:
    """The bounding box of everything in the world, or None when that has no area."""
    points: list[Point] = [v for group in (walls, floor, holes, goals) for item in group for v in item.vertices]
    for line in lines:
        h = line.width / 2
        points += [(x + dx, y + dy) for x, y in line.points for dx, dy in ((-h, -h), (h, h))]
    for m in movables:
        points += [(m.position[0] - m.radius, m.position[1] - m.radius), (m.position[0] + m.radius, m.position[1] + m.radius)]
    points += [(s.x, s.y) for s in starts] + [light.position for light in lights]
    if grid is not None:
        points += [grid.bounds[:2], grid.bounds[2:]]
    box_ = bbox(points)
    return box_ if box_[0] < box_[2] and box_[1] < box_[3] else None
