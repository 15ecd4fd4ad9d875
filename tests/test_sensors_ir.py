"""Issue 3 and 12: IR distance sensors read hand-computed distances to walls and other robots
(the nearest point within c't-Sim's 3-degree cone) through the characteristic curves, read as
c't-Sim reads its measured files."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from shared_data import CURVES
from shared_data import needs_curves as needs_shared

from bots.ctbot import CTBOT
from bots.ir_curve import CurveFileError, IRCurve, gp2d12, load_ir_curve
from bots.spec import IRSensorSpec
from sim.world import World
from sim.world.files.grid import build_grid
from sim.world.spec import Wall, WorldSpec, box

SENSOR_X, SENSOR_Y = CTBOT.ir[0].position  # 0.0554 forward, 0.036 to the left


def read_file(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(distance m, value) rows of a characteristic file, parsed here independently."""
    rows = []
    for line in (CURVES / name).read_text(encoding="latin-1").splitlines()[2:]:
        cells = [c.strip() for c in line.split(";") if c.strip()]
        if cells:
            rows.append((float(cells[0]) / 100, float(cells[1])))
    table = np.array(rows)
    return table[:, 0], table[:, 1]


def inverse_resolution(curve, distance: float) -> float:
    """Distance (m) that half a raw unit spans on the curve around `distance` (the steeper-less of
    the two table segments next to it): how far a rounded raw value can move the inverse."""
    k = int(np.searchsorted(curve.distance, distance))
    slopes = [
        abs((curve.raw[j + 1] - curve.raw[j]) / (curve.distance[j + 1] - curve.distance[j]))
        for j in (k - 2, k - 1, k)
        if 0 <= j < len(curve.distance) - 1
    ]
    return 0.5 / min(slopes)


def wall_world(distance_from_sensor: float, heading: float = 0.0) -> tuple[World, object]:
    """A robot at the origin facing `heading`, with a wall across its way whose face is
    `distance_from_sensor` ahead of the IR sensors' plane."""
    c, s = math.cos(heading), math.sin(heading)
    face = SENSOR_X + distance_from_sensor
    local = ((face, -1.0), (face + 0.05, -1.0), (face + 0.05, 1.0), (face, 1.0))
    wall = Wall(tuple((c * x - s * y, s * x + c * y) for x, y in local))
    world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(wall,)))
    return world, world.add_robot(CTBOT, (0.0, 0.0, heading))


@pytest.mark.parametrize("heading", [0.0, 0.7, -2.3])
@pytest.mark.parametrize("distance", [0.08, 0.1, 0.1537, 0.3, 0.42, 0.6, 0.79])
def test_ir_reads_the_curve_at_the_distance_to_a_wall(distance, heading):
    """Facing a wall at a known distance (any heading): ir_raw is the curve's value at exactly that
    distance from each sensor, and from 0.1 m on ir_distance gives it back within the curve's
    inverse resolution."""
    world, robot = wall_world(distance, heading)
    r = world.read_all()[0]
    for k, curve in enumerate(robot.ir_curves):
        assert r.ir_raw[k] == curve.lookup(distance)
        if distance >= 0.1:  # below, the sensor folds back: its value is that of a farther distance
            assert abs(r.ir_distance[k] - distance) <= inverse_resolution(curve, distance) + 1e-12


def test_ir_errors_stay_small_over_the_range():
    """Over 0.1-0.8 m in 1 cm steps the inverse error stays within the resolution bound (the worst
    case is reported in the assertion message), except where the right sensor reads 80, c't-Sim's
    value for nothing in view, which the inverse takes for nothing (nan)."""
    worst = 0.0
    for distance in np.arange(0.10, 0.80, 0.01):
        world, robot = wall_world(float(distance))
        r = world.read_all()[0]
        nothing = r.ir_raw == [c.beyond for c in robot.ir_curves]
        assert np.array_equal(np.isnan(r.ir_distance), nothing)
        assert not nothing[0] and (not nothing[1] or 0.745 < distance < 0.765)
        error = np.where(nothing, 0.0, np.abs(r.ir_distance - distance))
        worst = max(worst, float(error.max()))
        assert all(e <= inverse_resolution(c, distance) + 1e-12 for e, c in zip(error, robot.ir_curves))
    assert worst < 0.02, f"worst IR distance error {worst * 1000:.1f} mm"


