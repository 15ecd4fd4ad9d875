"""Uniform grids that let a query meet only what is near, compiled: the static walls' (`walls_near`,
over the grid `build_wall_grid` makes in numpy), the circles' of a crowd (`circle_grid`) and the
pairs of robots that could touch in a step (`near_pairs`), with the sort and search they share."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.world.layout import GRID, Walls

_GRID = GRID.dtype  # (a dtype for the compiled code: it reads globals, not attributes of objects)


def build_wall_grid(boxes: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """A uniform grid of square `cell`s over the walls' BOXES, for `walls_near`: (frame: one GRID
    row; cells: one int64 array, the starts of each cell's list (rows x columns + 1, row-major;
    cell k lists members[starts[k]:starts[k + 1]]), then the members, then a buffer one wall long
    per wall). A wall is listed, in ascending order, in every cell its box overlaps. The grid
    spans the walls' boxes only (a query beyond it meets its edge cells, whose walls' boxes it
    misses). An infinite `cell` gives one cell of every wall: the plain loop. (numpy, once per
    world: compiled, it cost every first run seconds of compiling before anything else.)"""
    n = boxes.shape[0]
    x0 = float(boxes["xmin"].min()) if n else 0.0
    y0 = float(boxes["ymin"].min()) if n else 0.0
    cols = 1 + max(int(_cell_indices(boxes["xmax"].max(keepdims=True), x0, cell, 1 << 30)[0]), 0) if n else 1
    rows = 1 + max(int(_cell_indices(boxes["ymax"].max(keepdims=True), y0, cell, 1 << 30)[0]), 0) if n else 1
    # per wall: its first column and row, and how many columns and rows it spans
    col_lo, row_lo = _cell_indices(boxes["xmin"], x0, cell, cols - 1), _cell_indices(boxes["ymin"], y0, cell, rows - 1)
    width = np.maximum(_cell_indices(boxes["xmax"], x0, cell, cols - 1) - col_lo + 1, 0)
    height = np.maximum(_cell_indices(boxes["ymax"], y0, cell, rows - 1) - row_lo + 1, 0)
    spans = width * height
    wall = np.repeat(np.arange(n, dtype=np.int64), spans)  # each (wall, cell) entry's wall, walls ascending
    within = np.arange(len(wall)) - np.repeat(np.cumsum(spans) - spans, spans)  # its place in its wall's cells, row-major
    cell_of = (row_lo[wall] + within // width[wall]) * cols + col_lo[wall] + within % width[wall]
    starts = np.zeros(rows * cols + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell_of, minlength=rows * cols), out=starts[1:])
    cells = np.empty(len(starts) + len(wall) + max(n, 1), dtype=np.int64)
    cells[: len(starts)] = starts
    cells[len(starts) : len(starts) + len(wall)] = wall[np.argsort(cell_of, kind="stable")]  # (stable: each cell's walls stay ascending)
    frame = np.zeros(1, _GRID)
    frame["x"], frame["y"], frame["cell"], frame["columns"], frame["rows"] = x0, y0, cell, cols, rows
    return frame, cells


def _cell_indices(x: np.ndarray, origin: float, cell: float, last: int) -> np.ndarray:
    """`_cell_index` of every coordinate in `x`, in numpy."""
    v = (x - origin) / cell
    return np.where(v >= last, last, np.where((v >= 0.0) & (v < last), v, 0.0).astype(np.int64))


@numba.njit(cache=True, inline="always")
def _cell_index(x: float, origin: float, cell: float, last: int) -> int:
    """The grid column (or row) of coordinate `x`, clamped to 0..last; clamped as a float, since
    numba's floor and int of a float far beyond the grid (or nan) overflow: 0 for nan."""
    v = (x - origin) / cell
    return int(v) if 0.0 <= v < last else (last if v >= last else 0)


@numba.njit(cache=True, inline="always")
def walls_near(lo_x: float, lo_y: float, hi_x: float, hi_y: float, frame: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The walls listed in the grid cells (`build_wall_grid`) that the query box (lo_x, lo_y, hi_x,
    hi_y) overlaps, each once and in ascending order: the order of a loop over every wall, so that
    ties and early exits fall on the same wall. The caller still tests each one's box. One cell's
    list is returned as it is; the lists of several are merged into the buffer (insertion into a
    sorted run: a query meets a handful of walls)."""
    grid = frame[0]
    cols, rows = grid.columns, grid.rows
    first = rows * cols + 1
    c0, c1 = _cell_index(lo_x, grid.x, grid.cell, cols - 1), _cell_index(hi_x, grid.x, grid.cell, cols - 1)
    r0, r1 = _cell_index(lo_y, grid.y, grid.cell, rows - 1), _cell_index(hi_y, grid.y, grid.cell, rows - 1)
    if r0 == r1 and c0 == c1:
        return cells[first + cells[r0 * cols + c0] : first + cells[r0 * cols + c0 + 1]]
    buffer = cells[first + cells[first - 1] :]
    count = 0
    for r in range(r0, r1 + 1):
        for p in range(first + cells[r * cols + c0], first + cells[r * cols + c1 + 1]):
            w, q = cells[p], count
            while q > 0 and buffer[q - 1] > w:
                q -= 1
            if q > 0 and buffer[q - 1] == w:
                continue  # listed in an earlier cell
            for m in range(count, q, -1):
                buffer[m] = buffer[m - 1]
            buffer[q] = w
            count += 1
    return buffer[:count]


@numba.njit(cache=True)
def circle_grid(circles: np.ndarray, length: float):
    """A uniform grid over the CIRCLES' centres: (cell size, origin x, y, columns, rows, circle
    order by cell, sorted cell keys, largest radius); key = row * columns + column, so a row's run
    of cells is one run of keys. Cells are a quarter of the ray length (at least two diameters), so
    a cone's bounding box spans a handful of cells."""
    n = circles.shape[0]
    widest = circles.radius.max()
    cell = max(0.25 * length, 4.0 * widest)
    x0, y0 = circles.x.min(), circles.y.min()
    cx = np.empty(n, dtype=np.int64)
    cy = np.empty(n, dtype=np.int64)
    for j in range(n):
        cx[j] = int(math.floor((circles[j].x - x0) / cell))
        cy[j] = int(math.floor((circles[j].y - y0) / cell))
    cols, rows = cx.max() + 1, cy.max() + 1
    order, sorted_key = stable_order(cy * cols + cx)
    return cell, x0, y0, cols, rows, order, sorted_key, widest


