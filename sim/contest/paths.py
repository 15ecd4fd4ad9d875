"""How far a robot still has to go: the shortest path (m) from a point to a robot's goal areas
through the world's free floor, as c't-Sim's judge measures the way left (`getShortestDistanceToFinish`).

The floor is a grid of `CELL` m. Walls, holes and (in c't-Sim worlds) everything beyond the map
are blocked, grown by a clearance; the distance from the goal cells spreads through the free
cells by Dijkstra's algorithm over 16 directions (the 8 neighbours and the 8 knight's moves, each
only where the cells it passes are free). A path along the grid is at most 2.7 % longer than the
straight line in its direction (the knight's moves bound the detour), and the grid adds up to a
cell at either end: good to a few centimetres over a contest's metres, which is what deciding the
nearer of two robots needs.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import replace

import numba
import numpy as np

from sim.errors import UserError
from sim.world.floor import rasterize
from sim.world.spec import Goal, Hole, WorldSpec

CELL = 0.02
"""Grid cell (m): a c't-Bot is 6 cells wide, a c't-Sim corridor 12."""
MOVES = np.array([(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1),
                  (2, 1), (1, 2), (-1, 2), (-2, 1), (-2, -1), (-1, -2), (1, -2), (2, -1)], dtype=np.int64)  # fmt: skip
"""(column, row) steps of the 16 directions."""


def _passes(move: np.ndarray) -> list[tuple[int, int]]:
    """The cells a move brushes on its way (besides its ends): both cells beside a diagonal,
    the straight and the diagonal cell of a knight's move."""
    dx, dy = int(move[0]), int(move[1])
    if abs(dx) + abs(dy) == 1:
        return [(0, 0), (0, 0)]
    if abs(dx) == abs(dy):
        return [(dx, 0), (0, dy)]
    sx, sy = int(math.copysign(1, dx)), int(math.copysign(1, dy))
    return [(sx, 0), (sx, sy)] if abs(dx) == 2 else [(0, sy), (sx, sy)]


PASSES = np.array([_passes(m) for m in MOVES], dtype=np.int64)
LENGTHS = np.hypot(MOVES[:, 0], MOVES[:, 1])


@numba.njit(cache=True)
def _spread(distance: np.ndarray, blocked: np.ndarray, moves: np.ndarray, passes: np.ndarray, lengths: np.ndarray) -> None:
    """Dijkstra from every cell whose `distance` is finite (the sources, in cells) through the
    cells not `blocked`; `distance` is updated in place."""
    rows, cols = distance.shape
    heap = [(0.0, 0)]
    heap.pop()
    for r in range(rows):
        for c in range(cols):
            if np.isfinite(distance[r, c]):
                heap.append((distance[r, c], r * cols + c))
    heapq.heapify(heap)
    while heap:
        d, index = heapq.heappop(heap)
        r, c = index // cols, index % cols
        if d > distance[r, c]:
            continue
        for k in range(moves.shape[0]):
            cc, rr = c + moves[k, 0], r + moves[k, 1]
            if rr < 0 or rr >= rows or cc < 0 or cc >= cols or blocked[rr, cc]:
                continue
            free = True
            for j in range(2):
                pc, pr = c + passes[k, j, 0], r + passes[k, j, 1]
                if 0 <= pr < rows and 0 <= pc < cols and blocked[pr, pc]:
                    free = False
            if not free:
                continue
            nd = d + lengths[k]
            if nd < distance[rr, cc]:
                distance[rr, cc] = nd
                heapq.heappush(heap, (nd, rr * cols + cc))


def _mask(world: WorldSpec, areas: tuple, cell: float) -> tuple[np.ndarray, float]:
    """Which cells of `world`'s grid have their centre inside one of `areas` (convex polygons),
    drawn by the floor's rasteriser as the holes of an otherwise bare world, and the cell size (m)
    it drew with (it coarsens the grid of a very large world)."""
    bare = replace(world, floor=(), lines=(), holes=tuple(Hole(a) for a in areas), outside_is_hole=False)
    drawn = rasterize(bare, cell)
    return drawn.hole, drawn.cell


class PathField:
    """The path distance (m) to the goal areas `goals` of `world` from any point, for a robot that
    keeps `clearance` m (its centre's distance) from walls and holes. Built once per world, goal
    and robot (a fraction of a second), then `distance(x, y)` is a lookup."""

    def __init__(self, world: WorldSpec, goals: tuple[Goal, ...], clearance: float, cell: float = CELL):
        if not goals:
            raise UserError(f"{world.source or world.name}: the world has no goal to measure the way to")
        self.origin = (world.bounds[0], world.bounds[1])
        solid, self.cell = _mask(world, tuple(w.vertices for w in world.walls) + tuple(h.vertices for h in world.holes), cell)
        if world.outside_is_hole:  # the map's edge is an abyss's edge
            solid[[0, -1], :] = solid[:, [0, -1]] = True
        # blocked: within the clearance of something solid (the free distance from it, by the same spread)
        near = np.where(solid, 0.0, np.inf)
        _spread(near, np.zeros_like(solid), MOVES, PASSES, LENGTHS)
        self.blocked = near * self.cell < clearance
        goal, _ = _mask(world, tuple(g.vertices for g in goals), cell)
        self.cells = np.where(goal, 0.0, np.inf)  # in cells
        _spread(self.cells, self.blocked, MOVES, PASSES, LENGTHS)

    def distance(self, x: float, y: float) -> float:
        """Metres from (x, y) to the nearest goal along the free floor; inf where no way leads there.
        The way from a point is the best of the free cells around it (within one cell, or three for
        a robot pressed against a wall), plus the straight line to that cell's centre: the same
        for a point and its mirror image where a point lies on a cell's edge."""
        if self.cells.size == 0:
            return math.inf
        u, v = (x - self.origin[0]) / self.cell - 0.5, (y - self.origin[1]) / self.cell - 0.5  # in cell centres
        for reach in (1, 3):
            best = math.inf
            for r in range(math.floor(v) - reach + 1, math.floor(v) + reach + 1):
                for c in range(math.floor(u) - reach + 1, math.floor(u) + reach + 1):
                    if 0 <= r < self.cells.shape[0] and 0 <= c < self.cells.shape[1] and not self.blocked[r, c]:
                        best = min(best, float(self.cells[r, c]) + math.hypot(c - u, r - v))
            if math.isfinite(best):
                return best * self.cell
        return math.inf
