"""The c't-Sim ASCII-grid legend turned into WorldSpec pieces; shared by the parcours XML importer
and the `[grid]` shorthand of the TOML format, so one layout means the same world in both.

Semantics (c't-Sim's ParcoursLoader/Parcours, v2.x, read for the rules only):
- rows are given top-down; the last row is y = 0; cell (col, row) covers [col, col+1]·cell × [row, row+1]·cell;
- `X` is one wall block; maximal horizontal runs of `=` and vertical runs of `#` become one box each;
- `*` is a pillar with a light 0.5 m above its centre. By default it is a wall block (the whole
  cell, as `X`), and a pillar at the end of a `=` run (or else of a `#` run) joins that run's box,
  so `*=====*` is one box and a wall has no seam at its corner posts. With pillars="cylinder" it is
  c't-Sim's own: a cylinder of 0.1 m diameter (Java3D's, a 15-sided prism with a corner due north),
  never part of a run, the rest of its cell open floor;
- `L` is a hole; starts `0 1 2 $` (slots 0 1 2 1) face an adjacent `.` tile, looked for south,
  north, west, east in that order; with none they face +x (c't-Sim's default heading);
- line tiles are black lines 0.1 cell wide through the cell centre, c't-Sim's outlines: flat ends
  at the cell's edges, square corners; `!` and `%` have a gap of one line width at the centre;
- `o` and the line+object tiles put a movable can at the cell centre; `l` (BPS beacon) and `O`
  (c't-Sim's internal 'already built' marker, found in some shipped files) are plain floor.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Container, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.world.spec import (
    BLACK,
    JAVA3D_FLOOR,
    Colour,
    FloorLine,
    FloorRegion,
    Goal,
    Hole,
    Light,
    Movable,
    Point,
    SceneShape,
    Start,
    Wall,
    WorldFileError,
    box,
)

DEFAULT_CELL = 0.24  # m, c't-Sim's blockSizeInM
LIGHT_HEIGHT = 0.5  # m, c't-Sim's LIGHTZ
LINE_WIDTH_CELLS = 0.1  # c't-Sim's LINEWIDTH, in cells
LINE_HEIGHT = 0.001  # m, c't-Sim's lines over its floor (ParcoursLoader: floor tiles' top at z 0.001, line tiles at 0.002)
PILLAR_STYLES = ("cell", "cylinder")
PILLAR_DIAMETER = 0.1  # m, c't-Sim's lamp pillar (ParcoursLoader: createPillar(x, y, 0.1f, ...))
PILLAR_SIDES = 15  # Java3D's Cylinder: 15 divisions round its axis

_N, _E, _S, _W = "N", "E", "S", "W"
# Which cell edges a line tile's line reaches (c't-Sim's LINE_* shapes; corner names as in template.xml).
LINE_ARMS: dict[str, str] = {
    "|": "NS", "$": "NS", "(": "NS", "!": "NS",
    "-": "EW", "_": "EW", "%": "EW",
    "/": "ES", "p": "ES",  # corner NW of a loop: line goes east and south
    "\\": "SW", "q": "SW",  # corner NE
    "+": "NE", "b": "NE",  # corner SW
    "~": "NW", "d": "NW",  # corner SE
    "[": "NESW",
    "T": "EWS",  # stem down
    "]": "EWN",  # stem up
    "}": "NSE",  # stem right
    "{": "NSW",  # stem left
}  # fmt: skip
GAPPED_LINES = "!%"
START_SLOTS: dict[str, int] = {"0": 0, "1": 1, "2": 2, "$": 1}
MOVABLE_TILES = "o(_pqbd"
WALL_TILES = "X=#*"
HOLE_TILE = "L"
COLOURED_FLOOR_TILES = " .Z012"  # tiles whose own appearance colours the floor
PLAIN_FLOOR_TILES = "lO"  # floor in the ' ' colour
KNOWN_TILES = set(LINE_ARMS) | set(START_SLOTS) | set(MOVABLE_TILES) | set(WALL_TILES) | {
    HOLE_TILE, *COLOURED_FLOOR_TILES, *PLAIN_FLOOR_TILES,
}  # fmt: skip


def _hex(value: str) -> Colour:
    return tuple(int(value[i : i + 2], 16) / 255 for i in (1, 3, 5))  # type: ignore[return-value]


# Floor colours per tile when a world does not say (c't-Sim's template.xml optics).
DEFAULT_TILE_COLOURS: dict[str, Colour] = {
    " ": _hex("#606060"),
    ".": _hex("#FFFFFF"),
    "0": _hex("#FFFFFF"),
    "1": _hex("#993030"),
    "2": _hex("#000099"),
    "Z": _hex("#66FF00"),
    **{c: BLACK for c in LINE_ARMS},
}


TILE_NAMES: dict[Colour, str] = {
    DEFAULT_TILE_COLOURS["1"]: "start tile, slot 1",
    DEFAULT_TILE_COLOURS["2"]: "start tile, slot 2",
    DEFAULT_TILE_COLOURS["0"]: "white tile (start slot 0, or '.')",
    DEFAULT_TILE_COLOURS["Z"]: "goal tile",
}
"""What c't-Sim's floor tiles of these colours mean, for a map's key."""


