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