def cone_distance_to_circle(origin, axis: float, half_angle: float, centre, radius: float) -> float:
    """Nearest point of a circle within a cone, by hand: the point towards the centre if that
    direction lies in the cone, else the nearer first hit of the two edge rays (inf if none)."""
    ox, oy = centre[0] - origin[0], centre[1] - origin[1]
    if abs(math.atan2(oy, ox) - axis) <= half_angle:
        return math.hypot(ox, oy) - radius
    best = math.inf
    for a in (axis - half_angle, axis + half_angle):
        along = ox * math.cos(a) + oy * math.sin(a)
        across2 = ox * ox + oy * oy - along * along
        if along > 0 and across2 <= radius * radius:
            best = min(best, along - math.sqrt(radius * radius - across2))
    return best


def test_ir_sees_another_robot_and_skips_its_own_body():
    """A robot 0.3 m ahead (slightly to the side): one ray along each sensor's axis meets the other
    body's circle where the hand-computed chord says, and the sensors read the nearest point of
    the circle within their 3-degree cone (here the edge ray nearer the centre: shorter); the sensors sit inside their own body, which they do not see."""
    world = World(WorldSpec("open", (-2, -2, 2, 2)))
    me = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    cx, cy, radius = 0.3, 0.02, CTBOT.body_radius
    world.add_robot(CTBOT, (cx, cy, 1.0))
    r = world.read_all()[0]
    for k, sensor in enumerate(CTBOT.ir):
        sx, sy = sensor.position
        expected = (cx - sx) - math.sqrt(radius**2 - (sy - cy) ** 2)
        assert abs(world.ray_distance(me, (sx, sy), 0.0) - expected) < 1e-9
        in_cone = cone_distance_to_circle((sx, sy), 0.0, sensor.cone, (cx, cy), radius)
        assert abs(world.ray_distance(me, (sx, sy), 0.0, cone=sensor.cone) - in_cone) < 1e-9
        assert expected - in_cone > 0.0
        assert r.ir_raw[k] == me.ir_curves[k].lookup(in_cone)
        assert abs(r.ir_distance[k] - in_cone) <= inverse_resolution(me.ir_curves[k], in_cone) + 1e-12


@pytest.mark.parametrize("slant", [0.0, 2.0, 30.0, 60.0, 80.0])
def test_a_slanted_wall_reads_at_the_cone_edge(slant):
    """A wall whose normal is `slant` degrees off the sensor's axis, met by the axis at 0.6 m: the
    cone's nearest point is the foot of the perpendicular while that lies in the cone (slant
    within 3 degrees), else on the edge ray nearer the normal, at 0.6 cos(slant) / cos(slant - 3);
    at 60 degrees that is 49 mm short of the axis (the figure in issue 12)."""
    world = World(WorldSpec("w", (-3, -3, 3, 3)))
    me = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    sx, sy = CTBOT.ir[0].position
    phi, cone = math.radians(slant), CTBOT.ir[0].cone
    normal, along = np.array((math.cos(phi), math.sin(phi))), np.array((-math.sin(phi), math.cos(phi)))
    hit = np.array((sx + 0.6, sy))
    face = [hit - 2 * along, hit + 2 * along, hit + 2 * along + 0.05 * normal, hit - 2 * along + 0.05 * normal]
    world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(Wall(tuple(map(tuple, face))),)))
    me = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    foot = 0.6 * math.cos(phi)
    expected = foot if phi <= cone else foot / math.cos(phi - cone)
    assert abs(world.ray_distance(me, (sx, sy), 0.0, cone=cone) - expected) < 1e-9
    if slant == 60.0:
        assert round((0.6 - expected) * 1000) == 49


def test_ir_with_nothing_in_range_reads_the_far_value():
    """Nothing within 0.85 m: the ray returns inf, ir_raw c't-Sim's values for nothing in view
    (100 left, 80 right: the built-in fit read 103/71 before issue 12), ir_distance nan."""
    world = World(WorldSpec("open", (-2, -2, 2, 2)))
    me = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    r = world.read_all()[0]
    assert world.ray_distance(me, (SENSOR_X, SENSOR_Y), 0.0, cone=CTBOT.ir[0].cone) == math.inf
    assert [int(v) for v in r.ir_raw] == [100, 80]
    assert np.all(np.isnan(r.ir_distance))


