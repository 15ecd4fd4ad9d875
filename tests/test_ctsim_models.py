"""The c't-Sim-compatible models a bridged firmware bot gets (`sim.bridge.session.as_in_ctsim`,
c't-Sim's lamp pillars and line outlines), each against a closed-form value from c't-Sim's rules:
encoder arithmetic, the line sensors' spot, flat line ends, the lamp cylinder."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.ctbot import CTBOT
from sim.bridge.firmware import ENCODER_MARKS, CtsimEncoders, revs_per_second
from sim.bridge.session import CTSIM_LINE_HEIGHT, as_in_ctsim
from sim.world import World
from sim.world.files import load_world
from sim.world.files.grid import LINE_HEIGHT, PILLAR_DIAMETER, PILLAR_SIDES, build_grid
from sim.world.floor import rasterize
from sim.world.spec import WHITE, FloorLine, WorldSpec

# --- encoders ------------------------------------------------------------------------------------


def test_wheel_speed_is_a_double_product_of_two_float32_factors():
    """c't-Sim: `governor.floatValue() / PWM_MAX` is float32, `REVS_PER_SEC_MAX = 151f / 60f` is
    float32, their product is taken in double. At 30 units that is 0.2960784306 rev/s, below the
    exact 151 / 510 = 0.2960784314; the product rounded to float32 would be 0.2960784435, above."""
    assert revs_per_second(30) == pytest.approx(0.29607843060557747, abs=1e-17)
    assert revs_per_second(30) < 151 / 510 < float(np.float32(revs_per_second(30)))


def test_ticks_of_an_exact_boundary_come_a_step_late_in_double_arithmetic():
    """30 units make exactly 151 ticks in 850 steps of 10 ms (0.1776 ticks a step). c't-Sim's speed
    is a hair slow (above), so the 151st tick comes with step 851, not 850; a float32 product,
    a hair fast, would give it with step 850."""
    assert 30 / 255 * 151 / 60 * 0.01 * ENCODER_MARKS * 850 == pytest.approx(151, abs=1e-9)
    encoders = CtsimEncoders(0.01)
    total = np.cumsum([encoders.count((30, 30))[0] for _ in range(860)])
    assert total[849] == 150 and total[850] == 151  # step 850 (index 849) has 150, step 851 the 151st


# --- line sensors ----------------------------------------------------------------------------------

LINE_EDGE = 0.100  # m, the right edge of the test line (on the floor raster's 2 mm cells)


def line_world(line_height: float = 0.0, **line) -> WorldSpec:
    """White floor, one black vertical line 24 mm wide from y = 0.2 to 0.8 with its right edge
    at LINE_EDGE, its top `line_height` above the floor."""
    centre = LINE_EDGE - 0.012
    return WorldSpec("line", (0.0, 0.0, 1.0, 1.0), lines=(FloorLine(((centre, 0.2), (centre, 0.8)), **line),), floor_colour=WHITE, line_height=line_height)


def line_values(spec, x: float, y: float, heading: float, **line) -> list[int]:
    w = World(line_world(**line))
    w.add_robot(spec, (x, y, heading))
    return [int(v) for v in w.read_all()[0].line]


def test_bridged_line_sensors_average_c_t_sims_cross_of_rays():
    """c't-Sim's line sensor sends 5 rays across the heading and 5 along it, 20 degrees apart, from
    3 mm over the floor: they meet it 0, 1.09 and 2.52 mm off the mount point. Facing +y with the
    left sensor 1.5 mm right of the line's edge, one ray of the cross fan (2.52 mm to the left)
    lands on black: that fan reads int(1/5 * 1023) = 204, the other 0, the sensor their mean, 102.
    The right sensor, 8 mm off, sees white only; ctsim's own one-point sensors read 0 and 0."""
    x = LINE_EDGE + 0.0015 + 0.004  # the left sensor sits 4 mm left of the centre
    bridged = as_in_ctsim(CTBOT)
    assert all(sensor.height == CTSIM_LINE_HEIGHT == 0.003 for sensor in bridged.line)
    assert CTSIM_LINE_HEIGHT * math.tan(math.radians(40)) == pytest.approx(0.00252, abs=1e-5)
    assert line_values(bridged, x, 0.5, math.pi / 2) == [102, 0]
    assert line_values(CTBOT, x, 0.5, math.pi / 2) == [0, 0]


