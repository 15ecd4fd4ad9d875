"""Compiled per-step kernels of the world, one pass over all robots each.

A world step is a handful of scalar formulas per robot (motor, encoders, arc, mouse, floor and
light sensors). Written with numpy they cost a few microseconds of call overhead each, which
dominates for one robot; these numba kernels do the same maths from `sim.kinematics` in one call
per step for any number of robots (tests compare them with the reference functions).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import exact_arc, half_angle, quantize_one

# A kernel call costs tens of nanoseconds per argument, so a world's step passes its per-robot
# values packed into a few 2-D arrays (`sim.world.physics` keeps named views of the columns):
# per-robot parameters (n, PARAMS) float64, fixed once the robots are in
COMMAND_MAX, MAX_SPEED, LAG, MAX_CHANGE, TICKS_PER_RAD = 0, 1, 2, 3, 4
REAL_RADIUS = 5  # left, right wheel (m)
TRACK = 7
MOUNT = 8  # the mouse's x, y in the body frame (m)
COUNTS_PER_METRE, MAX_STEP, SWEEP_RADIUS, APART_RADIUS, MASS, MOMENT, RADIUS = 10, 11, 12, 13, 14, 15, 16
STOPS = 17  # 1: c't-Sim's contact rule (`stop_at_contact`), 0: pymunk's
PARAMS = 18
# per-robot state (n, STATE) float64, two columns (left, right or x, y) each but ALPHA and BLOCKED
WHEEL_SPEED, TICK_CARRY, SLIP, MOUSE_NOISE, MOUSE_CARRY, MOVE, ALPHA = 0, 2, 4, 6, 8, 10, 12
BLOCKED = 13  # 1 when c't-Sim's contact rule refused the step's move
STATE = 14
# per-robot counts (n, TALLIES) int64: encoder ticks (left, right), mouse counts (x, y)
TICKS, COUNTS, TALLIES = 0, 2, 4
# the world's scalars (SCALARS,) float64: floor raster origin (x, y m), cell (m), whether outside
# it is a hole (0/1), the absorption outside it, IR ray length (m), slide margin (m), dt (s), the
# wall grid's origin (x, y m) and cell (m) (`build_wall_grid`), whether robots meet each other (0/1)
ORIGIN, CELL, OUTSIDE_IS_HOLE, OUTSIDE_ABSORPTION, IR_LENGTH, SLIDE_MARGIN, DT, WALL_FRAME, ROBOTS_MEET = 0, 2, 3, 4, 5, 6, 7, 8, 11
SCALARS = 12
# the wall grid's cells (int64, one array): columns, rows, then the cells' starts (rows x columns
# + 1, row-major; cell k lists members[starts[k]:starts[k + 1]]), the members, a buffer
COLUMNS, ROWS, STARTS = 0, 1, 2
# sensors of all robots (m, SENSOR) float64, floor then light then IR sensors: mount x, y (m),
# height (m; floor, light), view direction (rad; light, IR), half opening or cone (rad; light,
# IR), reach (m; light); and (m, INDEX) int64: owning robot, noise row and curve (IR)
AT, HEIGHT, DIRECTION, OPENING, REACH, AXIS, SENSOR = 0, 2, 3, 4, 5, 6, 7  # AXIS: 1 for an IR sensor's 'axis' view
OWNER, NOISE_ROW, CURVE, INDEX = 0, 1, 2, 3
GHOST = -2
"""The owner of a robot's circle that no sensor sees (a world of robots that do not meet, `sense_ir`)."""
# the world's count of quiet steps (2,) int64: steps in a row that began with no robot touching a
# wall, and how many such steps pymunk still takes (-1: every step is pymunk's)
STREAK, QUIET_AFTER = 0, 1
CLEAR = 1e-3
"""A robot nearer than this (m) to a wall counts as touching it (`settle`): far beyond rounding, so
that pymunk, which finds a contact at distance <= 0, finds none where this finds none."""


@numba.njit(cache=True)
def drive(
    commands: np.ndarray,
    wheel_speed: np.ndarray,
    command_max: np.ndarray,
    max_speed: np.ndarray,
    lag: np.ndarray,
    max_change: np.ndarray,
    dt: float,
    ticks_per_rad: np.ndarray,
    tick_carry: np.ndarray,
    ticks: np.ndarray,
    real_radius: np.ndarray,
    slip: np.ndarray,
    track: np.ndarray,
    pose: np.ndarray,
    move: np.ndarray,
    alpha: np.ndarray,
) -> None:
    """Motor model, encoder ticks and the exact-arc motion of every robot for one step.

    Writes wheel_speed (rad/s at the end of the step), ticks/tick_carry, and the unobstructed
    world displacement `move` (n, 2) and heading change `alpha` (n,) of the arc. Random slip
    `slip` (n, 2) (sqrt m, drawn per step) puts each wheel's arc s off by slip * sqrt(|s|): the
    variance grows with the distance rolled, whatever the step (Chong and Kleeman's model)."""
    for i in range(commands.shape[0]):
        for w in range(2):
            c = min(max(commands[i, w], -command_max[i]), command_max[i])
            target = c / command_max[i] * max_speed[i]
            current = wheel_speed[i, w]
            change = (target - current) * lag[i]
            change = min(max(change, -max_change[i]), max_change[i])
            wheel_speed[i, w] = current + change
            whole, fraction = quantize_one(wheel_speed[i, w] * dt * ticks_per_rad[i] + tick_carry[i, w])
            ticks[i, w] = whole
            tick_carry[i, w] = fraction
        s_l = wheel_speed[i, 0] * dt * real_radius[i, 0]
        s_r = wheel_speed[i, 1] * dt * real_radius[i, 1]
        s_l += slip[i, 0] * math.sqrt(abs(s_l))
        s_r += slip[i, 1] * math.sqrt(abs(s_r))
        chord, a, _, _ = exact_arc(s_l, s_r, track[i])
        mid = pose[i, 2] + 0.5 * a
        move[i, 0] = chord * math.cos(mid)
        move[i, 1] = chord * math.sin(mid)
        alpha[i] = a