@dataclass(frozen=True)
class GridPieces:
    """What a grid contributes to a world."""

    bounds: tuple[float, float, float, float]
    walls: tuple[Wall, ...]
    floor: tuple[FloorRegion, ...]
    lines: tuple[FloorLine, ...]
    holes: tuple[Hole, ...]
    lights: tuple[Light, ...]
    starts: tuple[Start, ...]
    goals: tuple[Goal, ...]
    movables: tuple[Movable, ...]
    scene: tuple[SceneShape, ...] = ()


MAX_CELLS = 250_000
"""Most tiles in a grid (500 x 500: 120 m square at c't-Sim's 0.24 m cells; its own largest is 40 x 40)."""


def build_grid(
    rows: Sequence[str],
    *,
    cell: float = DEFAULT_CELL,
    origin: Point = (0.0, 0.0),
    colours: Mapping[str, Colour] = DEFAULT_TILE_COLOURS,
    row_lines: Sequence[int | None] | None = None,
    path: str | Path | None = None,
    pillars: str = "cell",
) -> GridPieces:
    """Turn grid rows (top-down, as written) into world pieces.

    `colours` maps tiles to floor (or, for line tiles, line) colours and falls back to
    DEFAULT_TILE_COLOURS; `row_lines` gives each row's line in the source file for error messages;
    `pillars`: 'cell' (a lamp pillar is a wall block) or 'cylinder' (c't-Sim's 0.1 m cylinder)."""
    if pillars not in PILLAR_STYLES:
        raise ValueError(f"pillars must be one of {PILLAR_STYLES}, not {pillars!r}")
    lines_of = list(row_lines) if row_lines is not None else [None] * len(rows)
    size = len(rows) * max((len(row) for row in rows), default=0)
    if size > MAX_CELLS:
        raise WorldFileError(path, lines_of[0] if lines_of else None,
                             f"the grid has {len(rows):,} rows of up to {size // len(rows):,} tiles, more than the {MAX_CELLS:,} tiles a grid may have")
    for r, row in enumerate(rows):
        for c, ch in enumerate(row):
            if ch not in KNOWN_TILES:
                raise WorldFileError(path, lines_of[r], f"unknown tile {ch!r} in grid row {r + 1}, column {c + 1}")
    width = max((len(row) for row in rows), default=0)
    if width == 0:
        raise WorldFileError(path, lines_of[0] if lines_of else None, "the grid is empty")
    tiles = _Tiles([row.ljust(width) for row in reversed(rows)])
    colour = {**DEFAULT_TILE_COLOURS, **colours}
    cells = _Cells(cell, origin)
    spans = _wall_spans(tiles, pillars == "cell")
    walls = tuple(Wall(cells.box(*span)) for span in spans) + tuple(
        Wall(_pillar(*cells.centre(c, r)), cylinder=True) for c, r, _ in tiles.cells("*") if pillars == "cylinder"
    )
    return GridPieces(
        bounds=(origin[0], origin[1], origin[0] + width * cell, origin[1] + tiles.height * cell),
        walls=walls,
        floor=tuple(_floor(tiles, cells, colour)),
        lines=tuple(line for c, r, ch in tiles.cells(LINE_ARMS) for line in _line(ch, c, r, cells, colour[ch])),
        holes=tuple(Hole(cells.box(*span)) for span in _runs(tiles, lambda ch: ch == HOLE_TILE)),
        lights=tuple(Light(_ctsim_centre(c, r, cell, origin), LIGHT_HEIGHT) for c, r, _ in tiles.cells("*")),
        starts=tuple(Start(*cells.centre(c, r), _heading(tiles, c, r), START_SLOTS[ch]) for c, r, ch in tiles.cells(START_SLOTS)),
        goals=tuple(Goal(cells.box(c, r, 1, 1)) for c, r, _ in tiles.cells("Z")),
        movables=tuple(Movable(cells.centre(c, r)) for c, r, _ in tiles.cells(MOVABLE_TILES)),
        scene=_scene(tiles, cell, origin, spans, walls) if pillars == "cylinder" else (),
    )  # fmt: skip


