"""The floor as a raster: CNY70 absorption and holes sampled in O(1) per point for any world.

Floor regions, painted lines and holes are drawn once into a grid (2 mm cells, coarser for very
large worlds) so that line, border and hole tests cost an array lookup per sensor.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from sim.world.kernels.floor import in_hole
from sim.world.layout import Floor
from sim.world.sensors import CNY70_MAX, absorption
from sim.world.spec import WorldSpec

MAX_CELLS = 8_000_000


@dataclass(frozen=True)
class FloorMap:
    """The floor's absorption (float32, 1 over holes; `sensors.absorption`) without its lines
    (`ground`) and the lines' own (`lines`, NaN where there is none: they may stand
    `line_height` m above the ground) and a hole mask, on a grid with `origin` (m) and `cell`
    size (m); sampled by the world's compiled kernels (`sim.world.kernels.floor`,
    `sim.world.kernels.sensing`)."""

    ground: np.ndarray
    lines: np.ndarray
    hole: np.ndarray
    origin: tuple[float, float]
    cell: float
    base_absorption: float
    outside_is_hole: bool
    line_height: float = 0.0

    @cached_property
    def absorption(self) -> np.ndarray:
        """The floor as seen from above: the lines over the ground."""
        return np.where(np.isnan(self.lines), self.ground, self.lines)

    @property
    def outside_absorption(self) -> float:
        """What the floor swallows off the map: everything where that is a hole, else as the base floor."""
        return 1.0 if self.outside_is_hole else self.base_absorption

    def hole_at(self, x: float, y: float) -> bool:
        """Whether the point (x, y) (m) is over a hole (off the map: where that is a hole), as
        the world's kernels test it (`kernels.floor.in_hole`)."""
        return bool(in_hole(x, y, self.kernel))

    @cached_property
    def kernel(self) -> Floor:
        """The raster as the compiled kernels take it."""
        return Floor(self.ground, self.lines, self.hole, np.array(self.origin, dtype=np.float64), float(self.cell), float(self.outside_absorption),
                     bool(self.outside_is_hole), float(self.line_height))

    @cached_property
    def value(self) -> np.ndarray:
        """The CNY70 value (uint16, 0..1023) of each cell, for pictures of the floor."""
        return np.floor(self.absorption * np.float32(CNY70_MAX)).astype(np.uint16)


def _pixel_centres(grid_shape, origin, cell, vertices, margin=0.0):
    """Pixel index ranges and centre coordinates covering the bounding box of `vertices`."""
    v = np.asarray(vertices, dtype=np.float64)
    lo = np.floor((v.min(axis=0) - margin - origin) / cell).astype(int)
    hi = np.ceil((v.max(axis=0) + margin - origin) / cell).astype(int)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, (grid_shape[1], grid_shape[0]))
    if np.any(hi <= lo):
        return None
    xs = origin[0] + (np.arange(lo[0], hi[0]) + 0.5) * cell
    ys = origin[1] + (np.arange(lo[1], hi[1]) + 0.5) * cell
    return (slice(lo[1], hi[1]), slice(lo[0], hi[0])), xs[None, :], ys[:, None]


def _convex_mask(xs, ys, vertices):
    v = np.asarray(vertices, dtype=np.float64)
    mask = np.ones(np.broadcast_shapes(xs.shape, ys.shape), dtype=bool)
    area = np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
    sign = 1.0 if area >= 0 else -1.0
    for (x0, y0), (x1, y1) in zip(v, np.roll(v, -1, axis=0)):
        mask &= sign * ((x1 - x0) * (ys - y0) - (y1 - y0) * (xs - x0)) >= 0
    return mask


def _segment_mask(xs, ys, a, b, half_width, flat=False):
    """Pixels within `half_width` of the segment a-b: with round ends, or (`flat`) only those
    beside it, so that the stroke ends square at a and b."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    d = b - a
    length2 = float(d @ d)
    if length2 == 0:
        return np.zeros(np.broadcast_shapes(xs.shape, ys.shape), dtype=bool) if flat else (xs - a[0]) ** 2 + (ys - a[1]) ** 2 <= half_width**2
    along = ((xs - a[0]) * d[0] + (ys - a[1]) * d[1]) / length2
    t = np.clip(along, 0.0, 1.0)
    near = (xs - a[0] - t * d[0]) ** 2 + (ys - a[1] - t * d[1]) ** 2 <= half_width**2
    return near & (along >= 0.0) & (along <= 1.0) if flat else near


def rasterize(world: WorldSpec, cell: float = 0.002) -> FloorMap:
    """Draw the floor of `world`: base colour, then regions, lines and holes, in that order (a hole
    takes the lines over it away). The last raster drawn is kept and given again for the same
    world and cell (nothing writes into one): the runs of a sweep or a bench share their world,
    and drawing it is some 10 ms of a short run (the 2 mm raster of the maze fills 22 MB)."""
    try:
        return _last_raster(world, cell)
    except TypeError:  # (a world that cannot be hashed: drawn afresh)
        return _draw(world, cell)


@functools.lru_cache(maxsize=1)
def _last_raster(world: WorldSpec, cell: float) -> FloorMap:
    return _draw(world, cell)


def _draw(world: WorldSpec, cell: float) -> FloorMap:
    xmin, ymin, xmax, ymax = world.bounds
    area = (xmax - xmin) * (ymax - ymin)
    cell = max(cell, float(np.sqrt(area / MAX_CELLS)))
    shape = (max(1, int(np.ceil((ymax - ymin) / cell))), max(1, int(np.ceil((xmax - xmin) / cell))))
    origin = np.array([xmin, ymin])
    base = absorption(world.floor_colour)
    value = np.full(shape, base, dtype=np.float32)
    painted = np.full(shape, np.nan, dtype=np.float32)
    hole = np.zeros(shape, dtype=bool)

    for region in world.floor:
        cover = _pixel_centres(shape, origin, cell, region.vertices)
        if cover:
            window, xs, ys = cover
            value[window][_convex_mask(xs, ys, region.vertices)] = absorption(region.colour)
    for line in world.lines:
        colour = absorption(line.colour)
        for a, b in zip(line.points[:-1], line.points[1:]):
            cover = _pixel_centres(shape, origin, cell, (a, b), margin=line.width / 2)
            if cover:
                window, xs, ys = cover
                painted[window][_segment_mask(xs, ys, a, b, line.width / 2, line.flat)] = colour
    for h in world.holes:
        cover = _pixel_centres(shape, origin, cell, h.vertices)
        if cover:
            window, xs, ys = cover
            inside = _convex_mask(xs, ys, h.vertices)
            hole[window] |= inside
            value[window][inside] = 1.0
            painted[window][inside] = np.nan
    return FloorMap(value, painted, hole, (float(xmin), float(ymin)), cell, float(base), world.outside_is_hole, world.line_height)
