"""Compiled plane geometry of convex walls and circles: a point's distance to a polygon, a ray's
first crossing of a polygon or a circle, the nearest corner inside a cone. Shared by the contacts
and the sensors."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import INNER


@numba.njit(cache=True, **INNER)
def ray_polygon(ox: float, oy: float, ux: float, uy: float, vertices: np.ndarray, start: int, end: int) -> float:
    """Distance along the ray (origin, unit direction) to its first crossing of the polygon's
    edges vertices[start:end]; inf if none."""
    best = math.inf
    for k in range(start, end):
        ax, ay = vertices[k, 0], vertices[k, 1]
        nxt = k + 1 if k + 1 < end else start
        ex, ey = vertices[nxt, 0] - ax, vertices[nxt, 1] - ay
        denom = ux * ey - uy * ex
        if denom == 0.0:
            continue
        wx, wy = ax - ox, ay - oy
        t = (wx * ey - wy * ex) / denom
        u = (wx * uy - wy * ux) / denom
        if t >= 0.0 and 0.0 <= u <= 1.0 and t < best:
            best = t
    return best


@numba.njit(cache=True, **INNER)
def ray_circle(ox: float, oy: float, ux: float, uy: float, cx: float, cy: float, r: float) -> float:
    along = (cx - ox) * ux + (cy - oy) * uy
    across2 = (cx - ox) ** 2 + (cy - oy) ** 2 - along * along
    if along < 0.0 or across2 > r * r:
        return math.inf
    return along - math.sqrt(r * r - across2)


@numba.njit(cache=True, **INNER)
def polygon_distance(px: float, py: float, vertices: np.ndarray, start: int, end: int) -> tuple[float, float, float]:
    """(signed distance, closest point x, y) from a point to the convex polygon
    vertices[start:end] (either winding); negative inside."""
    best, cx, cy = math.inf, px, py
    positive = negative = False
    for k in range(start, end):
        ax, ay = vertices[k, 0], vertices[k, 1]
        nxt = k + 1 if k + 1 < end else start
        ex, ey = vertices[nxt, 0] - ax, vertices[nxt, 1] - ay
        side = ex * (py - ay) - ey * (px - ax)
        positive |= side > 0.0
        negative |= side < 0.0
        t = min(max(((px - ax) * ex + (py - ay) * ey) / (ex * ex + ey * ey), 0.0), 1.0)
        qx, qy = ax + t * ex, ay + t * ey
        d2 = (px - qx) ** 2 + (py - qy) ** 2
        if d2 < best:
            best, cx, cy = d2, qx, qy
    distance = math.sqrt(best)
    return (distance if positive and negative else -distance), cx, cy