class _Tiles:
    """The grid bottom-up: `at(c, r)` with row 0 at y = 0; off-grid reads as None."""

    def __init__(self, rows_bottom_up: list[str]):
        self.rows = rows_bottom_up
        self.width = len(rows_bottom_up[0])
        self.height = len(rows_bottom_up)

    def at(self, c: int, r: int) -> str | None:
        return self.rows[r][c] if 0 <= r < self.height and 0 <= c < self.width else None

    def cells(self, wanted: Container[str]) -> Iterator[tuple[int, int, str]]:
        """(col, row, tile) of the wanted tiles in c't-Sim's scan order (rows bottom-up, columns left-right)."""
        for r, row in enumerate(self.rows):
            for c, ch in enumerate(row):
                if ch in wanted:
                    yield c, r, ch


@dataclass(frozen=True)
class _Cells:
    """Grid cells to metres."""

    size: float
    origin: Point

    def box(self, c: int, r: int, w: int, h: int) -> tuple[Point, ...]:
        x0, y0 = self.origin[0] + c * self.size, self.origin[1] + r * self.size
        return box(x0, y0, x0 + w * self.size, y0 + h * self.size)

    def centre(self, c: float, r: float) -> Point:
        return (self.origin[0] + (c + 0.5) * self.size, self.origin[1] + (r + 0.5) * self.size)


def _runs(
    tiles: _Tiles, member: Callable[[str | None], bool], used: set[tuple[int, int]] | None = None
) -> Iterator[tuple[int, int, int, int]]:
    """Maximal horizontal runs (col, row, length, 1) of cells for which `member(tile)` holds."""
    for r in range(tiles.height):
        c = 0
        while c < tiles.width:
            if member(tiles.at(c, r)) and (used is None or (c, r) not in used):
                start = c
                while c < tiles.width and member(tiles.at(c, r)) and (used is None or (c, r) not in used):
                    c += 1
                yield (start, r, c - start, 1)
            else:
                c += 1


def _ctsim_centre(c: int, r: int, cell: float, origin: Point) -> Point:
    """Cell (c, r)'s centre (m) as c't-Sim computes a lamp's place: (c + 0.5f) * blockSizeInM in
    float arithmetic (within 0.1 µm of the exact centre; its light pick meets the lamp's mesh to
    the last bit, `kernels.light_pick`)."""
    f = np.float32
    return (origin[0] + float(f(c + 0.5) * f(cell)), origin[1] + float(f(r + 0.5) * f(cell)))


