"""Compiled kernels that cut the planned moves where something stops them: c't-Sim's contact rule
(`stop_at_contact`), the sweep against walls with sliding (`sweep_walls`), robots running into
each other (`keep_apart`), and the step's arithmetic between the drive and pymunk (`settle`)."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import INNER
from sim.world.kernels.floor import hold_at_holes
from sim.world.kernels.geometry import polygon_distance
from sim.world.kernels.grids import near_pairs, walls_near
from sim.world.layout import Bodies, Floor, Ground, Walls

CLEAR = 1e-3
"""A robot nearer than this (m) to a wall counts as touching it (`settle`): far beyond rounding, so
that pymunk, which finds a contact at distance <= 0, finds none where this finds none."""


@numba.njit(cache=True)
def settle(pose: np.ndarray, robots: np.ndarray, state: np.ndarray, world: np.ndarray, walls: Walls, floor: Floor, ground: Ground,
           bodies: Bodies) -> tuple[bool, bool]:  # fmt: skip
    """The planned moves and turns (STATE's move, alpha) cut where walls (`sweep_walls`) or holes
    (`hold_at_holes`) stop them, and the force and torque that give each robot that motion in
    pymunk's velocity phase (`push`): the world step's arithmetic between the drive and pymunk in
    one call, for a world whose robots cannot meet and none of which has c't-Sim's contact rule
    (one c't-Bot in a maze: `settle_meeting` otherwise, whose code such a world need not compile,
    half of this kernel's on a first run). Returns `push`'s answer."""
    sweep_walls(pose, state.move, robots.sweep_radius, world[0].slide_margin, walls)
    return push(pose, robots, state, world, walls, floor, ground, bodies)


@numba.njit(cache=True)
def settle_meeting(pose: np.ndarray, robots: np.ndarray, state: np.ndarray, world: np.ndarray, walls: Walls, floor: Floor, ground: Ground,
                   bodies: Bodies) -> tuple[bool, bool]:  # fmt: skip
    """`settle` for any world: moves also refused by c't-Sim's contact rule (`stop_at_contact`)
    and cut where other robots stop them (`keep_apart`)."""
    here = world[0]
    stop_at_contact(pose, robots, state, walls, bodies.circles)
    sweep_walls(pose, state.move, robots.sweep_radius, here.slide_margin, walls)
    if pose.shape[0] > 1 and here.robots_meet:
        keep_apart(pose, state.move, robots.apart_radius, robots.stops)
    return push(pose, robots, state, world, walls, floor, ground, bodies)


@numba.njit(cache=True, inline="always")
def push(pose: np.ndarray, robots: np.ndarray, state: np.ndarray, world: np.ndarray, walls: Walls, floor: Floor, ground: Ground,
         bodies: Bodies) -> tuple[bool, bool]:  # fmt: skip
    """The planned moves held at holes (`hold_at_holes`), and the force and torque that give each
    robot its motion in pymunk's velocity phase (m move / dt^2, I alpha / dt^2) written into its
    MOTION row of pymunk's body data.

    Returns whether any robot's `fallen` changed, and whether the step is quiet: it began with no
    robot touching a wall (`CLEAR`), as did the WORLD's quiet_after steps before it (its streak
    counts them; a negative quiet_after: never quiet). Then pymunk has no contact to solve and
    none in its memory, so that `glide` moves the robots as pymunk's step would. (Inlined: a call
    handing on the world's tables cost `settle` 0.1 µs, a hundredth of a lone c't-Bot's step.)"""
    here = world[0]
    move, alpha = state.move, state.alpha
    changed = hold_at_holes(pose, state, ground, floor)
    dt = here.dt
    dt2 = dt * dt
    for i in range(pose.shape[0]):
        body = bodies.motion[bodies.rows[i]]
        scale = robots[i].mass / dt2
        body.force[0] = move[i, 0] * scale
        body.force[1] = move[i, 1] * scale
        body.torque = alpha[i] * robots[i].moment / dt2
    if here.quiet_after < 0:
        return changed, False
    clear = True
    for i in range(pose.shape[0]):
        clear = clear and clear_of_walls(pose[i, 0], pose[i, 1], robots[i].radius + CLEAR, walls)
    here.streak = here.streak + 1 if clear else 0
    return changed, here.streak > here.quiet_after


CAN_ACROSS, CAN_SOUTH = math.cos(math.pi / 30), math.cos(math.pi / 15)
"""c't-Sim's can (Java3D's cylinder of 15 sides, a corner due north) as its contact test sees it,
in radii: the box round its corners, cos 6° either side across and from cos 12° south to 1 north."""


def _ctbot_parts() -> np.ndarray:
    """c't-Sim's c't-Bot as its contact test sees another bot (`CtBotShape`): three Java3D shapes,
    each met at the box round its corners in the bot's frame (forward, left; m): the two cheeks
    beside the mouth and the middle behind it. Their outlines are the body's circle of 60 mm in
    corners every 10° from the mouth's edge (asin(25 / 54.55) either side of straight ahead) and
    the mouth's floor 39.55 mm behind that edge; the corner nearest the side and the one nearest
    the back lie 2.72° off, 59.93 mm out."""
    radius, mouth = 0.06, math.asin(25 / 54.55)
    corners = mouth + np.radians(np.arange(0.0, 180.0, 10.0))
    out = radius * np.abs(np.sin(corners[corners < math.pi - mouth])).max()
    edge_forward, edge_side = radius * math.cos(mouth), radius * math.sin(mouth)
    cheek = (-edge_forward, edge_side, edge_forward, out)
    return np.array((cheek, (cheek[0], -cheek[3], cheek[2], -cheek[1]), (-out, -edge_side, edge_forward - 0.05455 + 0.015, edge_side)))


CTBOT_PARTS = _ctbot_parts()
"""Rows (forward min, left min, forward max, left max), m: left cheek, right cheek, middle (`_ctbot_parts`)."""


@numba.njit(cache=True)
def _meets_ctbot(x: float, y: float, radius: float, other: np.ndarray) -> bool:
    """Whether a sphere of `radius` at (x, y) meets the c't-Bot at the pose OTHER (x, y, heading)
    as c't-Sim's contact test has it: the box round each of its parts (`CTBOT_PARTS`) turned with
    the bot, then the box round that in world axes (Java3D's bounds)."""
    c, s = math.cos(other[2]), math.sin(other[2])
    for part in CTBOT_PARTS:
        lo_x, lo_y, hi_x, hi_y = math.inf, math.inf, -math.inf, -math.inf
        for forward in (part[0], part[2]):
            for left in (part[1], part[3]):
                cx, cy = other[0] + forward * c - left * s, other[1] + forward * s + left * c
                lo_x, lo_y, hi_x, hi_y = min(lo_x, cx), min(lo_y, cy), max(hi_x, cx), max(hi_y, cy)
        if _box_gap2(x, y, lo_x, lo_y, hi_x, hi_y) <= radius * radius:
            return True
    return False


@numba.njit(cache=True, **INNER)
def _box_gap2(x: float, y: float, xmin: float, ymin: float, xmax: float, ymax: float) -> float:
    """Squared distance from (x, y) to the box (0 inside)."""
    dx = max(xmin - x, 0.0, x - xmax)
    dy = max(ymin - y, 0.0, y - ymax)
    return dx * dx + dy * dy


@numba.njit(cache=True)
def stop_at_contact(pose: np.ndarray, robots: np.ndarray, state: np.ndarray, walls: Walls, circles: np.ndarray) -> None:
    """c't-Sim's contact rule for the robots that have it (ROBOTS' stops): a move that would put
    the body within its radius of a wall (a lamp pillar's box: `clear_of_walls`), of a can (the
    CIRCLES owned by -1, as c't-Sim's contact test sees them: boxes, `CAN_ACROSS`) or of another
    robot's body where that stands at the start of the step (another robot with this rule is a
    c't-Bot of c't-Sim's and met at its parts' boxes, `_meets_ctbot`) is not made at all (move set
    to 0, blocked set); the turn still is. So the robot stays at its last position clear of
    everything and can turn away, as c't-Sim commits the position only when its bounding sphere at
    the new one meets nothing (MasterSimulator)."""
    n = pose.shape[0]
    for i in range(n):
        if not robots[i].stops:
            continue
        now = state[i]
        now.blocked = False
        move = now.move
        if move[0] == 0.0 and move[1] == 0.0:
            continue
        x, y, radius = pose[i, 0] + move[0], pose[i, 1] + move[1], robots[i].radius
        blocked = not clear_of_walls(x, y, radius, walls, True)
        for j in range(n):
            if not blocked and j != i:
                if robots[j].stops:
                    blocked = _meets_ctbot(x, y, radius, pose[j])
                else:
                    blocked = math.hypot(pose[j, 0] - x, pose[j, 1] - y) <= radius + robots[j].radius
        for j in range(circles.shape[0]):
            can = circles[j]
            if not blocked and can.owner == -1:
                r = can.radius
                blocked = _box_gap2(x, y, can.x - r * CAN_ACROSS, can.y - r * CAN_SOUTH, can.x + r * CAN_ACROSS, can.y + r) <= radius * radius
        if blocked:
            move[0], move[1], now.blocked = 0.0, 0.0, True


@numba.njit(cache=True, **INNER)
def clear_of_walls(x: float, y: float, radius: float, walls: Walls, as_ctsim: bool = False) -> bool:
    """Whether a circle of `radius` at (x, y) is clear of every wall (farther than `radius`);
    `as_ctsim`: a cylinder (c't-Sim's lamp pillar, `Wall.cylinder`) counts by its box, as c't-Sim's contact test
    meets it."""
    lo_x, lo_y, hi_x, hi_y = x - radius, y - radius, x + radius, y + radius
    boxes, spans = walls.boxes, walls.spans
    for w in walls_near(lo_x, lo_y, hi_x, hi_y, walls.frame, walls.cells):
        box = boxes[w]
        if box.xmin > hi_x or box.xmax < lo_x or box.ymin > hi_y or box.ymax < lo_y:
            continue
        if as_ctsim and box.cylinder:
            if _box_gap2(x, y, box.xmin, box.ymin, box.xmax, box.ymax) <= radius * radius:
                return False
        elif polygon_distance(x, y, walls.vertices, spans[w].start, spans[w].end)[0] <= radius:
            return False
    return True


@numba.njit(cache=True, **INNER)
def _sweep(px: float, py: float, mx: float, my: float, radius: float, walls: Walls) -> tuple[float, float, float]:
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
    boxes, spans = walls.boxes, walls.spans
    for w in walls_near(lo_x, lo_y, hi_x, hi_y, walls.frame, walls.cells):
        box = boxes[w]
        if box.xmin > hi_x or box.xmax < lo_x or box.ymin > hi_y or box.ymax < lo_y:
            continue
        t = 0.0
        for _ in range(64):
            x, y = px + t * mx, py + t * my
            distance, cx, cy = polygon_distance(x, y, walls.vertices, spans[w].start, spans[w].end)
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
def sweep_walls(pose: np.ndarray, move: np.ndarray, radius: np.ndarray, slide_margin: float, walls: Walls) -> None:
    """Cut every robot's planned move (n, 2), in place, where its body would first sink deeper
    than allowed into a wall, and let the rest slide: the remainder without its part into the
    surface is swept again with a slightly thinner circle (so the surface just touched does not
    stop it, another one does). `radius` is each robot's sweep radius (body radius minus the
    allowed depth); walls are convex polygons found through their grid (`build_wall_grid`)."""
    for i in range(pose.shape[0]):
        px, py, mx, my = pose[i, 0], pose[i, 1], move[i, 0], move[i, 1]
        t, nx, ny = _sweep(px, py, mx, my, radius[i], walls)
        if t >= 1.0:
            continue
        ax, ay = mx * t, my * t
        rx, ry = mx - ax, my - ay
        into = rx * nx + ry * ny
        if into < 0.0:
            rx, ry = rx - into * nx, ry - into * ny
        t2, _, _ = _sweep(px + ax, py + ay, rx, ry, radius[i] - slide_margin, walls)
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
def keep_apart(pose: np.ndarray, move: np.ndarray, reach: np.ndarray, ctsim: np.ndarray) -> None:
    """Shorten the moves (n, 2), in place, of robots that would run into each other: both moves
    of a pair are cut at the moment the pair would touch (closer than reach[i] + reach[j]). A pair
    of robots both under c't-Sim's contact rule (CTSIM, n) is left to it (`stop_at_contact`).
    Cuts only shorten moves, but a shorter move can let a follower catch up, so the pairs are
    checked again until none closes in; robots still in conflict after that stand still.

    Only pairs near enough to meet are checked (`near_pairs`, found once: cuts never lengthen
    a move), in the order of checking all pairs, so the cuts are those of all pairs."""
    if pose.shape[0] < 2:
        return
    pairs = near_pairs(pose, move, reach)
    kept = 0
    for p in range(pairs.shape[0]):
        if not (ctsim[pairs[p, 0]] and ctsim[pairs[p, 1]]):
            pairs[kept, 0], pairs[kept, 1] = pairs[p, 0], pairs[p, 1]
            kept += 1
    pairs = pairs[:kept]
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
