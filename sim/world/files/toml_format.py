"""ctsim's native world format: TOML a student can write by hand, in metres (worlds/README.md).

tomllib reports line numbers for syntax errors only, so `_Locator` finds the line of the N-th
`[[wall]]` header or of a key inside it by scanning the text; every user mistake becomes a
WorldFileError(path, line, problem), never a traceback.
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Any, NoReturn

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
TOP_KEYS = ("name", "description", "bounds", "floor_colour", "outside_is_hole", "grid", *ARRAYS)
_REQUIRED: Any = object()
_WALL_COLOUR = Wall(()).colour


class _Locator:
    """Line numbers of table headers and keys, found by scanning the TOML text."""

    _ARRAY = re.compile(r"^\s*\[\[\s*([^\[\]#]+?)\s*\]\]")
    _TABLE = re.compile(r"^\s*\[\s*([^\[\]#]+?)\s*\]")

    def __init__(self, text: str):
        self.lines = text.splitlines()
        # (table name, index among same-named arrays or None) -> (header line, last line), 1-based
        self.sections: dict[tuple[str | None, int | None], tuple[int, int]] = {}
        counts: dict[str, int] = {}
        current: tuple[str | None, int | None] = (None, None)
        start = 1
        in_string = None
        for number, line in enumerate(self.lines, 1):
            if in_string is None:
                header = self._ARRAY.match(line) or self._TABLE.match(line)
                if header:
                    self.sections[current] = (start, number - 1)
                    name = header.group(1).replace(" ", "").replace('"', "")
                    if header.re is self._ARRAY:
                        current = (name, counts.get(name, 0))
                        counts[name] = current[1] + 1
                    else:
                        current = (name, None)
                    start = number
            for quote in ('"""', "'''"):
                if line.count(quote) % 2 and in_string in (None, quote):
                    in_string = None if in_string else quote
        self.sections[current] = (start, len(self.lines))

    def line(self, table: str | None, index: int | None, key: str | None = None) -> int | None:
        """The line of `key` in the table (the header when no key, or when the key is not found)."""
        span = self.sections.get((table, index))
        if span is None:
            return None
        first, last = span
        if key is not None:
            pattern = re.compile(rf"^\s*[\"']?{re.escape(key)}[\"']?\s*=")
            for number in range(first, last + 1):
                if pattern.match(self.lines[number - 1]):
                    return number
            # not a key = value line: maybe a [key] or [[key]] table of its own
            name = key if table is None else f"{table}.{key}"
            sub = self.sections.get((name, 0)) or self.sections.get((name, None))
            if sub is not None:
                return sub[0]
        return first if table is not None else None