def _pillar(x: float, y: float, r: float = PILLAR_DIAMETER / 2) -> tuple[Point, ...]:
    """c't-Sim's lamp pillar at (x, y): Java3D's cylinder, corners on the circle of radius `r` (m)
    from due north clockwise (its vertex k at angle -pi/2 + k 2pi/15 about the axis, which stands
    up after the pillar's rotation about x)."""
    angles = (math.pi / 2 - k * 2 * math.pi / PILLAR_SIDES for k in range(PILLAR_SIDES))
    return tuple(reversed([(x + r * math.cos(a), y + r * math.sin(a)) for a in angles]))  # counter-clockwise


def _wall_spans(tiles: _Tiles, pillar_blocks: bool = True) -> list[tuple[int, int, int, int]]:
    """Wall boxes (col, row, w, h): `=` runs, then `#` runs, each taking the pillars at its ends
    and between its cells; what is left (`X`, lone pillars) is one block per cell. Without
    `pillar_blocks` the pillars are no part of any box."""
    used: set[tuple[int, int]] = set()
    spans = []
    post = "*" if pillar_blocks else ""
    for c, r, w, _ in _runs(tiles, lambda ch: ch in "=" + post):
        if any(tiles.at(c + i, r) == "=" for i in range(w)):
            spans.append((c, r, w, 1))
            used.update((c + i, r) for i in range(w))
    transposed = _Tiles(["".join(tiles.at(c, r) for r in range(tiles.height)) for c in range(tiles.width)])
    used_t = {(r, c) for c, r in used}
    for r, c, h, _ in _runs(transposed, lambda ch: ch in "#" + post, used_t):
        if any(tiles.at(c, r + i) == "#" for i in range(h)):
            spans.append((c, r, 1, h))
            used.update((c, r + i) for i in range(h))
    spans.extend((c, r, 1, 1) for c, r, _ in tiles.cells("X" + post) if (c, r) not in used)
    return spans


def _floor(tiles: _Tiles, cells: _Cells, colour: Mapping[str, Colour]) -> Iterator[FloorRegion]:
    """Regions for tiles coloured unlike the plain floor, merged along rows."""
    plain = colour[" "]

    def tile_colour(ch: str | None) -> Colour | None:
        if ch is None or ch in WALL_TILES or ch == HOLE_TILE:
            return None
        own = colour[ch] if ch in COLOURED_FLOOR_TILES else plain
        return own if own != plain else None

    for r in range(tiles.height):
        c = 0
        while c < tiles.width:
            here = tile_colour(tiles.at(c, r))
            start = c
            c += 1
            while here is not None and c < tiles.width and tile_colour(tiles.at(c, r)) == here:
                c += 1
            if here is not None:
                yield FloorRegion(cells.box(start, r, c - start, 1), here)


def _line(ch: str, c: int, r: int, cells: _Cells, colour: Colour) -> Iterator[FloorLine]:
    """The lines of one line tile, as c't-Sim's outlines (ParcoursLoader's LINE_* polygons): a
    straight line runs edge to edge; an arm that ends at the centre (corners, T stems) reaches
    half a line width past it, so corners are square; every end is flat, at the cell's edge or
    at the gap of `!` and `%` (one line width at the centre)."""
    cx, cy = cells.centre(c, r)
    half = cells.size / 2
    width = LINE_WIDTH_CELLS * cells.size
    ends = {_N: (cx, cy + half), _S: (cx, cy - half), _E: (cx + half, cy), _W: (cx - half, cy)}
    arms = [a for a in (_N, _E, _S, _W) if a in LINE_ARMS[ch]]

    def arm(a: str, start: float) -> FloorLine:
        """The arm towards edge `a` from `start` (m, signed) along it from the centre."""
        ex, ey = ends[a]
        dx, dy = (ex - cx) / half, (ey - cy) / half
        return FloorLine(((cx + dx * start, cy + dy * start), (ex, ey)), width, colour, flat=True)

    if ch in GAPPED_LINES:
        yield from (arm(a, width / 2) for a in arms)
        return
    for a, b in ((_N, _S), (_E, _W)):
        if a in arms and b in arms:
            yield FloorLine((ends[a], ends[b]), width, colour, flat=True)
            arms = [x for x in arms if x not in (a, b)]
    yield from (arm(a, -width / 2) for a in arms)


