"""Small plane-geometry helpers the loaders and the checker share (metres, counter-clockwise)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from sim.world.spec import Point


def _cross(o: Point, a: Point, b: Point) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def convex_ccw(points: Sequence[Point]) -> tuple[Point, ...] | None:
    """The polygon counter-clockwise if it is convex with non-zero area, else None.

    Collinear vertices are allowed (a box given with a mid-edge point is still convex)."""
    n = len(points)
    if n < 3:
        return None
    turns = [_cross(points[i], points[(i + 1) % n], points[(i + 2) % n]) for i in range(n)]
    if all(t >= 0 for t in turns):
        ccw = tuple(points)
    elif all(t <= 0 for t in turns):
        ccw = tuple(reversed(points))
    else:
        return None
    # Same-sign turns also hold for a star that winds twice; the winding angle rules that out.
    if abs(area(ccw)) < 1e-12 or not _winds_once(ccw):
        return None
    return ccw


def _winds_once(ccw: Sequence[Point]) -> bool:
    n = len(ccw)
    total = 0.0
    for i in range(n):
        a, b, c = ccw[i - 1], ccw[i], ccw[(i + 1) % n]
        h1 = math.atan2(b[1] - a[1], b[0] - a[0])
        h2 = math.atan2(c[1] - b[1], c[0] - b[0])
        total += (h2 - h1 + math.pi) % (2 * math.pi) - math.pi
    return abs(total - 2 * math.pi) < 1e-6


def area(polygon: Sequence[Point]) -> float:
    """Signed area (positive for counter-clockwise)."""
    n = len(polygon)
    return 0.5 * sum(_cross((0.0, 0.0), polygon[i], polygon[(i + 1) % n]) for i in range(n))


def segment_box(p: Point, q: Point, thickness: float) -> tuple[Point, ...]:
    """The rectangle of a wall from p to q, `thickness` wide, with square caps of half the
    thickness at both ends so that walls meeting at a corner leave no notch."""
    length = math.dist(p, q)
    ux, uy = (q[0] - p[0]) / length, (q[1] - p[1]) / length
    h = thickness / 2
    ex, ey = ux * h, uy * h  # along the wall
    nx, ny = -uy * h, ux * h  # to its left
    return (
        (p[0] - ex - nx, p[1] - ey - ny),
        (q[0] + ex - nx, q[1] + ey - ny),
        (q[0] + ex + nx, q[1] + ey + ny),
        (p[0] - ex + nx, p[1] - ey + ny),
    )


def inside(point: Point, ccw: Sequence[Point]) -> bool:
    """Whether `point` is strictly inside a convex counter-clockwise polygon."""
    n = len(ccw)
    return all(_cross(ccw[i], ccw[(i + 1) % n], point) > 0 for i in range(n))


def bbox(points: Sequence[Point]) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of some points."""
    xs = [p[0] for p in points]
    ys = [p[1] for p in points]
    return (min(xs), min(ys), max(xs), max(ys))


class Budget:
    """A count of pairs looked at, shared by a check's parts: `spend(n)` is False once `most`
    are spent, so a check of any world within the file limits ends in bounded time."""

    def __init__(self, most: int):
        self.most, self.spent = most, 0

    def spend(self, count: int) -> bool:
        self.spent += count
        return self.spent <= self.most

    @property
    def exhausted(self) -> bool:
        return self.spent > self.most


class Near:
    """Convex polygons binned by their bounding boxes into square cells of `cell` m, to ask which
    come within `reach` of a point without looking at them all. A polygon covering more than
    `most_cells` cells is kept in a list every question looks through (binning it would cost more)."""

    def __init__(self, polygons: Sequence[Sequence[Point]], budget: Budget, cell: float = 0.25, most_cells: int = 16):
        self.polygons, self.cell, self.budget = polygons, cell, budget
        self.boxes = [bbox(p) for p in polygons]
        self.bins: dict[tuple[int, int], list[int]] = {}
        self.wide: list[int] = []
        for i, (x0, y0, x1, y1) in enumerate(self.boxes):
            c0, r0, c1, r1 = (math.floor(v / cell) for v in (x0, y0, x1, y1))
            if (c1 - c0 + 1) * (r1 - r0 + 1) > most_cells:
                self.wide.append(i)
                continue
            for c in range(c0, c1 + 1):
                for r in range(r0, r1 + 1):
                    self.bins.setdefault((c, r), []).append(i)

    def near(self, p: Point, reach: float) -> list[int]:
        """Indices of the polygons whose bounding box comes within `reach` of p, in index order;
        [] once the budget is spent."""
        x, y = p
        c0, r0, c1, r1 = (math.floor(v / self.cell) for v in (x - reach, y - reach, x + reach, y + reach))
        if (c1 - c0 + 1) * (r1 - r0 + 1) > 64:  # (a long reach: look through everything)
            if not self.budget.spend(len(self.polygons)):
                return []
            candidates: set[int] | range = range(len(self.polygons))
        else:
            candidates = {i for c in range(c0, c1 + 1) for r in range(r0, r1 + 1) for i in self.bins.get((c, r), ())}
            candidates.update(self.wide)
            if not self.budget.spend(len(candidates) + 1):
                return []
        found = sorted(i for i in candidates if _box_gap(self.boxes[i], p) <= reach)
        return found if self.budget.spend(sum(len(self.polygons[i]) for i in found)) else []


def _box_gap(box_: tuple[float, float, float, float], p: Point) -> float:
    dx = max(box_[0] - p[0], 0.0, p[0] - box_[2])
    dy = max(box_[1] - p[1], 0.0, p[1] - box_[3])
    return math.hypot(dx, dy)