def test_c_t_sims_lines_lie_1_mm_above_its_floor():
    """c't-Sim's line tiles lie 1 mm above its floor tiles (a parcours' `line_height`), so a line
    sensor's rays meet a line 2 mm below it (the 40 degree ray 1.68 mm off) and the floor 3 mm
    below (2.52 mm off). With the left sensor 2.0 mm right of the line's edge, a flat line is met
    by the 40 degree ray (102, as above), a raised one is missed (that ray passes its edge and
    goes on to the white floor: 0); 1.5 mm right, both are met. A parcours' lines are raised."""
    bridged = as_in_ctsim(CTBOT)
    for off, flat, raised in ((0.0020, 102, 0), (0.0015, 102, 102)):
        x = LINE_EDGE + off + 0.004
        assert line_values(bridged, x, 0.5, math.pi / 2)[0] == flat
        assert line_values(bridged, x, 0.5, math.pi / 2, line_height=LINE_HEIGHT)[0] == raised
    assert (CTSIM_LINE_HEIGHT - LINE_HEIGHT) * math.tan(math.radians(40)) == pytest.approx(0.00168, abs=1e-5)


def test_a_parcours_lines_are_raised(tmp_path):
    path = tmp_path / "lines.xml"
    path.write_text("<world><parcours><line>#|#</line><line>#0#</line></parcours></world>")
    assert load_world(path).line_height == LINE_HEIGHT == 0.001


def test_c_t_sims_line_tiles_end_flat_at_their_cell():
    """A line tile ends at its cell's edge (ParcoursLoader's outlines); a round end reaches half a
    width (12 mm) further. 6 mm past the end the flat line is floor, the round one still black."""
    past_end = (LINE_EDGE - 0.012, 0.806)
    for flat, expected in ((True, 0.0), (False, 1.0)):
        floor = rasterize(line_world(flat=flat))
        ix, iy = (int(math.floor((p - o) / floor.cell)) for p, o in zip(past_end, floor.origin))
        assert floor.absorption[iy, ix] == pytest.approx(expected)


def test_a_corner_tile_is_square_like_c_t_sims():
    """'/' (east and south arms): its outer corner at (centre - w/2, centre + w/2) is black, as
    the L-shaped outline in c't-Sim; a round joint would leave it white (it is w/2 * sqrt 2 from
    the centre)."""
    pieces = build_grid(["/"], cell=0.24)
    floor = rasterize(WorldSpec("corner", pieces.bounds, lines=pieces.lines, floor_colour=WHITE))
    corner = (0.12 - 0.012 + 0.001, 0.12 + 0.012 - 0.001)  # 1 mm inside the outer corner
    ix, iy = (int(math.floor((p - o) / floor.cell)) for p, o in zip(corner, floor.origin))
    assert floor.absorption[iy, ix] == 1.0


# --- lamp pillars -----------------------------------------------------------------------------------


def test_a_lamp_pillar_is_c_t_sims_cylinder():
    """With pillars='cylinder' a '*' is Java3D's cylinder of 0.1 m diameter: 15 corners on the
    circle of 0.05 m round the cell centre, one due north, and no part of a wall run: `*==*`
    gives the run's box over the two '=' cells alone and two cylinders."""
    pieces = build_grid(["*==*"], cell=0.24, pillars="cylinder")
    boxes = [w for w in pieces.walls if len(w.vertices) == 4]
    pillars = [w for w in pieces.walls if len(w.vertices) == PILLAR_SIDES]
    assert len(boxes) == 1 and len(pillars) == 2
    assert {round(x, 9) for x, _ in boxes[0].vertices} == {0.24, 0.72}
    for pillar, cx in zip(pillars, (0.12, 0.84)):
        offsets = [(x - cx, y - 0.12) for x, y in pillar.vertices]
        assert all(math.hypot(*o) == pytest.approx(PILLAR_DIAMETER / 2, abs=1e-12) for o in offsets)
        assert any(o == pytest.approx((0.0, 0.05), abs=1e-12) for o in offsets)
    by_default = build_grid(["*==*"], cell=0.24)
    assert [len(w.vertices) for w in by_default.walls] == [4] and {round(x, 9) for x, _ in by_default.walls[0].vertices} == {0.0, 0.96}


def test_ir_sees_the_cylinders_flat_south_face():
    """Java3D's 15-gon with a corner due north has a flat edge due south, r cos(12 deg) = 48.9 mm
    from its axis: a bot facing north with its left IR sensor (36 mm left of its centre, 55.4 mm
    ahead) 0.3 m south of the axis sees that face 0.196 m ahead, where a whole-cell pillar's
    wall would be 0.125 m ahead (120 mm from the axis)."""
    pieces = build_grid(["*"], cell=0.24, pillars="cylinder")
    world = WorldSpec("pillar", (-1.0, -1.0, 1.24, 1.24), walls=pieces.walls)
    w = World(world)
    w.add_robot(as_in_ctsim(CTBOT), (0.12 + 0.036, 0.12 - 0.3 - 0.0554, math.pi / 2))
    face = 0.05 * math.cos(math.radians(12))
    assert face == pytest.approx(0.0489, abs=1e-4)
    seen = w.read_all()[0].ir_distance[0]
    assert seen == pytest.approx(0.3 - face, abs=0.004)  # the firmware's inverse table: a few mm steps
