"""The map of a world as data (`map_shapes`) and as a raster image (`map_surface`, `map_png`).

One list of shapes, in drawing order, is what every view draws: the PNG figures turn it into
matplotlib patches (vector, `figures.draw_world`), the rerun recording and the pygame window into
pixels here. The raster is drawn with pygame, not matplotlib: a run's recording then costs no
plotting library (matplotlib alone is 35 MB of a run's memory).
"""

from __future__ import annotations

import functools
import io
import math
import os
from dataclasses import dataclass
from typing import Literal

import numpy as np

from sim.views import palette
from sim.world.spec import WorldSpec

STAR_RADIUS_PX = 9
"""Outer radius of a light's star in the raster (about the figures' 13 pt marker at 100 px/inch)."""


@dataclass(frozen=True)
class Shape:
    """One element of the map: a filled polygon (`points` (k, 2), m), a filled circle (`points`
    the centre (1, 2) and `radius` m) or a light (a star marker at `points` (1, 2)); colours 0-255
    RGB, `edge` None for none; `edge_pt` the edge's width in points (figures; 1 px in rasters)."""

    kind: Literal["polygon", "circle", "light"]
    points: np.ndarray
    fill: palette.RGB
    edge: palette.RGB | None = None
    edge_pt: float = 0.0
    radius: float = 0.0


def map_shapes(world: WorldSpec) -> list[Shape]:
    """Ground, floor regions, painted lines (at their true width), holes, goals, walls, cans (at
    their start) and lights, bottom to top."""
    xmin, ymin, xmax, ymax = world.bounds
    ground = np.array([(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)])
    shapes = [Shape("polygon", ground, palette.from_unit(world.floor_colour), (153, 153, 153), 0.5)]
    shapes += [Shape("polygon", np.asarray(r.vertices, float), palette.from_unit(r.colour)) for r in world.floor]
    for line in world.lines:
        points, half, colour = np.asarray(line.points, dtype=float), line.width / 2, palette.from_unit(line.colour)
        for a, b in zip(points[:-1], points[1:]):
            normal = np.array((a[1] - b[1], b[0] - a[0])) / max(np.hypot(*(b - a)), 1e-12) * half
            shapes.append(Shape("polygon", np.array([a + normal, b + normal, b - normal, a - normal]), colour))
        shapes += [Shape("circle", p[None], colour, radius=half) for p in points]
    shapes += [Shape("polygon", np.asarray(h.vertices, float), palette.HOLE, palette.HOLE_EDGE, 1.0) for h in world.holes]
    shapes += [Shape("polygon", np.asarray(g.vertices, float), palette.GOAL, palette.GOAL_EDGE, 0.8) for g in world.goals]
    shapes += [Shape("polygon", np.asarray(w.vertices, float), palette.WALL, palette.WALL_EDGE, 0.6) for w in world.walls]
    shapes += [Shape("circle", np.asarray(c.position, float)[None], palette.CAN, palette.WALL_EDGE, 0.5, c.radius) for c in world.movables]
    shapes += [Shape("light", np.asarray(light.position, float)[None], palette.LIGHT, palette.LIGHT_EDGE, 1.0) for light in world.lights]
    return shapes


def _pygame():
    """pygame, without its greeting; drawing on surfaces needs no display."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame

    return pygame


def map_surface(world: WorldSpec, per_metre: float):
    """A pygame Surface of `world.bounds` edge to edge at `per_metre` pixels per metre, y up."""
    pygame = _pygame()
    xmin, ymin, xmax, ymax = world.bounds
    width, height = max(1, round((xmax - xmin) * per_metre)), max(1, round((ymax - ymin) * per_metre))
    surface = pygame.Surface((width, height))
    surface.fill(palette.BACKGROUND)

    def px(points: np.ndarray) -> list[tuple[float, float]]:
        return [((x - xmin) * per_metre, (ymax - y) * per_metre) for x, y in points]

    def polygon(colour: palette.RGB, corners: list[tuple[float, float]], edge: int = 0) -> None:
        corners = _clipped(corners, width, height)
        if len(corners) >= 3:
            pygame.draw.polygon(surface, colour, corners, edge)

    for shape in map_shapes(world):
        if shape.kind == "polygon":
            polygon(shape.fill, px(shape.points))
            if shape.edge is not None:
                polygon(shape.edge, px(shape.points), 1)
        elif shape.kind == "circle":
            (x, y), radius = px(shape.points)[0], max(1.0, shape.radius * per_metre)
            if -radius < x < width + radius and -radius < y < height + radius:
                pygame.draw.circle(surface, shape.fill, (x, y), min(radius, width + height))
                if shape.edge is not None:
                    pygame.draw.circle(surface, shape.edge, (x, y), min(radius, width + height), 1)
        else:
            star = _star(*px(shape.points)[0], STAR_RADIUS_PX)
            polygon(shape.fill, star)
            polygon(shape.edge, star, 1)
    return surface


def _clipped(corners: list[tuple[float, float]], width: int, height: int) -> list[tuple[float, float]]:
    """A polygon (pixels) cut to the image and a pixel around it (Sutherland-Hodgman): pygame walks
    a polygon's whole extent, which for a wall a million kilometres off (a typo in a world file)
    takes hours; the cut edges lie outside the image."""
    for axis, limit, below in ((0, -1.0, False), (0, width + 1.0, True), (1, -1.0, False), (1, height + 1.0, True)):
        inside = [(p[axis] <= limit) == below for p in corners]
        kept = []
        for k, point in enumerate(corners):
            previous = corners[k - 1]
            if inside[k] != inside[k - 1]:  # the edge from the previous corner crosses the limit
                t = (limit - previous[axis]) / (point[axis] - previous[axis])
                kept.append((previous[0] + t * (point[0] - previous[0]), previous[1] + t * (point[1] - previous[1])))
            if inside[k]:
                kept.append(point)
        corners = kept
    return corners


def _star(x: float, y: float, radius: float) -> list[tuple[float, float]]:
    """A five-pointed star around (x, y) in pixels, a point upwards."""
    corners = []
    for k in range(10):
        r, angle = (radius if k % 2 == 0 else radius * 0.45), math.pi / 2 + k * math.pi / 5
        corners.append((x + r * math.cos(angle), y - r * math.sin(angle)))
    return corners


@functools.lru_cache(maxsize=8)
def map_png(world: WorldSpec, max_pixels: int = 2000) -> tuple[bytes, float]:
    """The map as PNG bytes covering `world.bounds` edge to edge, at most `max_pixels` (and 500
    per metre) along its longer side, and its resolution (pixels per metre). Kept for the last
    few worlds: encoding takes 50-120 ms, which every recording of a sweep or a lab's runs of one
    world would otherwise pay again."""
    xmin, ymin, xmax, ymax = world.bounds
    per_metre = min(500.0, max_pixels / max(xmax - xmin, ymax - ymin))
    surface = map_surface(world, per_metre)
    return _png(surface), surface.get_width() / (xmax - xmin)


def rgba_png(rgba: np.ndarray) -> bytes:
    """An RGBA image (rows, columns, 4) uint8 as PNG bytes, encoded by pygame as the map is."""
    height, width = rgba.shape[:2]
    return _png(_pygame().image.frombuffer(np.ascontiguousarray(rgba, dtype=np.uint8).tobytes(), (width, height), "RGBA"))


def _png(surface) -> bytes:  # noqa: ANN001 (a pygame Surface)
    buffer = io.BytesIO()
    _pygame().image.save(surface, buffer, "map.png")
    return buffer.getvalue()