@numba.njit(cache=True)
def _in_hole(x: float, y: float, hole: np.ndarray, origin: np.ndarray, cell: float, outside_is_hole: bool) -> bool:
    ix = int(math.floor((x - origin[0]) / cell))
    iy = int(math.floor((y - origin[1]) / cell))
    if ix < 0 or iy < 0 or iy >= hole.shape[0] or ix >= hole.shape[1]:
        return outside_is_hole
    return hole[iy, ix]


@numba.njit(cache=True)
def hold_at_holes(
    pose: np.ndarray,
    move: np.ndarray,
    alpha: np.ndarray,
    contacts: np.ndarray,
    anchored: np.ndarray,
    hole: np.ndarray,
    origin: np.ndarray,
    cell: float,
    outside_is_hole: bool,
    in_hole: np.ndarray,
) -> bool:
    """c't-Sim's ground-contact rule (`MasterSimulator`, "Bodenkontakt"): a robot whose planned
    move (n, 2) and turn (n,) would bring a ground contact over a hole neither moves nor turns
    this step (both zeroed in place; `in_hole` says so), and is asked again next step.

    Contacts are body-frame points (n, m, 2) at the new heading; c't-Sim places the skid at the
    new position but the wheels at the old one (`anchored`), so a skid stops at the edge and the
    robot drives off again, while wheels are checked a step late, end over the hole and keep
    every later move refused (c't-Sim's "falling"). Returns whether any robot's `in_hole` changed."""
    changed = False
    for i in range(pose.shape[0]):
        heading = pose[i, 2] + alpha[i]
        c, s = math.cos(heading), math.sin(heading)
        held = False
        for k in range(contacts.shape[1]):
            x, y = pose[i, 0], pose[i, 1]
            if not anchored[i, k]:
                x, y = x + move[i, 0], y + move[i, 1]
            px, py = contacts[i, k, 0], contacts[i, k, 1]
            held |= _in_hole(x + c * px - s * py, y + s * px + c * py, hole, origin, cell, outside_is_hole)
        changed |= in_hole[i] != held
        in_hole[i] = held
        if held:
            move[i, 0] = move[i, 1] = alpha[i] = 0.0
    return changed


@numba.njit(cache=True)
def first_bad(commands: np.ndarray) -> int:
    """Index of the first robot with a non-finite command (n, 2); -1 if none."""
    for i in range(commands.shape[0]):
        if not (math.isfinite(commands[i, 0]) and math.isfinite(commands[i, 1])):
            return i
    return -1


@numba.njit(cache=True)
def plan(commands: np.ndarray, params: np.ndarray, state: np.ndarray, tallies: np.ndarray, pose: np.ndarray, dt: float) -> int:
    """`drive` on the packed arrays (column layout above) when every command (n, 2) is finite;
    otherwise nothing changes and the first robot with a non-finite one is returned (-1: none)."""
    bad = first_bad(commands)
    if bad < 0:
        drive(
            commands, state[:, WHEEL_SPEED : WHEEL_SPEED + 2], params[:, COMMAND_MAX], params[:, MAX_SPEED], params[:, LAG],
            params[:, MAX_CHANGE], dt, params[:, TICKS_PER_RAD], state[:, TICK_CARRY : TICK_CARRY + 2],
            tallies[:, TICKS : TICKS + 2], params[:, REAL_RADIUS : REAL_RADIUS + 2],
            state[:, SLIP : SLIP + 2], params[:, TRACK], pose, state[:, MOVE : MOVE + 2], state[:, ALPHA],
        )  # fmt: skip
    return bad


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
    stop_at_contact(pose, move, params, state, vertices, ranges, boxes, wall_grid)
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
        clear = clear and _clear_of_walls(pose[i, 0], pose[i, 1], params[i, RADIUS] + CLEAR, vertices, ranges, boxes, wall_grid)
    quiet[STREAK] = quiet[STREAK] + 1 if clear else 0
    return changed, quiet[STREAK] > quiet[QUIET_AFTER]


