"""The map raster: shapes cut to the image before pygame fills them (a wall far outside the world,
a typo in a world file, once made pygame walk its whole extent for hours)."""

from __future__ import annotations

from sim.views.map_image import _clipped, map_png
from sim.world.spec import Wall, WorldSpec


def test_a_polygon_inside_the_image_is_kept_as_it_is():
    square = [(10.0, 10.0), (20.0, 10.0), (20.0, 20.0), (10.0, 20.0)]
    assert _clipped(square, 100, 100) == square


def test_a_polygon_far_outside_is_cut_away_and_one_across_is_cut_to_the_image():
    assert _clipped([(1e12, 1e12), (1e12 + 5, 1e12), (1e12, 1e12 + 5)], 100, 50) == []
    cut = _clipped([(-1e12, 25.0), (1e12, 20.0), (1e12, 30.0)], 100, 50)
    slack = 1e-3  # where an edge 2e12 px long meets the limit: its round-off, 2e12 * 2**-52 = 4e-4 px
    assert all(-1.0 - slack <= x <= 101.0 + slack and -1.0 <= y <= 51.0 for x, y in cut)
    assert min(x for x, _ in cut) < -1.0 + slack and max(x for x, _ in cut) > 101.0 - slack  # spans the image
    assert len(cut) == 4  # the triangle's tip is cut off on both sides


def test_a_world_with_a_wall_a_million_kilometres_away_draws():
    world = WorldSpec("far", (0.0, 0.0, 2.0, 1.0), walls=(Wall(((0.0, 0.5), (1e9, 1e9), (1e9, 1e9 + 0.01), (0.0, 0.51))),))
    png, per_metre = map_png(world)
    assert png.startswith(b"\x89PNG") and per_metre == 500.0