def test_ir_lookup_follows_ctsim_characteristic():
    """The shipped left table read as c't-Sim's `Characteristic.lookupPrecise`, by hand: 30 cm ->
    206; 31 cm lies a quarter of the way from 206 (30) to 189 (34): 201.75 -> 202; 85 cm, the
    last row, reads it (100); beyond 85 cm and closer than 0 the sensor reads `beyond`."""
    left = gp2d12("left")
    assert list(left.lookup(np.array((0.30, 0.31, 0.85, 0.8501, 5.0, math.inf)))) == [206, 202, 100, 100, 100, 100]
    right = gp2d12("right")
    assert list(right.lookup(np.array((0.0, 0.10, 0.80, 0.86)))) == [173, 511, 76, 80]


@needs_shared
@pytest.mark.parametrize("name", ["gp2d12Left.txt", "gp2d12Right.txt", "gp2y0a60Left.txt", "vl53l0xRight.txt"])
def test_curve_files_are_matched_exactly_and_interpolated_with_rounding(name):
    """A characteristic file is reproduced exactly at its tabulated distances and interpolated
    linearly, then rounded, between them (checked at 2000 random distances, ties excepted)."""
    distance, value = read_file(name)
    curve = load_ir_curve(CURVES / name)
    assert np.array_equal(curve.lookup(distance), value.astype(int))
    probe = np.random.default_rng(5).uniform(distance[0], distance[-1], 2000)
    k = np.clip(np.searchsorted(distance, probe, side="right") - 1, 0, len(distance) - 2)
    w = (probe - distance[k]) / (distance[k + 1] - distance[k])
    exact = value[k] + w * (value[k + 1] - value[k])
    clear = np.abs(exact - np.floor(exact) - 0.5) > 1e-3  # c't-Sim's float32 table moves a tie by ~1e-4
    assert np.array_equal(curve.lookup(probe)[clear], np.floor(exact[clear] + 0.5).astype(int))


@needs_shared
def test_a_sensor_naming_a_file_uses_it_and_left_and_right_differ():
    """IRSensorSpec(curve="gp2d12Left.txt") resolves in the shared folder: at 0.3 m the robot's left
    and right sensors read the files' 206 and 191; at 0.8 m 110 and 76."""
    left, right = CTBOT.ir
    spec = CTBOT.with_changes(
        ir=(IRSensorSpec(left.name, left.position, curve="gp2d12Left.txt"), IRSensorSpec(right.name, right.position, side="right", curve="gp2d12Right.txt"))
    )
    for distance, expected in ((0.3, [206, 191]), (0.8, [110, 76]), (0.1, [525, 511])):
        world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(Wall(((SENSOR_X + distance, -1), (1.5, -1), (1.5, 1), (SENSOR_X + distance, 1))),)))
        world.add_robot(spec, (0.0, 0.0, 0.0))
        assert list(world.read_all()[0].ir_raw) == expected


RISING = IRCurve(np.array([0.0, 0.01, 0.1, 0.5, 0.8, 1.2]), np.array([20.0, 10.0, 100.0, 500.0, 800.0, 1200.0]), 2000.0, name="rising")
"""A time-of-flight sensor's curve as c't-Sim's vl53l0x files give it: raw in mm, rising with the distance."""


def test_a_rising_curve_reads_back_its_distance():
    """The firmware's inverse of a curve whose raw values rise with the distance (a VL53L0X):
    the distance in range, min_range nearer (raw below the branch), nan farther and for nothing in
    view; the falling GP2D12's as before (0.1 m at its fold-back peak, nan past 0.8 m)."""
    raw = RISING.lookup(np.array([0.005, 0.05, 0.1, 0.25, 0.8, 0.81, 1.3]))
    assert list(raw) == [15, 50, 100, 250, 800, 810, 2000]
    assert np.allclose(RISING.distance_from_raw(raw), [0.1, 0.1, 0.1, 0.25, 0.8, np.nan, np.nan], equal_nan=True)
    left = gp2d12("left")
    assert np.allclose(left.distance_from_raw(left.lookup(np.array([0.09, 0.3, 0.81]))), [0.1, 0.3, np.nan], atol=0.005, equal_nan=True)


def test_a_range_into_the_fold_back_reads_the_far_branch():
    """A range nearer than a GP2D12's peak (9 cm): a raw value there is two distances, and reads as
    the one on the branch that reaches max_range, for every raw value (interpolating across the
    turn gave distances on neither branch)."""
    left = gp2d12("left")
    inverse = left.inverse(0.05, 0.5)
    far = left.lookup(np.array([0.12, 0.2, 0.4]))
    assert np.allclose(inverse(far), [0.12, 0.2, 0.4], atol=0.003)
    folded = left.lookup(np.array([0.06]))  # 400 on the fold-back, also about 14 cm on the far branch
    assert 0.13 < float(inverse(folded)[0]) < 0.15
    seen = inverse(np.arange(left.raw_range()[0], left.raw_range()[1] + 1))
    assert np.all(np.diff(seen[np.isfinite(seen)]) <= 0)  # one branch: nearer as the raw value rises