@numba.njit(cache=True)
def stop_at_contact(pose: np.ndarray, move: np.ndarray, params: np.ndarray, state: np.ndarray, vertices: np.ndarray, ranges: np.ndarray,
                    boxes: np.ndarray, wall_grid: tuple) -> None:  # fmt: skip
    """c't-Sim's contact rule for the robots that have it (params' STOPS): a move that would put
    the body within its radius of a wall, or of another robot's body where that stands at the
    start of the step, is not made at all (MOVE set to 0, BLOCKED 1); the turn still is. So the
    robot stays at its last position clear of everything and can turn away, as c't-Sim commits
    the position only when its bounding sphere at the new one meets nothing (MasterSimulator)."""
    n = pose.shape[0]
    for i in range(n):
        if params[i, STOPS] == 0.0:
            continue
        state[i, BLOCKED] = 0.0
        if move[i, 0] == 0.0 and move[i, 1] == 0.0:
            continue
        x, y, radius = pose[i, 0] + move[i, 0], pose[i, 1] + move[i, 1], params[i, RADIUS]
        blocked = not _clear_of_walls(x, y, radius, vertices, ranges, boxes, wall_grid)
        for j in range(n):
            if not blocked and j != i:
                blocked = math.hypot(pose[j, 0] - x, pose[j, 1] - y) <= radius + params[j, RADIUS]
        if blocked:
            move[i, 0], move[i, 1], state[i, BLOCKED] = 0.0, 0.0, 1.0


@numba.njit(cache=True)
def _clear_of_walls(x: float, y: float, radius: float, vertices: np.ndarray, ranges: np.ndarray, boxes: np.ndarray, wall_grid: tuple) -> bool:
    """Whether a circle of `radius` at (x, y) is clear of every wall (farther than `radius`)."""
    lo_x, lo_y, hi_x, hi_y = x - radius, y - radius, x + radius, y + radius
    for w in walls_near(lo_x, lo_y, hi_x, hi_y, wall_grid[0], wall_grid[1]):
        if boxes[w, 0] > hi_x or boxes[w, 2] < lo_x or boxes[w, 1] > hi_y or boxes[w, 3] < lo_y:
            continue
        if _polygon_distance(x, y, vertices, ranges[w, 0], ranges[w, 1])[0] <= radius:
            return False
    return True


@numba.njit(cache=True)
def glide(pose: np.ndarray, params: np.ndarray, motion: np.ndarray, rows: np.ndarray, dt: float) -> np.ndarray:
    """The poses (n, 3) after a quiet step (`settle`): what pymunk's step and its position update
    give a body that enters the step at rest and meets nothing, the same operations in the same
    order (`cpBodyUpdateVelocity` with no gravity and no damping, then `cpBodyUpdatePosition`), so
    that they agree bit for bit."""
    after = np.empty_like(pose)
    for i in range(pose.shape[0]):
        r = rows[i]
        m_inv, i_inv = 1.0 / params[i, MASS], 1.0 / params[i, MOMENT]
        # velocity 0 times damping 1 plus (gravity 0 + force / mass) dt, and the position plus
        # (velocity + bias 0) dt: the zeros written out, as adding one can change the sign of a zero
        vx = 0.0 * 1.0 + (0.0 + motion[r, 3] * m_inv) * dt
        vy = 0.0 * 1.0 + (0.0 + motion[r, 4] * m_inv) * dt
        w = 0.0 * 1.0 + motion[r, 5] * i_inv * dt
        after[i, 0] = pose[i, 0] + (vx + 0.0) * dt
        after[i, 1] = pose[i, 1] + (vy + 0.0) * dt
        after[i, 2] = pose[i, 2] + (w + 0.0) * dt
    return after


@numba.njit(cache=True)
def measure(
    before: np.ndarray,
    after: np.ndarray,
    mount: np.ndarray,
    counts_per_metre: np.ndarray,
    max_step: np.ndarray,
    noise: np.ndarray,
    mouse_carry: np.ndarray,
    counts: np.ndarray,
    hole: np.ndarray,
    origin: np.ndarray,
    cell: float,
    outside_is_hole: bool,
) -> None:
    """Mouse counts from each body's true motion `before` -> `after`, read as the constant twist
    between them; a mouse over a hole reads nothing.

    counts_per_metre is 0 for a robot without a mouse; max_step the longest displacement per
    step (m) the sensor tracks; noise (n, 2) counts per sqrt m of floor passed (drawn per step):
    the error's variance grows with the distance the sensor moved, whatever the step."""
    for i in range(before.shape[0]):
        c0, s0 = math.cos(before[i, 2]), math.sin(before[i, 2])
        c1, s1 = math.cos(after[i, 2]), math.sin(after[i, 2])
        if counts_per_metre[i] == 0.0:
            continue
        dx, dy = after[i, 0] - before[i, 0], after[i, 1] - before[i, 1]
        bx, by = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
        dth = after[i, 2] - before[i, 2]
        h = 0.5 * dth
        cos_h, sinc_h = half_angle(h)
        sin_h = sinc_h * h
        tx, ty = (cos_h * bx + sin_h * by) / sinc_h, (-sin_h * bx + cos_h * by) / sinc_h
        fx, fy = tx - dth * mount[i, 1], ty + dth * mount[i, 0]
        mx, my = mount[i, 0], mount[i, 1]
        lifted = _in_hole(after[i, 0] + c1 * mx - s1 * my, after[i, 1] + s1 * mx + c1 * my, hole, origin, cell, outside_is_hole)
        if lifted or fx * fx + fy * fy > max_step[i] * max_step[i]:
            fx = fy = 0.0
        passed = math.sqrt(math.hypot(fx, fy))
        for axis, metres in enumerate((fx, fy)):
            whole, fraction = quantize_one(metres * counts_per_metre[i] + noise[i, axis] * passed + mouse_carry[i, axis])
            counts[i, axis] = whole
            mouse_carry[i, axis] = fraction