class _Table:
    """One TOML table with typed, located accessors: each bad value names its file and line."""

    def __init__(self, path: Path, where: _Locator, name: str | None, index: int | None, data: dict):
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

    def number(self, key: str, default: Any = _REQUIRED, *, positive: bool = False) -> float:
        value = self.raw(key, default)
        if value is default and key not in self.data:
            return value
        result = self._number(value, key, f"`{key}`")
        if positive and result <= 0:
            self.fail(f"`{key}` must be greater than 0, not {result:g}", key)
        return result

    def _number(self, value: Any, key: str, what: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(f"{what} must be a number, not {_kind(value)}", key)
        if not math.isfinite(value):
            self.fail(f"{what} must be finite, not {value}", key)
        return float(value)

    def integer(self, key: str, default: int) -> int:
        value = self.raw(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(f"`{key}` must be an integer, not {_kind(value)}", key)
        return value

    def text(self, key: str, default: str) -> str:
        value = self.raw(key, default)
        if not isinstance(value, str):
            self.fail(f"`{key}` must be a string, not {_kind(value)}", key)
        return value

    def boolean(self, key: str, default: bool) -> bool:
        value = self.raw(key, default)
        if not isinstance(value, bool):
            self.fail(f"`{key}` must be true or false, not {_kind(value)}", key)
        return value

    def numbers(self, key: str, count: int, default: Any = _REQUIRED) -> tuple[float, ...]:
        value = self.raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, list) or len(value) != count:
            self.fail(f"`{key}` must be a list of {count} numbers, not {_kind(value)}", key)
        return tuple(self._number(v, key, f"`{key}`[{i}]") for i, v in enumerate(value))

    def point(self, key: str, default: Any = _REQUIRED) -> Point:
        return self.numbers(key, 2, default)  # type: ignore[return-value]

    def points(self, key: str, minimum: int) -> tuple[Point, ...]:
        value = self.raw(key)
        if not isinstance(value, list) or len(value) < minimum:
            self.fail(f"`{key}` must be a list of at least {minimum} [x, y] points", key)
        result = []
        for i, p in enumerate(value):
            if not isinstance(p, list) or len(p) != 2:
                self.fail(f"`{key}`[{i}] must be an [x, y] point, not {_kind(p)}", key)
            result.append((self._number(p[0], key, f"`{key}`[{i}]"), self._number(p[1], key, f"`{key}`[{i}]")))
        return tuple(result)

    def colour(self, key: str, default: Any = _REQUIRED) -> Colour:
        value = self.raw(key, default)
        if key not in self.data:
            return value
        parsed = parse_colour(value) if isinstance(value, str) else None
        if parsed is None:
            self.fail(f"`{key}` must be a colour like \"#a0b0c0\", not {value!r}", key)
        return parsed

    def area(self, *, segment: bool = False) -> tuple[Point, ...]:
        """A convex polygon from exactly one of `box`, `polygon` (or, for walls, `from`/`to`)."""
        given = [k for k in ("box", "polygon", "from") if k in self.data]
        options = "`box`, `polygon` or `from`/`to`" if segment else "`box` or `polygon`"
        if len(given) != 1:
            self.fail(f"give exactly one of {options}", given[1] if len(given) > 1 else None)
        if given[0] == "box":
            x0, y0, x1, y1 = self.numbers("box", 4)
            if not (x0 < x1 and y0 < y1):
                self.fail("`box` is [xmin, ymin, xmax, ymax] with xmin < xmax and ymin < ymax", "box")
            return ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
        if given[0] == "polygon":
            ccw = convex_ccw(self.points("polygon", 3))
            if ccw is None:
                self.fail("`polygon` must be convex with a non-zero area", "polygon")
            return ccw
        p, q = self.point("from"), self.point("to")
        thickness = self.number("thickness", 0.02, positive=True)
        if math.dist(p, q) == 0:
            self.fail("the wall has no length: `from` and `to` are the same point", "to")
        return segment_box(p, q, thickness)

    def child(self, key: str, data: Any, index: int | None = None) -> _Table:
        name = key if self.name is None else f"{self.name}.{key}"
        return _Table(self.path, self.where, name, index, data)


def parse_colour(text: str) -> Colour | None:
    """`#rrggbb` as RGB in 0..1; None if malformed."""
    t = text.strip()
    if len(t) != 7 or t[0] != "#" or any(c not in "0123456789abcdefABCDEF" for c in t[1:]):
        return None
    return tuple(int(t[i : i + 2], 16) / 255 for i in (1, 3, 5))  # type: ignore[return-value]


def _kind(value: Any) -> str:
    return {bool: "a boolean", str: "a string", list: "a list", dict: "a table"}.get(
        type(value), type(value).__name__
    )


def load_toml(path: Path) -> WorldSpec:
    """Load a native TOML world file."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise WorldFileError(path, None, f"cannot read: {e}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        found = re.search(r"\(at line (\d+), column \d+\)", str(e))
        line = int(found.group(1)) if found else len(text.splitlines()) if "end of document" in str(e) else None
        problem = re.sub(r"\s*\(at (line \d+, column \d+|end of document)\)", "", str(e)) or "TOML syntax error"
        raise WorldFileError(path, line, f"TOML syntax: {problem}") from None
    top = _Table(path, _Locator(text), None, None, data)
    top.check_keys(TOP_KEYS)
    name = top.text("name", path.stem)
    description = top.text("description", "").strip()
    outside_is_hole = top.boolean("outside_is_hole", False)
    tables = {name: _array(top, name) for name in ARRAYS}
    floor_colour = top.colour("floor_colour", DEFAULT_FLOOR)
    grid = _grid(top.child("grid", top.data["grid"]), floor_colour) if "grid" in top.data else None

    walls = [Wall(t.area(segment=True), t.colour("colour", _WALL_COLOUR)) for t in _keys(tables["wall"], "box", "polygon", "from", "to", "thickness", "colour")]  # fmt: skip
    floor = [FloorRegion(t.area(), t.colour("colour")) for t in _keys(tables["floor"], "box", "polygon", "colour")]  # fmt: skip
    lines = [_line(t) for t in _keys(tables["line"], "points", "width", "colour")]
    holes = [Hole(t.area()) for t in _keys(tables["hole"], "box", "polygon")]
    lights = [Light(t.point("position"), t.number("height", 0.5, positive=True)) for t in _keys(tables["light"], "position", "height")]  # fmt: skip
    starts = [_start(t) for t in _keys(tables["start"], "position", "heading_deg", "heading", "slot")]
    goals = [Goal(t.area(), _slot(t)) for t in _keys(tables["goal"], "box", "polygon", "slot")]
    movables = [Movable(t.point("position"), t.number("radius", 0.025, positive=True), t.number("mass", 0.05, positive=True)) for t in _keys(tables["movable"], "position", "radius", "mass")]  # fmt: skip
    faults = [_fault(t) for t in _keys(tables["fault"], "time", "robot", "wheel", "kind")]
    if grid is not None:
        walls[:0], floor[:0], lines[:0] = grid.walls, grid.floor, grid.lines
        holes[:0], lights[:0], starts[:0] = grid.holes, grid.lights, grid.starts
        goals[:0], movables[:0] = grid.goals, grid.movables
    if not starts:
        raise WorldFileError(path, None, "the world has no start pose: add a [[start]] or a start tile (0, 1, 2) to the grid")

    bounds = top.numbers("bounds", 4, None)
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


def _keys(tables: list[_Table], *allowed: str) -> list[_Table]:
    for t in tables:
        t.check_keys(allowed)
    return tables


def _fault(t: _Table) -> WheelFault:
    """A scheduled wheel fault of a robot on a general chassis (`sim.world.chassis_drive`)."""
    kind = t.text("kind", "")
    if kind not in FAULT_KINDS:
        t.fail(f"`kind` must be one of {', '.join(FAULT_KINDS)}, not {kind!r}", "kind")
    robot, wheel = t.integer("robot", 0), t.integer("wheel", -1)
    if robot < 0 or wheel < 0:
        t.fail("`robot` and `wheel` are indices from 0", "wheel" if wheel < 0 else "robot")
    return WheelFault(t.number("time"), wheel, kind, robot)


def _line(t: _Table) -> FloorLine:
    points = t.points("points", 2)
    if all(p == points[0] for p in points):
        t.fail("the line has no length: all its points are the same", "points")
    return FloorLine(points, t.number("width", 0.024, positive=True), t.colour("colour", BLACK))


def _start(t: _Table) -> Start:
    """`heading_deg` in degrees or `heading` in radians (not both), counter-clockwise from +x."""
    if "heading" in t.data and "heading_deg" in t.data:
        t.fail("give `heading` (radians) or `heading_deg` (degrees), not both", "heading")
    heading = math.radians(t.number("heading_deg", 0.0)) if "heading" not in t.data else t.number("heading")
    x, y = t.point("position")
    return Start(x, y, heading, _slot(t))


def _slot(t: _Table) -> int:
    """A start's or goal's `slot`: 0 (default) or the robot's start slot 1, 2, ..."""
    slot = t.integer("slot", 0)
    if slot < 0:
        t.fail(f"`slot` must be 0 or more, not {slot}", "slot")
    return slot


def _grid(t: _Table, floor_colour: Colour) -> GridPieces:
    """The `[grid]` shorthand: c't-Sim tiles; the plain-floor tile takes the world's floor colour."""
    if not isinstance(t.data, dict):
        raise WorldFileError(t.path, t.where.line(None, None, "grid"), "`grid` must be a [grid] table")
    t.check_keys(("cell", "origin", "rows", "colours"))
    rows_text = t.text("rows", _REQUIRED)
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
            colours[tile] = ct.colour(tile, floor_colour)
    return build_grid(
        rows,
        cell=t.number("cell", DEFAULT_CELL, positive=True),
        origin=t.point("origin", (0.0, 0.0)),
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