def test_a_range_between_two_rows_is_refused_in_one_line(tmp_path, capsys):
    """min_range and max_range between two rows of the curve (the GP2D12's 80 and 85 cm): no
    distance can be read back there; the run is refused naming the curve and the range (it crashed
    with a traceback), nothing left in its folder."""
    from sim.cli.entry import main

    with pytest.raises(CurveFileError, match="fewer than two rows between min_range 0.81 m and max_range 0.84 m"):
        gp2d12("left").inverse(0.81, 0.84)
    out = tmp_path / "o"
    assert main(["run", "--robot-set", "ir.max_range=0.84", "--robot-set", "ir.min_range=0.81", "--duration", "1", "--out", str(out)]) == 2
    assert "fewer than two rows" in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("row", ["10; nan;", "10; inf;", "10; -5;", "10; 1e308;", "99999999999; 5;", "10;", "ten; 5;"])
def test_a_curve_file_with_a_bad_row_is_refused_naming_its_line(tmp_path, row):
    """Rows that would crash the table (nan, inf), fill the memory (a distance of 1e11 cm is a
    table of 400 GB) or make no sense: CurveFileError naming the file and line, nothing else."""
    path = tmp_path / "curve.txt"
    path.write_text(f"header\nheader\n0; 100;\n{row}\n80; 50;\n")
    if row.startswith("ten"):  # (not a row: skipped as a header line, the two others make the curve)
        assert len(load_ir_curve(path).raw) == 2
        return
    with pytest.raises(CurveFileError, match=f"{path}:4:"):
        load_ir_curve(path)


@needs_shared
def test_a_ctbot_with_time_of_flight_sensors_sees_its_walls():
    """The c't-Bot with c't-Sim's VL53L0X tables: 0.3 m to a wall reads 300 (mm) and is believed
    0.3 m (the inverse read the falling GP2D12 branch's way once: solve_maze walled itself in)."""
    left, right = CTBOT.ir
    spec = CTBOT.with_changes(ir=(replace(left, curve="vl53l0xLeft.txt"), replace(right, curve="vl53l0xRight.txt")))
    world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(Wall(((SENSOR_X + 0.3, -1), (1.5, -1), (1.5, 1), (SENSOR_X + 0.3, 1))),)))
    world.add_robot(spec, (0.0, 0.0, 0.0))
    readings = world.read_all()[0]
    assert list(readings.ir_raw) == [300, 300]
    assert np.allclose(readings.ir_distance, 0.3, atol=0.002)


@needs_shared
@pytest.mark.parametrize("side", ["left", "right"])
def test_shipped_tables_are_ctsims_files(side):
    """The c't-Bot's default tables (bots/curves/gp2d12.toml) hold exactly the numbers of
    c't-Sim's gp2d12Left/Right.txt and read as the files do everywhere from 0 to 90 cm."""
    distance, value = read_file(f"gp2d12{side.title()}.txt")
    shipped = gp2d12(side)
    assert np.array_equal(shipped.distance, distance) and np.array_equal(shipped.raw, value)
    probe = np.linspace(0.0, 0.9, 9001)
    assert np.array_equal(shipped.lookup(probe), load_ir_curve(CURVES / f"gp2d12{side.title()}.txt").lookup(probe))