@numba.njit(cache=True)
def measure_all(
    before: np.ndarray, after: np.ndarray, params: np.ndarray, state: np.ndarray, tallies: np.ndarray, hole: np.ndarray, scalars: np.ndarray
) -> None:
    """`measure` on the packed arrays (column layout above)."""
    measure(
        before, after, params[:, MOUNT : MOUNT + 2], params[:, COUNTS_PER_METRE], params[:, MAX_STEP], state[:, MOUSE_NOISE : MOUSE_NOISE + 2],
        state[:, MOUSE_CARRY : MOUSE_CARRY + 2], tallies[:, COUNTS : COUNTS + 2], hole, scalars[ORIGIN : ORIGIN + 2], scalars[CELL],
        scalars[OUTSIDE_IS_HOLE] != 0.0,
    )  # fmt: skip


@numba.njit(cache=True)
def to_world(pose: np.ndarray, offsets: np.ndarray, owner: np.ndarray, out: np.ndarray) -> None:
    """World positions of body-frame points `offsets` (m, 2) of robots `owner` (m,)."""
    for k in range(offsets.shape[0]):
        i = owner[k]
        c, s = math.cos(pose[i, 2]), math.sin(pose[i, 2])
        out[k, 0] = pose[i, 0] + c * offsets[k, 0] - s * offsets[k, 1]
        out[k, 1] = pose[i, 1] + s * offsets[k, 0] + c * offsets[k, 1]


FAN = np.tan(np.radians(np.array((40.0, 20.0, 0.0, -20.0, -40.0))))
"""Where c't-Sim's five rays of one fan of a CNY70 meet the floor, per metre of sensor height
(80° opening in 20° steps, `World.sensGroundReflectionLine`)."""


@numba.njit(cache=True)
def _absorption_at(x: float, y: float, absorption: np.ndarray, origin: np.ndarray, cell: float, outside: np.float32) -> np.float32:
    ix = int(math.floor((x - origin[0]) / cell))
    iy = int(math.floor((y - origin[1]) / cell))
    if ix < 0 or iy < 0 or iy >= absorption.shape[0] or ix >= absorption.shape[1]:
        return outside
    return absorption[iy, ix]


@numba.njit(cache=True)
def sample_floor(
    pose: np.ndarray,
    offsets: np.ndarray,
    owner: np.ndarray,
    height: np.ndarray,
    absorption: np.ndarray,
    origin: np.ndarray,
    cell: float,
    outside: float,
    fan: np.ndarray,
    out: np.ndarray,
) -> None:
    """CNY70 values (0..1023) of floor sensors mounted at body-frame `offsets` (m, 2) of robots
    `owner`, `height` m above the floor, as c't-Sim's `World.sensGroundReflectionCross`: a fan of
    rays across the heading (left first) and one along it (back first) meet the floor at
    height * `fan`; each fan's absorption is summed in float32 and truncated to 0..1023, and the
    reading is the two fans' truncated mean. Height 0 reads the mount point alone."""
    out_absorption = np.float32(outside)
    points = np.empty((offsets.shape[0], 2))
    to_world(pose, offsets, owner, points)
    for k in range(points.shape[0]):
        c, s = math.cos(pose[owner[k], 2]), math.sin(pose[owner[k], 2])
        total = 0
        for ux, uy in ((-s, c), (-c, -s)):
            swallowed = np.float32(0.0)
            for j in range(fan.shape[0]):
                r = height[k] * fan[j]
                swallowed += _absorption_at(points[k, 0] + r * ux, points[k, 1] + r * uy, absorption, origin, cell, out_absorption)
            total += int(swallowed * np.float32(1023.0) / np.float32(fan.shape[0]))
        out[k] = total // 2


@numba.njit(cache=True)
def _ray_polygon(ox: float, oy: float, ux: float, uy: float, vertices: np.ndarray, start: int, end: int) -> float:
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


@numba.njit(cache=True)
def _corner_in_cone(ox: float, oy: float, cx: float, cy: float, cos_cone: float, vertices: np.ndarray, start: int, end: int) -> float:
    """Distance to the nearest corner of the polygon vertices[start:end] inside the cone from (ox,
    oy) around the unit axis (cx, cy); inf if none."""
    best = math.inf
    for k in range(start, end):
        dx, dy = vertices[k, 0] - ox, vertices[k, 1] - oy
        d = math.hypot(dx, dy)
        if dx * cx + dy * cy >= cos_cone * d:
            best = min(best, d)
    return best


@numba.njit(cache=True)
def _ray_circle(ox: float, oy: float, ux: float, uy: float, cx: float, cy: float, r: float) -> float:
    along = (cx - ox) * ux + (cy - oy) * uy
    across2 = (cx - ox) ** 2 + (cy - oy) ** 2 - along * along
    if along < 0.0 or across2 > r * r:
        return math.inf
    return along - math.sqrt(r * r - across2)


