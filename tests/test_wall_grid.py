"""The uniform grid over the static walls (`kernels.grids.build_wall_grid`): each cell lists the walls
whose boxes overlap it, and IR readings and swept moves through the grid are those of checking
every wall, bit for bit (the grid with one infinite cell is that plain loop over every wall)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.world import layout
from sim.world.kernels.contacts import sweep_walls
from sim.world.kernels.grids import build_wall_grid, gridded, walls_near
from sim.world.kernels.sensing import sense_ir
from sim.world.tables import wall_cell


def random_walls(seed: int, count: int, spread: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`count` random convex walls (vertices, SPANS, BOXES) in a square of `spread` m: 3 to 8
    points on a circle, stretched and turned (an affine map keeps them convex); some long and
    thin, so that they span many cells."""
    rng = np.random.default_rng(seed)
    polygons = []
    for _ in range(count):
        k = int(rng.integers(3, 9))
        angles = np.sort(rng.uniform(0.0, 2 * math.pi, k))
        angles[1:] = np.maximum(angles[1:], angles[:-1] + 1e-3)  # distinct corners
        unit = np.column_stack((np.cos(angles), np.sin(angles)))
        long = spread * (0.5 if rng.random() < 0.15 else 0.03)
        stretch = np.diag((rng.uniform(0.005, long), rng.uniform(0.005, 0.03 * spread)))
        turn = rng.uniform(-math.pi, math.pi)
        rotate = np.array(((math.cos(turn), -math.sin(turn)), (math.sin(turn), math.cos(turn))))
        polygons.append(unit @ stretch @ rotate.T + rng.uniform(-spread, spread, 2))
    spans, boxes = layout.SPANS.new(count), layout.BOXES.new(count)
    spans["end"] = np.cumsum([len(p) for p in polygons])
    spans["start"] = spans["end"] - [len(p) for p in polygons]
    for name, values in zip(("xmin", "ymin", "xmax", "ymax"), np.array([(*p.min(axis=0), *p.max(axis=0)) for p in polygons]).T):
        boxes[name] = values
    return np.concatenate(polygons), spans, boxes


def rays(origins: np.ndarray, look: np.ndarray, cone: np.ndarray) -> layout.Rays:
    """IR rays of robot 0 that see walls in their whole cone."""
    return layout.Rays(origins, look, cone, np.zeros(len(look), dtype=np.int64), np.zeros(len(look), dtype=np.bool_))


def circles_at(centres: np.ndarray, radius: float) -> np.ndarray:
    """CIRCLES of `radius` at `centres`, no robot's."""
    circles = layout.CIRCLES.new(len(centres))
    circles["x"], circles["y"], circles["radius"], circles["owner"] = centres[:, 0], centres[:, 1], radius, -1
    return circles


def cell_sizes(boxes: np.ndarray, pick: int) -> float:
    """The world's own cell size, or much smaller cells (walls over many cells) or a few large ones."""
    return wall_cell(boxes) * (1.0, 0.05, 0.3, 4.0)[pick]


walls_and_cells = st.tuples(st.integers(0, 2**32 - 1), st.integers(1, 400), st.sampled_from([0.5, 3.0, 20.0]), st.integers(0, 3))