def test_compiled_cone_agrees_with_pymunk_queries():
    """The world reads IR with a compiled kernel (`kernels.sensing.sense_ir`: walls, robots, cans); at 300
    random poses in the maze beside another robot and a can it gives the distances of
    `World.ray_distance`'s pymunk queries (to 1e-9 m: two exact computations of one geometry)."""
    from sim.world import layout
    from sim.world.files import load_world
    from sim.world.kernels.sensing import sense_ir
    from sim.world.spec import Movable

    spec = load_world("maze")
    world = World(WorldSpec("maze+can", spec.bounds, walls=spec.walls, movables=(Movable((0.9, 0.4)),)))
    me = world.add_robot(CTBOT, (0.4, 0.4, 0.0))
    world.add_robot(CTBOT, (0.7, 0.45, 2.0))
    rng = np.random.default_rng(12)
    points = rng.uniform(0.1, 3.0, (300, 2))
    looks = rng.uniform(-math.pi, math.pi, 300)
    cones = np.full(300, CTBOT.ir[0].cone)
    out = np.empty(300)
    circles = layout.CIRCLES.new(3)
    for k, (x, y, radius, owner) in enumerate([(r.body.position.x, r.body.position.y, r.shape.radius, r.index) for r in world.robots]
                                              + [(world.movables[0].position.x, world.movables[0].position.y, 0.015, -1)]):
        circles[k] = (x, y, radius, owner)
    rays = layout.Rays(points, looks, cones, np.zeros(300, dtype=np.int64), np.zeros(300, dtype=np.bool_))
    sense_ir(rays, world._walls, circles, 0.85, out)
    expected = [world.ray_distance(me, p, a, cone=c) for p, a, c in zip(points, looks, cones)]
    expected = np.asarray(expected)
    finite = np.isfinite(expected)
    assert finite.sum() > 200 and (expected == 0).any()  # mostly walls in view; some points inside a wall
    assert np.array_equal(np.isfinite(out), finite)
    assert np.allclose(out[finite], expected[finite], atol=1e-9, rtol=0)


@pytest.mark.parametrize("slant", [0.0, 2.0, 30.0, 60.0])
def test_the_pick_view_reads_a_slanted_wall_where_the_axis_meets_it(slant):
    """c't-Sim's Java3D pick (view 'pick', measured against the real c't-Sim): the wall of
    `test_a_slanted_wall_reads_at_the_cone_edge` reads 0.6 m, where the axis meets it, at every
    slant; its corners lie 2 m off, outside the cone, and so does its face's diagonal."""
    sx, sy = CTBOT.ir[0].position
    phi = math.radians(slant)
    normal, along = np.array((math.cos(phi), math.sin(phi))), np.array((-math.sin(phi), math.cos(phi)))
    hit = np.array((sx + 0.6, sy))
    face = [hit - 2 * along, hit + 2 * along, hit + 2 * along + 0.05 * normal, hit - 2 * along + 0.05 * normal]
    world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(Wall(tuple(map(tuple, face))),)))
    me = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    assert abs(world.ray_distance(me, (sx, sy), 0.0, cone=CTBOT.ir[0].cone, pick=True) - 0.6) < 1e-9


PICK_BOT = CTBOT.with_changes(ir=tuple(replace(sensor, view="pick") for sensor in CTBOT.ir))


def test_the_pick_view_sees_a_corner_in_the_whole_cone_and_reads_as_the_kernel():
    """A box whose nearest corner lies 0.4 m ahead, 2.9 degrees off the axis, the box reaching away
    from the axis (up and back): the pick reads that corner (c't-Sim sees a corner up to the cone's
    3 degrees: measured), the cone view the box's near face where the cone's edge meets it, 0.4 sin
    2.9 / sin 3; 4 degrees off, neither sees the box. The compiled reading of a pick-view robot
    reads the curve at the same distance."""
    sx, sy = CTBOT.ir[0].position
    for off, expected, in_cone in ((2.9, 0.4, 0.4 * math.sin(math.radians(2.9)) / math.sin(math.radians(3))), (4.0, math.inf, math.inf)):
        a = math.radians(off)
        x, y = sx + 0.4 * math.cos(a), sy + 0.4 * math.sin(a)
        wall = Wall(((x, y), (x, y + 0.3), (x - 0.3, y + 0.3), (x - 0.3, y)))
        world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(wall,)))
        me = world.add_robot(PICK_BOT, (0.0, 0.0, 0.0))
        seen = world.ray_distance(me, (sx, sy), 0.0, cone=CTBOT.ir[0].cone, pick=True)
        assert seen == pytest.approx(expected, abs=1e-12)  # exact geometry, rounding only
        assert world.ray_distance(me, (sx, sy), 0.0, cone=CTBOT.ir[0].cone) == pytest.approx(in_cone, abs=1e-12)
        assert world.read_all()[0].ir_raw[0] == me.ir_curves[0].lookup(seen)  # the kernel's reading of the left sensor


def pick_of(box_corners, origin, direction):
    world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(Wall(box(*box_corners)),)))
    me = world.add_robot(PICK_BOT, (-2.5, -2.5, 0.0))
    return world.ray_distance(me, origin, direction, cone=math.radians(3.0), pick=True)