@numba.njit(cache=True)
def stable_order(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(order, key[order]): the stable ascending order of the int64 `key`s, as
    `np.argsort(key, kind="stable")`. A bottom-up merge sort written out: numba compiles its own
    argsort in seconds, this in a fraction of one."""
    n = key.shape[0]
    order, spare = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    for k in range(n):
        order[k] = k
    width = 1
    while width < n:
        for low in range(0, n, 2 * width):
            middle, high = min(low + width, n), min(low + 2 * width, n)
            i, j = low, middle
            for k in range(low, high):  # ties from the left run first: stable
                if i < middle and (j >= high or key[order[i]] <= key[order[j]]):
                    spare[k] = order[i]
                    i += 1
                else:
                    spare[k] = order[j]
                    j += 1
        order, spare = spare, order
        width *= 2
    for k in range(n):
        spare[k] = key[order[k]]
    return order, spare


@numba.njit(cache=True)
def first_at_least(values: np.ndarray, key: int) -> int:
    """Index of the first of the ascending `values` that is >= key (len(values) if none): a
    binary search without numpy's per-call setup (a crowd asks nine times per robot)."""
    lo, hi = 0, values.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if values[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def near_pairs(pose: np.ndarray, move: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """(m, 2) pairs i < j, in the order of a double loop over i then j, of robots that could touch
    this step: a uniform grid with cells wider than any pair's reach plus both moves, so robots
    in cells that are not neighbours can never meet. Cells are found by sorting their keys, which
    costs n log n whatever the spread of the robots (a dense array of cells could not hold a
    kilometre of sparse robots)."""
    n = pose.shape[0]
    longest = 0.0
    for i in range(n):
        longest = max(longest, math.hypot(move[i, 0], move[i, 1]))
    # the widest conflict distance, with a margin so that a pair at exactly this distance (whose
    # contact time rounds to just below 1) still falls in neighbouring cells
    cell = (2.0 * (reach.max() + longest)) * (1.0 + 1e-9) + 1e-9
    x0, y0 = pose[:, 0].min(), pose[:, 1].min()
    cx = np.empty(n, dtype=np.int64)
    cy = np.empty(n, dtype=np.int64)
    for i in range(n):
        cx[i] = int((pose[i, 0] - x0) / cell)
        cy[i] = int((pose[i, 1] - y0) / cell)
    rows = cy.max() + 3  # keys of the cells one beyond either side stay distinct
    key = (cx + 1) * rows + (cy + 1)
    order, sorted_key = stable_order(key)
    pairs = np.empty((4 * n + 16, 2), dtype=np.int64)
    count = 0
    found = np.empty(n, dtype=np.int64)
    for i in range(n):
        m = 0
        for dx in range(-1, 2):
            low = key[i] + dx * rows - 1  # the column's three cells dy = -1, 0, 1 are consecutive keys
            for p in range(first_at_least(sorted_key, low), n):
                if sorted_key[p] > low + 2:
                    break
                if order[p] > i:
                    found[m] = order[p]
                    m += 1
        for q in range(1, m):  # ascending, in place (few neighbours: no allocation per robot)
            j, p = found[q], q
            while p > 0 and found[p - 1] > j:
                found[p] = found[p - 1]
                p -= 1
            found[p] = j
        if count + m > pairs.shape[0]:
            grown = np.empty((2 * (count + m), 2), dtype=np.int64)
            for q in range(count):  # (a loop: numba's slice assignment compiles the formatting of its error message, seconds)
                grown[q, 0], grown[q, 1] = pairs[q, 0], pairs[q, 1]
            pairs = grown
        for q in range(m):
            pairs[count, 0], pairs[count, 1] = i, found[q]
            count += 1
    return pairs[:count]


def gridded(vertices: np.ndarray, spans: np.ndarray, boxes: np.ndarray, cell: float) -> Walls:
    """Walls (convex polygons vertices[spans[w].start:spans[w].end] with their BOXES) and the grid
    of `cell`s over them (`build_wall_grid`; an infinite cell: one cell of every wall) as the
    kernels take them."""
    frame, cells = build_wall_grid(boxes, cell)
    return Walls(vertices, spans, boxes, frame, cells)