def _heading(tiles: _Tiles, c: int, r: int) -> float:
    """Face the first `.` neighbour (south, north, west, east: c't-Sim's checkNeighbours order); else +x."""
    for dc, dr in ((0, -1), (0, 1), (-1, 0), (1, 0)):
        if tiles.at(c + dc, r + dr) == ".":
            return math.atan2(dr, dc)
    return 0.0


BOX_FACES = (None, None, 1, 3, 2, 0)
"""The wall polygon edge (`spec.box`: bottom, right, top, left) of each shape of a Java3D Box in
its order (front and back lie level, +z and -z; then +x, -x, +y, -y); None: a level face."""
CAN_DIAMETER, CAN_HEIGHT = 0.03, 0.08  # m, c't-Sim's movable object (ParcoursLoader.createMovableObject)
BEACON_RADIUS, BEACON_HEIGHT = 0.02, 0.1  # m, c't-Sim's BPS beacon sphere and its height (BPS.BPSZ)
WALL_HALF_HEIGHT = 0.2  # m, c't-Sim's wall boxes (ParcoursLoader.WALL_HEIGHT, a half-height)
LIGHT_RADIUS = 0.07  # m, c't-Sim's lamp sphere


def _scene(tiles: _Tiles, cell: float, origin: Point, spans: list[tuple[int, int, int, int]], walls: tuple[Wall, ...]) -> tuple[SceneShape, ...]:
    """c't-Sim's Java3D scene of the grid (ParcoursLoader.parse, World.setParcours) in the order
    its shapes go live: the lamp spheres, the BPS beacons, the floor (a tile under each lamp
    pillar, start, goal, hole, white and line tile, the lines, then one floor under everything),
    then the obstacles (walls, pillars, cans), each group in the parse's order (rows bottom-up,
    columns left to right, a wall where its first cell is met). Bounds as Java3D holds them:
    c't-Sim's float positions and sizes, moved 2 m down (`JAVA3D_FLOOR`)."""
    f = np.float32
    block = f(cell)

    def at(v: float) -> float:  # a grid coordinate (cells, float) to metres as c't-Sim computes it
        return float(f(v) * block)

    def shape(cx: float, cy: float, cz: float, hx: float, hy: float, hz: float, face: int = -1) -> SceneShape:
        x, y = cx + origin[0], cy + origin[1]
        return SceneShape((x - hx, y - hy, cz - hz), (x + hx, y + hy, cz + hz), face)

    def box(cx: float, cy: float, cz: float, hx: float, hy: float, hz: float, first: int | None) -> list[SceneShape]:
        """A Java3D Box's six shapes; `first`: the wall's first vertex, for its upright faces."""
        out = []
        for k, edge in enumerate(BOX_FACES):
            sx, sy, sz = ((0, 0, 1), (0, 0, -1), (1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0))[k]
            face = first + edge if first is not None and edge is not None else -1
            x, y, z = cx + sx * hx, cy + sy * hy, cz + sz * hz
            out.append(shape(x, y, z, hx * (sx == 0), hy * (sy == 0), hz * (sz == 0), face))
        return out

    def cylinder(cx: float, cy: float, bottom: float, top: float, radius: float, first: int) -> list[SceneShape]:
        """A Java3D Cylinder's side, top and bottom (its 15-sided outline's bounds)."""
        corners = np.array(_pillar(0.0, 0.0, radius))
        (lx, ly), (ux, uy) = corners.min(axis=0), corners.max(axis=0)
        x, y = cx + origin[0], cy + origin[1]
        side = SceneShape((x + lx, y + ly, bottom), (x + ux, y + uy, top), first)
        return [side, SceneShape((x + lx, y + ly, top), (x + ux, y + uy, top)), SceneShape((x + lx, y + ly, bottom), (x + ux, y + uy, bottom))]

    first_vertex = np.concatenate(([0], np.cumsum([len(w.vertices) for w in walls])))
    wall_at = {(c, r): (w, h, first_vertex[i]) for i, (c, r, w, h) in enumerate(spans)}
    pillar_at = {(c, r): first_vertex[len(spans) + i] for i, (c, r, _) in enumerate(tiles.cells("*"))}
    obstacle_z = JAVA3D_FLOOR + WALL_HALF_HEIGHT  # World's obstacle group stands 0.2 m up (its walls' half-height)
    floor_z = JAVA3D_FLOOR + float(f(0.001))
    lamps: list[SceneShape] = []
    beacons: list[SceneShape] = []
    floor: list[SceneShape] = []
    obstacles: list[SceneShape] = []
    half = float(f(block * f(0.5)))
    for c, r, ch in tiles.cells(set(KNOWN_TILES)):
        cx, cy = at(c + 0.5), at(r + 0.5)
        if (c, r) in wall_at:
            w, h, first = wall_at[c, r]
            hx, hy = float(f(block / f(2)) * f(w)), float(f(block / f(2)) * f(h))
            obstacles += box(at(c + w / 2), at(r + h / 2), obstacle_z, hx, hy, float(f(WALL_HALF_HEIGHT)), int(first))
        if ch == "*":
            height = f(LIGHT_HEIGHT)
            z = obstacle_z + float(height / f(2) - f(WALL_HALF_HEIGHT))
            obstacles += cylinder(cx, cy, z - float(height / f(2)), z + float(height / f(2)), PILLAR_DIAMETER / 2, int(pillar_at[c, r]))
            lamp = shape(cx, cy, JAVA3D_FLOOR + float(height), float(f(LIGHT_RADIUS)), float(f(LIGHT_RADIUS)), float(f(LIGHT_RADIUS)))
            lamps.append(SceneShape(lamp.lower, lamp.upper, lamp=len(lamps)))
        if ch == "l":
            beacons.append(shape(cx, cy, JAVA3D_FLOOR + float(f(BEACON_HEIGHT)), *[float(f(BEACON_RADIUS))] * 3))
        if ch in "*.L012Z" or ch in LINE_ARMS:
            floor += box(cx, cy, floor_z, half, half, 0.0, None)
        if ch in LINE_ARMS:
            line = [p for ln in _line(ch, c, r, _Cells(1.0, (0.0, 0.0)), BLACK) for p in _outline(ln)]
            (lx, ly), (ux, uy) = np.min(line, axis=0) - (c + 0.5, r + 0.5), np.max(line, axis=0) - (c + 0.5, r + 0.5)
            x0, y0, x1, y1 = (float(f(round(v * 20) / 20) * block) for v in (lx, ly, ux, uy))  # c't-Sim's outline points: 0.05 cell steps
            z = JAVA3D_FLOOR + float(f(2 * LINE_HEIGHT))
            floor.append(SceneShape((cx + origin[0] + x0, cy + origin[1] + y0, z), (cx + origin[0] + x1, cy + origin[1] + y1, z)))
        if ch in MOVABLE_TILES:
            height = f(CAN_HEIGHT)
            z = obstacle_z + float(height / f(2) - f(WALL_HALF_HEIGHT))
            obstacles += cylinder(float(f(c + 0.5) * block), float(f(r + 0.5) * block), z - float(height / f(2)), z + float(height / f(2)), CAN_DIAMETER / 2, -1)
    width, height = f(tiles.width), f(tiles.height)
    floor += box(float(width / f(2) * block), float(height / f(2) * block), JAVA3D_FLOOR + float(f(-0.005)),
                 float(width * block * f(0.5)), float(height * block * f(0.5)), 0.0, None)  # fmt: skip
    return tuple(lamps + beacons + floor + obstacles)


def _outline(line: FloorLine) -> list[Point]:
    """The corners of a straight flat-ended FloorLine's rectangle."""
    (ax, ay), (bx, by) = line.points[0], line.points[-1]
    length = math.hypot(bx - ax, by - ay)
    nx, ny = -(by - ay) / length * line.width / 2, (bx - ax) / length * line.width / 2
    return [(ax + nx, ay + ny), (ax - nx, ay - ny), (bx + nx, by + ny), (bx - nx, by - ny)]