def test_the_pick_view_reads_a_face_near_its_diagonal_at_the_diagonal():
    """c't-Sim's wall faces are two triangles split by a diagonal from the floor to the 0.4 m top,
    which crosses the sensors' 75 mm at 3/16 of the face from where it starts low; an axis that
    meets the face 5 mm beside that crossing reads the diagonal's nearest point, sqrt(0.48² +
    (0.005 sin(atan(0.4 / 0.24)))²) = 0.480019 m (the real c't-Sim, to its 6 printed decimals),
    and 30 mm beside it the face itself."""
    crossing = 0.24 * 3 / 16  # from the face's low end (its start, counter-clockwise)
    beside = 0.005 * math.sin(math.atan2(0.4, 0.24))
    assert pick_of((0.0, 0.48, 0.24, 0.72), (crossing + 0.005, 0.0), math.pi / 2) == pytest.approx(math.hypot(0.48, beside), abs=1e-12)
    assert pick_of((0.0, 0.48, 0.24, 0.72), (crossing + 0.03, 0.0), math.pi / 2) == pytest.approx(0.48, abs=1e-12)
    assert round(math.hypot(0.48, beside), 6) == 0.480019


def test_the_pick_view_from_inside_a_wall_reads_the_face_it_looks_out_through():
    """c't-Sim's sensor inside a wall box picks the face its axis leaves the box by (measured: the
    cone view reads 0 there)."""
    assert pick_of((0.0, 0.0, 0.2, 0.2), (0.05, 0.1), 0.0) == pytest.approx(0.15, abs=1e-12)


def test_ir_views_are_checked():
    with pytest.raises(ValueError, match="view"):
        IRSensorSpec("x", (0.0, 0.0), view="ray")


def test_the_pick_view_sees_a_lamp_pillar_as_java3d_s_triangle_strip():
    """c't-Sim's lamp pillar is a Java3D cylinder, its side one triangle strip round the corners
    from due north: a sensor 0.9046 m south of the pillar's centre and 36 mm west of it, looking
    north, reads 0.879630 m, and its mirror image 36 mm east 0.856784 m (the real c't-Sim at
    poses of a solve_maze run in testparcours2.xml, 6 decimals): the pillar lies beyond the
    segment's 0.85 m, the edges within the cone at its end key alike, and the strip's first of
    them wins. The same 15 corners as a polygon of the box rule read 0.856076 and 0.856744."""
    pillar = build_grid(["*"], pillars="cylinder", origin=(0.84 - 0.12, 1.32 - 0.12)).walls
    world = World(WorldSpec("w", (0.0, 0.0, 2.0, 2.0), walls=pillar))
    me = world.add_robot(PICK_BOT, (1.8, 0.2, 0.0))
    for x, read in ((0.804, 0.879630), (0.876, 0.856784)):
        assert round(world.ray_distance(me, (x, 0.4154), math.pi / 2, cone=math.radians(3.0), pick=True), 6) == read


def test_the_pick_view_skips_a_face_whose_bounds_the_cone_misses():
    """Java3D's pick tests a shape's bounding box before its triangles (`PickConeSegment`'s bounds
    test: the box's centre near the axis, the unbounded axis ray through the box, or an edge of the
    box within the cone), and each face of a wall box is a shape of its own. A sensor 37 mm west
    of a wall's south-west corner and 0.78 m south of it, looking north: the face's diagonal lies
    within the cone's rim, but neither its corners nor the axis ray meet the face's bounds, so the
    real c't-Sim (testparcours2.xml, a solve_maze run at 6.71 s and 6.81 s) reads the lamp pillar
    behind it, 0.878647 and 0.872709 m, where the triangles alone read the face at 0.828 and 0.823 m.
    Agreement within 0.1 µm: c't-Sim's geometry is single precision."""
    pillar = build_grid(["*"], pillars="cylinder", origin=(0.84 - 0.12, 1.32 - 0.12)).walls
    world = World(WorldSpec("w", (0.0, 0.0, 2.4, 2.4), walls=(*pillar, Wall(box(0.96, 1.2, 2.16, 1.44)))))
    me = world.add_robot(PICK_BOT, (2.2, 0.2, 0.0))
    for sensor, end, read in (((0.9230483718, 0.4172520984), (0.9172063218, 1.2672316984), 0.8786473099),
                              ((0.9231129864, 0.4231995838), (0.9188085864, 1.2731885338), 0.8727088997)):  # fmt: skip
        look = math.atan2(end[1] - sensor[1], end[0] - sensor[0])
        assert world.ray_distance(me, sensor, look, cone=math.radians(3.0), pick=True) == pytest.approx(read, abs=1e-7)
