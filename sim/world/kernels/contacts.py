"""Compiled kernels that cut the planned moves where something stops them: c't-Sim's contact rule
(`stop_at_contact`), the sweep against walls with sliding (`sweep_walls`), robots running into
each other (`keep_apart`), and the step's arithmetic between the drive and pymunk (`settle`)."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.world.kernels.floor import hold_at_holes
from sim.world.kernels.geometry import polygon_distance
from sim.world.kernels.grids import near_pairs, walls_near
from sim.world.layout import (
    ALPHA,
    APART_RADIUS,
    BLOCKED,
    CELL,
    DT,
    MASS,
    MOMENT,
    MOVE,
    ORIGIN,
    OUTSIDE_IS_HOLE,
    QUIET_AFTER,
    RADIUS,
    ROBOTS_MEET,
    SLIDE_MARGIN,
    STOPS,
    STREAK,
    SWEEP_RADIUS,
    WALL_FRAME,
)

CLEAR = 1e-3
"""A robot nearer than this (m) to a wall counts as touching it (`settle`): far beyond rounding, so
that pymunk, which finds a contact at distance <= 0, finds none where this finds none."""


@numba.njit(cache=True)
def settle(
    pose: np.ndarray,
    params: np.ndarray,
    state: np.ndarray,
    scalars: np.ndarray,
    vertices: np.ndarray,
    ranges: np.ndarray,
    boxes: np.ndarray,
    wall_cells: np.ndarray,
    contacts: np.ndarray,
    anchored: np.ndarray,
    hole: np.ndarray,
    in_hole: np.ndarray,
    rows: np.ndarray,
    motion: np.ndarray,
    quiet: np.ndarray,
    circles: np.ndarray,
) -> tuple[bool, bool]:
    """The planned moves and turns (state's MOVE, ALPHA) refused by c't-Sim's contact rule
    (`stop_at_contact`) or cut where walls (`sweep_walls`), other robots (`keep_apart`) or holes
    (`hold_at_holes`) stop them, and the force and torque that give
    each robot that motion in pymunk's velocity phase (m move / dt^2, I alpha / dt^2) written into
    its row of pymunk's body data (motion[rows[i], 3:6]): the world step's arithmetic between the
    drive and pymunk in one call.

    Returns whether any robot's `in_hole` changed, and whether the step is quiet: it began with no
    robot touching a wall (`CLEAR`), as did the quiet[QUIET_AFTER] steps before it (`quiet` counts
    them; a negative QUIET_AFTER: never quiet). Then pymunk has no contact to solve and none in its
    memory, so that `glide` moves the robots as pymunk's step would."""
    move, alpha = state[:, MOVE : MOVE + 2], state[:, ALPHA]
    wall_grid = (scalars[WALL_FRAME : WALL_FRAME + 3], wall_cells)
    stop_at_contact(pose, move, params, state, vertices, ranges, boxes, wall_grid, circles)
    sweep_walls(pose, move, params[:, SWEEP_RADIUS], scalars[SLIDE_MARGIN], vertices, ranges, boxes, wall_grid)
    if pose.shape[0] > 1 and scalars[ROBOTS_MEET] != 0.0:
        keep_apart(pose, move, params[:, APART_RADIUS])
    changed = hold_at_holes(
        pose, move, alpha, contacts, anchored, hole, scalars[ORIGIN : ORIGIN + 2], scalars[CELL], scalars[OUTSIDE_IS_HOLE] != 0.0,
        in_hole,
    )  # fmt: skip
    dt = scalars[DT]
    dt2 = dt * dt
    for i in range(pose.shape[0]):
        scale = params[i, MASS] / dt2
        motion[rows[i], 3] = move[i, 0] * scale
        motion[rows[i], 4] = move[i, 1] * scale
        motion[rows[i], 5] = alpha[i] * params[i, MOMENT] / dt2
    if quiet[QUIET_AFTER] < 0:
        return changed, False
    clear = True
    for i in range(pose.shape[0]):
        clear = clear and clear_of_walls(pose[i, 0], pose[i, 1], params[i, RADIUS] + CLEAR, vertices, ranges, boxes, wall_grid)
    quiet[STREAK] = quiet[STREAK] + 1 if clear else 0
    return changed, quiet[STREAK] > quiet[QUIET_AFTER]


CAN_ACROSS, CAN_SOUTH = math.cos(math.pi / 30), math.cos(math.pi / 15)
"""c't-Sim's can (Java3D's cylinder of 15 sides, a corner due north) as its contact test sees it,
in radii: the box round its corners, cos 6° either side across and from cos 12° south to 1 north."""
@numba.njit(cache=True)
def _box_gap2(x: float, y: float, xmin: float, ymin: float, xmax: float, ymax: float) -> float:
    """Squared distance from (x, y) to the box (0 inside)."""
    dx = max(xmin - x, 0.0, x - xmax)
    dy = max(ymin - y, 0.0, y - ymax)
    return dx * dx + dy * dy


@numba.njit(cache=True)
def stop_at_contact(pose: np.ndarray, move: np.ndarray, params: np.ndarray, state: np.ndarray, vertices: np.ndarray, ranges: np.ndarray,
                    boxes: np.ndarray, wall_grid: tuple, circles: np.ndarray) -> None:  # fmt: skip
    """c't-Sim's contact rule for the robots that have it (params' STOPS): a move that would put
    the body within its radius of a wall, of a can (`circles`' rows owned by -1, as c't-Sim's
    contact test sees them: boxes, `CAN_ACROSS`) or of another robot's body where that stands at
    the start of the step is not made at all (MOVE set to 0, BLOCKED 1); the turn still is. So the
    robot stays at its last position clear of everything and can turn away, as c't-Sim commits the
    position only when its bounding sphere at the new one meets nothing (MasterSimulator)."""
    n = pose.shape[0]
    for i in range(n):
        if params[i, STOPS] == 0.0:
            continue
        state[i, BLOCKED] = 0.0
        if move[i, 0] == 0.0 and move[i, 1] == 0.0:
            continue
        x, y, radius = pose[i, 0] + move[i, 0], pose[i, 1] + move[i, 1], params[i, RADIUS]
        blocked = not clear_of_walls(x, y, radius, vertices, ranges, boxes, wall_grid)
        for j in range(n):
            if not blocked and j != i:
                blocked = math.hypot(pose[j, 0] - x, pose[j, 1] - y) <= radius + params[j, RADIUS]
        for j in range(circles.shape[0]):
            if not blocked and circles[j, 3] == -1.0:
                cx, cy, r = circles[j, 0], circles[j, 1], circles[j, 2]
                blocked = _box_gap2(x, y, cx - r * CAN_ACROSS, cy - r * CAN_SOUTH, cx + r * CAN_ACROSS, cy + r) <= radius * radius
        if blocked:
            move[i, 0], move[i, 1], state[i, BLOCKED] = 0.0, 0.0, 1.0


@numba.njit(cache=True)
def clear_of_walls(x: float, y: float, radius: float, vertices: np.ndarray, ranges: np.ndarray, boxes: np.ndarray, wall_grid: tuple) -> bool:
    """Whether a circle of `radius` at (x, y) is clear of every wall (farther than `radius`)."""
    lo_x, lo_y, hi_x, hi_y = x - radius, y - radius, x + radius, y + radius
    for w in walls_near(lo_x, lo_y, hi_x, hi_y, wall_grid[0], wall_grid[1]):
        if boxes[w, 0] > hi_x or boxes[w, 2] < lo_x or boxes[w, 1] > hi_y or boxes[w, 3] < lo_y:
            continue
        if polygon_distance(x, y, vertices, ranges[w, 0], ranges[w, 1])[0] <= radius:
            return False
    return True


@numba.njit(cache=True)
def _sweep(
    px: float, py: float, mx: float, my: float, radius: float, vertices: np.ndarray, ranges: np.ndarray, boxes: np.ndarray,
    wall_grid: tuple,
) -> tuple[float, float, float]:
    """First contact of a circle of `radius` moved from (px, py) by (mx, my) with any wall:
    (fraction of the move, contact normal x, y); fraction 1 when free. Conservative advancement
    (advance by the distance to the wall, which can never overshoot a convex shape). A wall the
    circle already touches only stops motion into it. Walls come from `walls_near` for the box of
    the swept circle, in ascending order: of walls met at the same fraction, the first one's normal
    is taken, as a loop over every wall takes it."""
    length = math.hypot(mx, my)
    first, nx, ny = 1.0, 0.0, 0.0
    if length == 0.0:
        return first, nx, ny
    lo_x, hi_x = min(px, px + mx) - radius, max(px, px + mx) + radius
    lo_y, hi_y = min(py, py + my) - radius, max(py, py + my) + radius
    for w in walls_near(lo_x, lo_y, hi_x, hi_y, wall_grid[0], wall_grid[1]):
        if boxes[w, 0] > hi_x or boxes[w, 2] < lo_x or boxes[w, 1] > hi_y or boxes[w, 3] < lo_y:
            continue
        t = 0.0
        for _ in range(64):
            x, y = px + t * mx, py + t * my
            distance, cx, cy = polygon_distance(x, y, vertices, ranges[w, 0], ranges[w, 1])
            gap = distance - radius
            if gap <= 1e-9:
                ox, oy = x - cx, y - cy
                norm = math.hypot(ox, oy)
                if norm > 0.0:
                    ox, oy = ox / norm, oy / norm
                if distance < 0.0:
                    ox, oy = -ox, -oy
                if t == 0.0 and mx * ox + my * oy >= 0.0:
                    break  # touching already and moving away or along: free
                if t < first:
                    first, nx, ny = t, ox, oy
                break
            t += gap / length
            if t >= first:
                break
    return first, nx, ny


@numba.njit(cache=True)
def sweep_walls(
    pose: np.ndarray,
    move: np.ndarray,
    radius: np.ndarray,
    slide_margin: float,
    vertices: np.ndarray,
    ranges: np.ndarray,
    boxes: np.ndarray,
    wall_grid: tuple,
) -> None:
    """Cut every robot's planned move (n, 2), in place, where its body would first sink deeper
    than allowed into a wall, and let the rest slide: the remainder without its part into the
    surface is swept again with a slightly thinner circle (so the surface just touched does not
    stop it, another one does). `radius` is each robot's sweep radius (body radius minus the
    allowed depth); walls are convex polygons vertices[ranges[w, 0]:ranges[w, 1]] with boxes, found
    through `wall_grid` (`build_wall_grid`)."""
    for i in range(pose.shape[0]):
        px, py, mx, my = pose[i, 0], pose[i, 1], move[i, 0], move[i, 1]
        t, nx, ny = _sweep(px, py, mx, my, radius[i], vertices, ranges, boxes, wall_grid)
        if t >= 1.0:
            continue
        ax, ay = mx * t, my * t
        rx, ry = mx - ax, my - ay
        into = rx * nx + ry * ny
        if into < 0.0:
            rx, ry = rx - into * nx, ry - into * ny
        t2, _, _ = _sweep(px + ax, py + ay, rx, ry, radius[i] - slide_margin, vertices, ranges, boxes, wall_grid)
        move[i, 0], move[i, 1] = ax + rx * t2, ay + ry * t2


@numba.njit(cache=True)
def _contact_time(pose: np.ndarray, move: np.ndarray, reach: np.ndarray, i: int, j: int) -> float:
    """Fraction of the step at which robots i and j, moving along their moves, would come closer
    than reach[i] + reach[j]; 1 if they do not (or separate)."""
    rpx, rpy = pose[i, 0] - pose[j, 0], pose[i, 1] - pose[j, 1]
    rdx, rdy = move[i, 0] - move[j, 0], move[i, 1] - move[j, 1]
    limit = reach[i] + reach[j]
    b = rpx * rdx + rpy * rdy
    a = rdx * rdx + rdy * rdy
    if b >= 0.0 or a == 0.0:
        return 1.0  # apart or separating
    c = rpx * rpx + rpy * rpy - limit * limit
    if c <= 0.0:
        return 0.0  # touching and closing in
    disc = b * b - a * c
    if disc < 0.0:
        return 1.0  # they pass each other
    return min(max((-b - math.sqrt(disc)) / a, 0.0), 1.0)


@numba.njit(cache=True)
def keep_apart(pose: np.ndarray, move: np.ndarray, reach: np.ndarray) -> None:
    """Shorten the moves (n, 2), in place, of robots that would run into each other: both moves
    of a pair are cut at the moment the pair would touch (closer than reach[i] + reach[j]).
    Cuts only shorten moves, but a shorter move can let a follower catch up, so the pairs are
    checked again until none closes in; robots still in conflict after that stand still.

    Only pairs near enough to meet are checked (`near_pairs`, found once: cuts never lengthen
    a move), in the order of checking all pairs, so the cuts are those of all pairs."""
    if pose.shape[0] < 2:
        return
    pairs = near_pairs(pose, move, reach)
    for _ in range(100):
        changed = False
        for p in range(pairs.shape[0]):
            i, j = pairs[p, 0], pairs[p, 1]
            t = _contact_time(pose, move, reach, i, j)
            if t < 1.0 - 1e-12:
                move[i, 0] *= t
                move[i, 1] *= t
                move[j, 0] *= t
                move[j, 1] *= t
                changed = True
        if not changed:
            return
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        if _contact_time(pose, move, reach, i, j) < 1.0:
            move[i, 0] = move[i, 1] = move[j, 0] = move[j, 1] = 0.0