@given(walls_and_cells)
@settings(max_examples=60)
def test_each_cell_lists_the_walls_over_it_in_ascending_order(case):
    seed, count, spread, pick = case
    _, _, boxes = random_walls(seed, count, spread)
    frame, cells = build_wall_grid(boxes, cell_sizes(boxes, pick))
    x0, y0, size, cols, rows = frame[0]
    starts = cells[: rows * cols + 1]
    members = cells[len(starts) :][: starts[-1]]
    cell = np.repeat(np.arange(rows * cols), np.diff(starts))  # each entry's cell
    same = cell[1:] == cell[:-1]
    assert np.all(members[1:][same] > members[:-1][same])  # each cell's list ascends
    # each listed wall's box reaches into the cell (closed; a rounding's width at the edges)
    lo_x, lo_y, slack = x0 + (cell % cols) * size, y0 + (cell // cols) * size, 1e-9 * (1.0 + abs(x0) + abs(y0) + size * (cols + rows))
    box = boxes[members]
    assert np.all((box["xmin"] <= lo_x + size + slack) & (box["xmax"] >= lo_x - slack) & (box["ymin"] <= lo_y + size + slack) & (box["ymax"] >= lo_y - slack))
    every = set(members)
    assert every == set(range(count))
    one_frame, one = build_wall_grid(boxes, math.inf)
    assert one_frame[0]["columns"] == one_frame[0]["rows"] == 1
    assert np.array_equal(one[2:][:count], np.arange(count))  # the plain loop's order


@given(walls_and_cells, st.integers(0, 2**32 - 1))
@settings(max_examples=80)
def test_ir_through_the_grid_reads_what_every_wall_gives(case, query_seed):
    """Sensors anywhere (inside walls, far beyond the grid), cones from a ray (along the axes too)
    to wider than 45 degrees, with and without circles: the same bits as the plain loop."""
    seed, count, spread, pick = case
    vertices, spans, boxes = random_walls(seed, count, spread)
    grid, one = gridded(vertices, spans, boxes, cell_sizes(boxes, pick)), gridded(vertices, spans, boxes, math.inf)
    rng = np.random.default_rng(query_seed)
    m = 60
    origins = rng.uniform(-1.5 * spread, 1.5 * spread, (m, 2))
    origins[:5] = rng.uniform(-50.0, 50.0, (5, 2)) + 100.0 * spread  # far outside the grid
    look = np.where(rng.random(m) < 0.2, rng.integers(0, 4, m) * (math.pi / 2), rng.uniform(-math.pi, math.pi, m))
    cone = rng.choice([0.0, math.radians(3.0), 0.5, 1.2], m)
    circles = circles_at(rng.uniform(-spread, spread, (5, 2)), 0.05)
    for seen in (circles[:0], circles):
        every, through = np.empty(m), np.empty(m)
        sense_ir(rays(origins, look, cone), one, seen, 0.85, every)
        sense_ir(rays(origins, look, cone), grid, seen, 0.85, through)
        assert every.tobytes() == through.tobytes()


@given(walls_and_cells, st.integers(0, 2**32 - 1))
@settings(max_examples=80)
def test_moves_swept_through_the_grid_are_those_of_every_wall(case, query_seed):
    """Robots anywhere (touching or inside walls, beyond the grid), moves from none to long ones
    over several cells: the cut and slid moves of the plain loop, bit for bit."""
    seed, count, spread, pick = case
    vertices, spans, boxes = random_walls(seed, count, spread)
    grid, one = gridded(vertices, spans, boxes, cell_sizes(boxes, pick)), gridded(vertices, spans, boxes, math.inf)
    rng = np.random.default_rng(query_seed)
    pose, move, radius = robots(rng, spread)
    every, through = move.copy(), move.copy()
    sweep_walls(pose, every, radius, 1e-4, one)
    sweep_walls(pose, through, radius, 1e-4, grid)
    assert every.tobytes() == through.tobytes()


def robots(rng: np.random.Generator, spread: float, n: int = 60) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses, moves and sweep radii of `n` robots in the square of the walls and beyond it."""
    pose = np.column_stack((rng.uniform(-1.5 * spread, 1.5 * spread, (n, 2)), np.zeros(n)))
    pose[:3, :2] += 100.0 * spread  # far outside the grid
    reach = rng.choice([0.0, 0.005, 0.05, 0.3 * spread], n)
    return pose, rng.normal(0.0, 1.0, (n, 2)) * reach[:, None], rng.uniform(0.02, 0.1, n)


def test_the_random_worlds_stop_moves_and_meet_rays():
    """The comparisons above are not empty: in such a world many moves are cut or slid, sensors
    read walls, some from inside one, and the grid has many cells with walls over several."""
    vertices, spans, boxes = random_walls(7, 300, 3.0)
    walls = gridded(vertices, spans, boxes, wall_cell(boxes))
    assert walls.frame[0]["columns"] * walls.frame[0]["rows"] > 50 and len(walls.cells) > 2 * 300 + 50
    rng = np.random.default_rng(8)
    pose, move, radius = robots(rng, 3.0)
    swept = move.copy()
    sweep_walls(pose, swept, radius, 1e-4, walls)
    assert np.sum(np.any(swept != move, axis=1)) > 10
    origins = rng.uniform(-3.0, 3.0, (200, 2))
    out = np.empty(200)
    sense_ir(rays(origins, rng.uniform(-math.pi, math.pi, 200), np.full(200, 0.05)), walls, layout.CIRCLES.new(0), 0.85, out)
    assert np.isfinite(out).sum() > 100 and (out == 0.0).sum() > 5


@given(walls_and_cells, st.integers(0, 2**32 - 1))
@settings(max_examples=60)
def test_a_query_gets_every_wall_over_its_box_once_in_ascending_order(case, query_seed):
    """The order a loop over every wall meets them in, which decides ties and early exits."""
    seed, count, spread, pick = case
    _, _, boxes = random_walls(seed, count, spread)
    frame, cells = build_wall_grid(boxes, cell_sizes(boxes, pick))
    rng = np.random.default_rng(query_seed)
    for _ in range(40):
        lo = rng.uniform(-1.5 * spread, 1.5 * spread, 2)
        hi = lo + rng.choice([0.0, 0.05, 1.7, spread], 2)
        near = walls_near(lo[0], lo[1], hi[0], hi[1], frame, cells).copy()
        assert np.all(np.diff(near) > 0)
        over = (boxes["xmin"] <= hi[0]) & (boxes["xmax"] >= lo[0]) & (boxes["ymin"] <= hi[1]) & (boxes["ymax"] >= lo[1])
        assert set(np.nonzero(over)[0]) <= set(near)
