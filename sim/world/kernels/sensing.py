"""Compiled sensor kernels, one pass over all sensors of all robots each: floor (CNY70), light (LDR)
and IR (GP2D12: rays, walls and circles in view, noise and curves), and `read_sensors`, every
floor, light and IR reading of a world in one call."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.world.kernels.floor import absorption_at
from sim.world.kernels.geometry import polygon_distance, ray_circle, ray_polygon
from sim.world.kernels.grids import build_wall_grid, circle_grid, first_at_least, walls_near
from sim.world.kernels.pick import pick_polygon
from sim.world.layout import AT, CELL, CURVE, DIRECTION, GHOST, HEIGHT, IR_LENGTH, LINE_HEIGHT, NOISE_ROW, OPENING, ORIGIN, OUTSIDE_ABSORPTION, OWNER, PICK, REACH, WALL_FRAME


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
def _line_at(x: float, y: float, lines: np.ndarray, origin: np.ndarray, cell: float) -> np.float32:
    """The absorption of the line at (x, y); NaN off every line (and off the map)."""
    ix = int(math.floor((x - origin[0]) / cell))
    iy = int(math.floor((y - origin[1]) / cell))
    if ix < 0 or iy < 0 or iy >= lines.shape[0] or ix >= lines.shape[1]:
        return np.float32(np.nan)
    return lines[iy, ix]


@numba.njit(cache=True)
def sample_floor(
    pose: np.ndarray,
    offsets: np.ndarray,
    owner: np.ndarray,
    height: np.ndarray,
    ground: np.ndarray,
    lines: np.ndarray,
    line_height: float,
    origin: np.ndarray,
    cell: float,
    outside: float,
    fan: np.ndarray,
    out: np.ndarray,
) -> None:
    """CNY70 values (0..1023) of floor sensors mounted at body-frame `offsets` (m, 2) of robots
    `owner`, `height` m above the floor, as c't-Sim's `World.sensGroundReflectionCross`: a fan of
    rays across the heading (left first) and one along it (back first); a ray meets a line, whose
    top stands `line_height` above the floor, at (height - line_height) * `fan` off the mount
    point, else the floor (`ground`, without its lines) at height * `fan`; each fan's absorption
    is summed in float32 and truncated to 0..1023, and the reading is the two fans' truncated
    mean. Height 0 reads the mount point alone."""
    out_absorption = np.float32(outside)
    points = np.empty((offsets.shape[0], 2))
    to_world(pose, offsets, owner, points)
    for k in range(points.shape[0]):
        c, s = math.cos(pose[owner[k], 2]), math.sin(pose[owner[k], 2])
        above_lines = max(height[k] - line_height, 0.0)
        total = 0
        for ux, uy in ((-s, c), (-c, -s)):
            swallowed = np.float32(0.0)
            for j in range(fan.shape[0]):
                r = above_lines * fan[j]
                value = _line_at(points[k, 0] + r * ux, points[k, 1] + r * uy, lines, origin, cell)
                if math.isnan(value):
                    r = height[k] * fan[j]
                    value = absorption_at(points[k, 0] + r * ux, points[k, 1] + r * uy, ground, origin, cell, out_absorption)
                swallowed += value
            total += int(swallowed * np.float32(1023.0) / np.float32(fan.shape[0]))
        out[k] = total // 2


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
    return min(best, ray_circle(ox, oy, l1x, l1y, px, py, r), ray_circle(ox, oy, l2x, l2y, px, py, r))


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
    pick: np.ndarray | None = None,
) -> None:
    """Distance (m) from each IR sensor at `origins` to the nearest point of a wall (convex
    polygons vertices[ranges[w, 0]:ranges[w, 1]], bounding boxes `boxes`) or a circle (x, y,
    radius, owning robot or -1; a sensor skips its own robot's, and every sensor a GHOST's) within `cone` (half-angle, rad) of
    `look` and within `length`; inf if none. As `World.ray_distance`: per convex body the nearest
    point if it lies in the cone, else the first hit of an edge ray. A sensor with `pick[k]` 1
    sees a wall as c't-Sim's Java3D cone pick does (`pick.pick_polygon`).

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
        cell, x0, y0, cols, rows, order, sorted_key, widest = circle_grid(circles, length)
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
            if pick is not None and pick[k] != 0.0:
                best = min(best, pick_polygon(ox, oy, cx, cy, length, math.tan(cone[k]), vertices, start, end))
                continue
            distance, qx, qy = polygon_distance(ox, oy, vertices, start, end)
            if distance <= 0.0:
                best = 0.0
                break
            if (qx - ox) * cx + (qy - oy) * cy >= cos_cone * distance:
                best = min(best, distance)
            best = min(best, ray_polygon(ox, oy, l1x, l1y, vertices, start, end), ray_polygon(ox, oy, l2x, l2y, vertices, start, end))
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
                for p in range(first_at_least(sorted_key, gy * cols + gx0), sorted_key.shape[0]):
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
        out[k] = best if best <= length or (pick is not None and pick[k] != 0.0) else math.inf  # a pick's rim reaches past the axis's end


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
    pick: np.ndarray,
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
    sense_ir(origins, look, cone, owner, length, vertices, ranges, boxes, circles, distance, 32, wall_grid, pick)
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
    ground: np.ndarray,
    lines: np.ndarray,
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
        pose, sensors[:lo, AT : AT + 2], index[:lo, OWNER], sensors[:lo, HEIGHT], ground, lines, scalars[LINE_HEIGHT], origin, scalars[CELL],
        scalars[OUTSIDE_ABSORPTION], FAN, values[:lo],
    )  # fmt: skip
    sense_light(
        pose, sensors[lo:hi, AT : AT + 2], index[lo:hi, OWNER], sensors[lo:hi, HEIGHT], sensors[lo:hi, DIRECTION],
        sensors[lo:hi, OPENING], sensors[lo:hi, REACH], lights, values[lo:hi],
    )  # fmt: skip
    if believed.shape[0]:
        read_ir(
            pose, sensors[hi:, AT : AT + 2], index[hi:, OWNER], sensors[hi:, DIRECTION], sensors[hi:, OPENING], sensors[hi:, PICK], scalars[IR_LENGTH],
            vertices, ranges, boxes, (scalars[WALL_FRAME : WALL_FRAME + 3], wall_cells), circles, index[hi:, NOISE_ROW], noise_std, normals, used, index[hi:, CURVE], tables,
            curve_ends[:, 0], beyond, inverse, curve_ends[:, 1], values[hi:], believed,
        )  # fmt: skip