@numba.njit(cache=True)
def build_wall_grid(boxes: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """A uniform grid of square `cell`s over the walls' bounding boxes (xmin, ymin, xmax, ymax), for
    `walls_near`: (frame: origin x, y and cell size; cells: one int64 array, layout above, the
    buffer one wall long per wall). A wall is listed, in ascending order, in every cell its box
    overlaps. The grid spans the walls' boxes only (a query beyond it meets its edge cells, whose
    walls' boxes it misses). An infinite `cell` gives one cell of every wall: the plain loop."""
    n = boxes.shape[0]
    x0 = boxes[:, 0].min() if n else 0.0
    y0 = boxes[:, 1].min() if n else 0.0
    cols = 1 + max(_cell_index(boxes[:, 2].max(), x0, cell, 1 << 30), 0) if n else 1
    rows = 1 + max(_cell_index(boxes[:, 3].max(), y0, cell, 1 << 30), 0) if n else 1
    span = np.empty((n, 4), dtype=np.int64)  # per wall: its first and last column, first and last row
    count = np.zeros(rows * cols + 1, dtype=np.int64)  # count[k + 1]: walls in cell k
    for w in range(n):
        span[w, 0], span[w, 1] = _cell_index(boxes[w, 0], x0, cell, cols - 1), _cell_index(boxes[w, 2], x0, cell, cols - 1)
        span[w, 2], span[w, 3] = _cell_index(boxes[w, 1], y0, cell, rows - 1), _cell_index(boxes[w, 3], y0, cell, rows - 1)
        for r in range(span[w, 2], span[w, 3] + 1):
            for k in range(r * cols + span[w, 0] + 1, r * cols + span[w, 1] + 2):  # (a loop: as below)
                count[k] += 1
    starts = np.cumsum(count)
    first = STARTS + starts.shape[0]  # where the members begin
    cells = np.empty(first + starts[-1] + max(n, 1), dtype=np.int64)
    cells[COLUMNS], cells[ROWS] = cols, rows
    for k in range(starts.shape[0]):  # (loops: numba's slice assignment compiles the formatting of its error message, seconds)
        cells[STARTS + k] = starts[k]
    fill = first + starts[:-1]
    for w in range(n):  # walls in ascending order: each cell's list ascends
        for r in range(span[w, 2], span[w, 3] + 1):
            for k in range(r * cols + span[w, 0], r * cols + span[w, 1] + 1):
                cells[fill[k]] = w
                fill[k] += 1
    return np.array((x0, y0, cell)), cells


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
    cols, rows = cells[COLUMNS], cells[ROWS]
    first = STARTS + rows * cols + 1
    c0, c1 = _cell_index(lo_x, frame[0], frame[2], cols - 1), _cell_index(hi_x, frame[0], frame[2], cols - 1)
    r0, r1 = _cell_index(lo_y, frame[1], frame[2], rows - 1), _cell_index(hi_y, frame[1], frame[2], rows - 1)
    if r0 == r1 and c0 == c1:
        return cells[first + cells[STARTS + r0 * cols + c0] : first + cells[STARTS + r0 * cols + c0 + 1]]
    buffer = cells[first + cells[first - 1] :]
    count = 0
    for r in range(r0, r1 + 1):
        for p in range(first + cells[STARTS + r * cols + c0], first + cells[STARTS + r * cols + c1 + 1]):
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
def ir_rays(pose: np.ndarray, offsets: np.ndarray, owner: np.ndarray, direction: np.ndarray, origins: np.ndarray, look: np.ndarray) -> None:
    """World origins (m, 2) and view directions (m,) of IR sensors mounted at body-frame `offsets`
    looking along body-frame `direction` on robots `owner` (as `to_world` and heading + direction)."""
    to_world(pose, offsets, owner, origins)
    for k in range(offsets.shape[0]):
        look[k] = pose[owner[k], 2] + direction[k]


@numba.njit(cache=True)
def _circle_in_view(ox: float, oy: float, cx: float, cy: float, cos_cone: float, l1x: float, l1y: float, l2x: float, l2y: float,
                    px: float, py: float, r: float, best: float) -> float:
    """`best` lowered to the distance of the circle (px, py, r) in the cone, as in `sense_ir`; -1 when
    the origin is inside the circle."""
    centre = math.hypot(px - ox, py - oy)
    if centre <= r:
        return -1.0
    if (px - ox) * cx + (py - oy) * cy >= cos_cone * centre:
        best = min(best, centre - r)
    return min(best, _ray_circle(ox, oy, l1x, l1y, px, py, r), _ray_circle(ox, oy, l2x, l2y, px, py, r))


@numba.njit(cache=True)
def sense_ir(
    origins: np.ndarray,
    look: np.ndarray,
    cone: np.ndarray,
    owner: np.ndarray,
    length: float,
    vertices: np.ndarray,
    ranges: np.ndarray,
    boxes: np.ndarray,
    circles: np.ndarray,
    out: np.ndarray,
    grid_above: int = 32,
    wall_grid: tuple | None = None,
    axis: np.ndarray | None = None,
) -> None:
    """Distance (m) from each IR sensor at `origins` to the nearest point of a wall (convex
    polygons vertices[ranges[w, 0]:ranges[w, 1]], bounding boxes `boxes`) or a circle (x, y,
    radius, owning robot or -1; a sensor skips its own robot's, and every sensor a GHOST's) within `cone` (half-angle, rad) of
    `look` and within `length`; inf if none. As `World.ray_distance`: per convex body the nearest
    point if it lies in the cone, else the first hit of an edge ray. A sensor with `axis[k]` 1
    sees a wall where its axis meets it or at a corner inside the cone (c't-Sim's pick).

    With more than `grid_above` circles, each sensor checks only the circles in the grid cells
    its cone's bounding box overlaps (a crowd would otherwise cost sensors x robots); the nearest
    distance is a minimum, so the grid gives the all-circles result bit for bit. Walls are taken
    from `wall_grid` (`build_wall_grid`; None: one cell of every wall) in the cells the cone's
    bounding box overlaps, in ascending order as a loop over every wall would meet them; only a
    wall whose box meets the cone's can give a distance within `length` (every nearest point and
    edge-ray hit that counts lies in the cone), so the others are skipped without changing a bit."""
    frame, cells = build_wall_grid(boxes, math.inf) if wall_grid is None else wall_grid
    use_grid = circles.shape[0] > grid_above
    cell, x0, y0, cols, rows, order, sorted_key, widest = 1.0, 0.0, 0.0, 1, 1, np.empty(0, np.int64), np.empty(0, np.int64), 0.0
    if use_grid:
        cell, x0, y0, cols, rows, order, sorted_key, widest = _circle_grid(circles, length)
    for k in range(origins.shape[0]):
        ox, oy = origins[k, 0], origins[k, 1]
        cx, cy = math.cos(look[k]), math.sin(look[k])
        cos_cone = math.cos(cone[k])
        l1x, l1y = math.cos(look[k] - cone[k]), math.sin(look[k] - cone[k])
        l2x, l2y = math.cos(look[k] + cone[k]), math.sin(look[k] + cone[k])
        best = math.inf
        # a wall counts only where it meets the cone within `length` (inside the wall: at the apex)
        lo_x, lo_y, hi_x, hi_y = _cone_box(ox, oy, cx, cy, l1x, l1y, l2x, l2y, cone[k], length)
        for w in walls_near(lo_x, lo_y, hi_x, hi_y, frame, cells):
            if boxes[w, 0] > hi_x or boxes[w, 2] < lo_x or boxes[w, 1] > hi_y or boxes[w, 3] < lo_y:
                continue
            start, end = ranges[w, 0], ranges[w, 1]
            distance, qx, qy = _polygon_distance(ox, oy, vertices, start, end)
            if distance <= 0.0:
                best = 0.0
                break
            if axis is not None and axis[k] != 0.0:
                best = min(best, _ray_polygon(ox, oy, cx, cy, vertices, start, end), _corner_in_cone(ox, oy, cx, cy, cos_cone, vertices, start, end))
                continue
            if (qx - ox) * cx + (qy - oy) * cy >= cos_cone * distance:
                best = min(best, distance)
            best = min(best, _ray_polygon(ox, oy, l1x, l1y, vertices, start, end), _ray_polygon(ox, oy, l2x, l2y, vertices, start, end))
        if use_grid:
            # a circle can matter if its centre lies within its radius of the cone's box
            gx0 = max(int(math.floor((lo_x - widest - x0) / cell)), 0)
            gx1 = min(int(math.floor((hi_x + widest - x0) / cell)), cols - 1)
            gy0 = max(int(math.floor((lo_y - widest - y0) / cell)), 0)
            gy1 = min(int(math.floor((hi_y + widest - y0) / cell)), rows - 1)
            inside = False
            for gy in range(gy0, gy1 + 1):
                if gx0 > gx1 or inside:
                    break
                last = gy * cols + gx1
                for p in range(_first_at_least(sorted_key, gy * cols + gx0), sorted_key.shape[0]):
                    if sorted_key[p] > last:
                        break
                    j = order[p]
                    if int(circles[j, 3]) == owner[k] or int(circles[j, 3]) == GHOST:
                        continue
                    best = _circle_in_view(ox, oy, cx, cy, cos_cone, l1x, l1y, l2x, l2y, circles[j, 0], circles[j, 1], circles[j, 2], best)
                    if best < 0.0:
                        inside = True
                        break
        else:
            for j in range(circles.shape[0]):
                if int(circles[j, 3]) == owner[k] or int(circles[j, 3]) == GHOST:
                    continue
                best = _circle_in_view(ox, oy, cx, cy, cos_cone, l1x, l1y, l2x, l2y, circles[j, 0], circles[j, 1], circles[j, 2], best)
                if best < 0.0:
                    break
        best = max(best, 0.0)  # -1: inside a circle
        out[k] = best if best <= length else math.inf


@numba.njit(cache=True)
def _circle_grid(circles: np.ndarray, length: float):
    """A uniform grid over the circles' centres: (cell size, origin x, y, columns, rows, circle
    order by cell, sorted cell keys, largest radius); key = row * columns + column, so a row's run
    of cells is one run of keys. Cells are a quarter of the ray length (at least two diameters), so
    a cone's bounding box spans a handful of cells."""
    n = circles.shape[0]
    widest = circles[:, 2].max()
    cell = max(0.25 * length, 4.0 * widest)
    x0, y0 = circles[:, 0].min(), circles[:, 1].min()
    cx = np.empty(n, dtype=np.int64)
    cy = np.empty(n, dtype=np.int64)
    for j in range(n):
        cx[j] = int(math.floor((circles[j, 0] - x0) / cell))
        cy[j] = int(math.floor((circles[j, 1] - y0) / cell))
    cols, rows = cx.max() + 1, cy.max() + 1
    order, sorted_key = _stable_order(cy * cols + cx)
    return cell, x0, y0, cols, rows, order, sorted_key, widest


@numba.njit(cache=True)
def _cone_box(ox: float, oy: float, cx: float, cy: float, l1x: float, l1y: float, l2x: float, l2y: float, cone: float, length: float):
    """(xmin, ymin, xmax, ymax) holding the cone of `length` (apex (ox, oy), axis (cx, cy), edges l1,
    l2): the box of its apex and its arc's ends and middle, grown by the arc's sagitta (a cone wider
    than 45 degrees: the box of the whole disc)."""
    if cone > 0.25 * math.pi:
        margin = length + 1e-9
        return ox - margin, oy - margin, ox + margin, oy + margin
    ax, bx, mx = ox + length * l1x, ox + length * l2x, ox + length * cx
    ay, by, my = oy + length * l1y, oy + length * l2y, oy + length * cy
    margin = length * (1.0 - math.cos(cone)) + 1e-9
    return min(ox, ax, bx, mx) - margin, min(oy, ay, by, my) - margin, max(ox, ax, bx, mx) + margin, max(oy, ay, by, my) + margin


@numba.njit(cache=True)
def ir_values(
    distance: np.ndarray,
    noise_row: np.ndarray,
    noise_std: np.ndarray,
    normals: np.ndarray,
    used: np.ndarray,
    curve: np.ndarray,
    tables: np.ndarray,
    last: np.ndarray,
    beyond: np.ndarray,
    inverse: np.ndarray,
    lowest: np.ndarray,
    raw: np.ndarray,
    believed: np.ndarray,
) -> None:
    """Raw value and believed distance of each IR sensor from its true `distance` (m).

    A sensor with noise (noise_row[k] = q >= 0) and something in view reads its distance plus
    noise_std[q] times its next standard normal (normals[q, used[q]], `used` advanced), not below
    0. The raw value is `IRCurve.lookup` on curve c = curve[k] (its per-centimetre float32 table
    tables[c, :last[c] + 1] and beyond[c]), the believed distance the curve's inverse for the
    sensor's range tabulated per raw value from lowest[c] (`IRCurve.inverse_table`): the same
    arithmetic, so the same bits."""
    for k in range(distance.shape[0]):
        d = distance[k]
        q = noise_row[k]
        if q >= 0 and d < math.inf:
            d = max(0.0, d + (0.0 + noise_std[q] * normals[q, used[q]]))  # as rng.normal(0.0, std)
            used[q] += 1
        c = curve[k]
        cm = d * 100.0
        value = np.float64(beyond[c])
        if cm >= 0.0 and cm <= last[c]:
            i = int(math.floor(cm))
            here = tables[c, i]
            value = np.float64(here)
            if here != beyond[c] and i < last[c]:
                value = value + (cm - i) * np.float64(tables[c, i + 1] - here)  # a float32 difference, as in Java
        r = int(math.floor(value + 0.5))
        raw[k] = r
        believed[k] = inverse[c, r - lowest[c]]


@numba.njit(cache=True)
def read_ir(
    pose: np.ndarray,
    offsets: np.ndarray,
    owner: np.ndarray,
    direction: np.ndarray,
    cone: np.ndarray,
    axis: np.ndarray,
    length: float,
    vertices: np.ndarray,
    ranges: np.ndarray,
    boxes: np.ndarray,
    wall_grid: tuple,
    circles: np.ndarray,
    noise_row: np.ndarray,
    noise_std: np.ndarray,
    normals: np.ndarray,
    used: np.ndarray,
    curve: np.ndarray,
    tables: np.ndarray,
    last: np.ndarray,
    beyond: np.ndarray,
    inverse: np.ndarray,
    lowest: np.ndarray,
    raw: np.ndarray,
    believed: np.ndarray,
) -> None:
    """Every IR reading of a world whose robots are all circles, in one call: the sensors' rays
    (`ir_rays`), the robots (the first rows of `circles`, positions taken from `pose`) and the
    other circles and walls they see (`sense_ir`), and noise and curves (`ir_values`)."""
    m = offsets.shape[0]
    origins, look, distance = np.empty((m, 2)), np.empty(m), np.empty(m)
    ir_rays(pose, offsets, owner, direction, origins, look)
    for i in range(pose.shape[0]):
        circles[i, 0], circles[i, 1] = pose[i, 0], pose[i, 1]
    sense_ir(origins, look, cone, owner, length, vertices, ranges, boxes, circles, distance, 32, wall_grid, axis)
    ir_values(distance, noise_row, noise_std, normals, used, curve, tables, last, beyond, inverse, lowest, raw, believed)


@numba.njit(cache=True)
def sense_light(
    pose: np.ndarray,
    offsets: np.ndarray,
    owner: np.ndarray,
    height: np.ndarray,
    direction: np.ndarray,
    half_opening: np.ndarray,
    reach: np.ndarray,
    lights: np.ndarray,
    out: np.ndarray,
) -> None:
    """LDR darkness (0..1023) of sensors mounted at body-frame `offsets` (m, 2) of robots `owner`,
    `height` m up, looking horizontally along body-frame `direction` (rad): the distance from the sensor to the surface of the nearest lamp (x, y,
    height, radius) whose centre is within `half_opening` of the view axis in 3-D, over `reach`,
    truncated; 1023 with none (c't-Sim `World.sensLight`)."""
    points = np.empty((offsets.shape[0], 2))
    to_world(pose, offsets, owner, points)
    for k in range(points.shape[0]):
        nearest = math.inf
        look = pose[owner[k], 2] + direction[k]
        cx, cy = math.cos(look), math.sin(look)
        cos_limit = math.cos(half_opening[k])
        for j in range(lights.shape[0]):
            ox, oy, oz = lights[j, 0] - points[k, 0], lights[j, 1] - points[k, 1], lights[j, 2] - height[k]
            centre = math.sqrt(ox * ox + oy * oy + oz * oz)
            if ox * cx + oy * cy >= cos_limit * centre - 1e-12:
                nearest = min(nearest, max(centre - lights[j, 3], 0.0))
        out[k] = int(math.floor(min(nearest / reach[k], 1.0) * 1023))


@numba.njit(cache=True)
def read_sensors(
    pose: np.ndarray,
    sensors: np.ndarray,
    index: np.ndarray,
    n_floor: int,
    absorption: np.ndarray,
    scalars: np.ndarray,
    lights: np.ndarray,
    vertices: np.ndarray,
    ranges: np.ndarray,
    boxes: np.ndarray,
    wall_cells: np.ndarray,
    circles: np.ndarray,
    noise_std: np.ndarray,
    normals: np.ndarray,
    used: np.ndarray,
    tables: np.ndarray,
    curve_ends: np.ndarray,
    beyond: np.ndarray,
    inverse: np.ndarray,
    values: np.ndarray,
    believed: np.ndarray,
) -> None:
    """Every floor, light and IR reading of the world in one call, on the packed sensor arrays
    (column layout above): the first `n_floor` rows are floor sensors (`sample_floor`), the last
    len(believed) IR sensors (`read_ir`; curve_ends holds each curve's `last` and `lowest`), the
    rows between light sensors (`sense_light`); `values` gets each row's integer reading. A world
    that reads its IR sensors with pymunk passes only the floor and light rows and no `believed`."""
    lo, hi = n_floor, sensors.shape[0] - believed.shape[0]
    origin = scalars[ORIGIN : ORIGIN + 2]
    sample_floor(
        pose, sensors[:lo, AT : AT + 2], index[:lo, OWNER], sensors[:lo, HEIGHT], absorption, origin, scalars[CELL],
        scalars[OUTSIDE_ABSORPTION], FAN, values[:lo],
    )  # fmt: skip
    sense_light(
        pose, sensors[lo:hi, AT : AT + 2], index[lo:hi, OWNER], sensors[lo:hi, HEIGHT], sensors[lo:hi, DIRECTION],
        sensors[lo:hi, OPENING], sensors[lo:hi, REACH], lights, values[lo:hi],
    )  # fmt: skip
    if believed.shape[0]:
        read_ir(
            pose, sensors[hi:, AT : AT + 2], index[hi:, OWNER], sensors[hi:, DIRECTION], sensors[hi:, OPENING], sensors[hi:, AXIS], scalars[IR_LENGTH],
            vertices, ranges, boxes, (scalars[WALL_FRAME : WALL_FRAME + 3], wall_cells), circles, index[hi:, NOISE_ROW], noise_std, normals, used, index[hi:, CURVE], tables,
            curve_ends[:, 0], beyond, inverse, curve_ends[:, 1], values[hi:], believed,
        )  # fmt: skip


@numba.njit(cache=True)
def _polygon_distance(px: float, py: float, vertices: np.ndarray, start: int, end: int) -> tuple[float, float, float]:
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
            distance, cx, cy = _polygon_distance(x, y, vertices, ranges[w, 0], ranges[w, 1])
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
def _stable_order(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
def _first_at_least(values: np.ndarray, key: int) -> int:
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
def _near_pairs(pose: np.ndarray, move: np.ndarray, reach: np.ndarray) -> np.ndarray:
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
    order, sorted_key = _stable_order(key)
    pairs = np.empty((4 * n + 16, 2), dtype=np.int64)
    count = 0
    found = np.empty(n, dtype=np.int64)
    for i in range(n):
        m = 0
        for dx in range(-1, 2):
            low = key[i] + dx * rows - 1  # the column's three cells dy = -1, 0, 1 are consecutive keys
            for p in range(_first_at_least(sorted_key, low), n):
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


@numba.njit(cache=True)
def keep_apart(pose: np.ndarray, move: np.ndarray, reach: np.ndarray) -> None:
    """Shorten the moves (n, 2), in place, of robots that would run into each other: both moves
    of a pair are cut at the moment the pair would touch (closer than reach[i] + reach[j]).
    Cuts only shorten moves, but a shorter move can let a follower catch up, so the pairs are
    checked again until none closes in; robots still in conflict after that stand still.

    Only pairs near enough to meet are checked (`_near_pairs`, found once: cuts never lengthen
    a move), in the order of checking all pairs, so the cuts are those of all pairs."""
    if pose.shape[0] < 2:
        return
    pairs = _near_pairs(pose, move, reach)
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
