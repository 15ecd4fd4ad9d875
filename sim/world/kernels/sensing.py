"""Compiled sensor kernels, one pass over all sensors of all robots each: floor (CNY70), light (LDR)
and IR (GP2D12: rays, walls and circles in view, noise and curves), and `read_sensors`, every
floor, light and IR reading of a world in one call."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import INNER
from sim.world.kernels.floor import raster_at
from sim.world.kernels.geometry import polygon_distance, ray_circle, ray_polygon
from sim.world.kernels.grids import circle_grid, first_at_least, walls_near
from sim.world.kernels.light_pick import pick_lamps
from sim.world.kernels.pick import move_robot_leaves, pick_tree, pick_wall
from sim.world.layout import GHOST, BoundsTree, Curves, Floor, Noise, Rays, Readout, Sensing, Walls

CIRCLE_GRID_ABOVE = 32
"""Circles (robots and cans) beyond which IR rays find the circles near them in a grid (`sense_ir`)."""


@numba.njit(cache=True, **INNER)
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


@numba.njit(cache=True, **INNER)
def sample_floor(pose: np.ndarray, sensors: np.ndarray, floor: Floor, out: np.ndarray) -> None:
    """CNY70 values (0..1023) of floor SENSORS (their mount, owner and height above the floor), as
    c't-Sim's `World.sensGroundReflectionCross`: a fan of rays across the heading (left first) and
    one along it (back first); a ray meets a line, whose top stands `floor.line_height` above the
    floor, at (height - line_height) * `FAN` off the mount point, else the ground (without its
    lines) at height * `FAN`; each fan's absorption is summed in float32 and truncated to 0..1023,
    and the reading is the two fans' truncated mean. Height 0 reads the mount point alone."""
    out_absorption, off_lines = np.float32(floor.outside_absorption), np.float32(np.nan)
    ground, lines, ox, oy, cell = floor.ground, floor.lines, floor.origin[0], floor.origin[1], floor.cell
    owner = sensors.owner
    points = np.empty((sensors.shape[0], 2))
    to_world(pose, sensors.at, owner, points)
    for k in range(points.shape[0]):
        c, s = math.cos(pose[owner[k], 2]), math.sin(pose[owner[k], 2])
        height = sensors[k].height
        above_lines = max(height - floor.line_height, 0.0)
        total = 0
        for ux, uy in ((-s, c), (-c, -s)):
            swallowed = np.float32(0.0)
            for j in range(FAN.shape[0]):
                r = above_lines * FAN[j]
                value = raster_at(points[k, 0] + r * ux, points[k, 1] + r * uy, lines, ox, oy, cell, off_lines)
                if math.isnan(value):
                    r = height * FAN[j]
                    value = raster_at(points[k, 0] + r * ux, points[k, 1] + r * uy, ground, ox, oy, cell, out_absorption)
                swallowed += value
            total += int(swallowed * np.float32(1023.0) / np.float32(FAN.shape[0]))
        out[k] = total // 2


@numba.njit(cache=True)
def ir_rays(pose: np.ndarray, sensors: np.ndarray, origins: np.ndarray, look: np.ndarray) -> None:
    """World origins (m, 2) and view directions (m,) of IR SENSORS (as `to_world`, and heading + direction)."""
    owner = sensors.owner
    to_world(pose, sensors.at, owner, origins)
    for k in range(sensors.shape[0]):
        look[k] = pose[owner[k], 2] + sensors[k].direction


@numba.njit(cache=True, **INNER)
def _circle_in_view(view: tuple, px: float, py: float, r: float, best: float) -> float:
    """`best` lowered to the distance of the circle (px, py, r) in the cone `view` (origin x, y,
    axis x, y, cos of the cone, edge rays 1 and 2 x, y), as in `sense_ir`; -1 when the origin is
    inside the circle."""
    ox, oy, cx, cy, cos_cone, l1x, l1y, l2x, l2y = view
    centre = math.hypot(px - ox, py - oy)
    if centre <= r:
        return -1.0
    if (px - ox) * cx + (py - oy) * cy >= cos_cone * centre:
        best = min(best, centre - r)
    return min(best, ray_circle(ox, oy, l1x, l1y, px, py, r), ray_circle(ox, oy, l2x, l2y, px, py, r))


@numba.njit(cache=True)
def sense_ir(rays: Rays, walls: Walls, circles: np.ndarray, length: float, out: np.ndarray, grid_above: int | None = CIRCLE_GRID_ABOVE,
             rare_parts: bool | None = True, tree: BoundsTree | None = None) -> None:  # fmt: skip
    """Distance (m) from each IR ray's origin to the nearest point of a wall (convex polygons with
    bounding boxes, `Walls`) or a circle (CIRCLES; a sensor skips its own robot's, and every sensor
    a GHOST's) within the ray's cone (half-angle, rad) of its view and within `length`; inf if
    none. As `World.ray_distance`: per convex body the nearest point if it lies in the cone, else
    the first hit of an edge ray. A ray whose `pick` is set sees a wall as c't-Sim's Java3D cone
    pick does (`pick.pick_wall`; in a c't-Sim parcours, through Java3D's bounds TREE,
    `pick.pick_tree`; None: the world has none, and numba compiles no tree walk).

    With more than `grid_above` circles, each sensor checks only the circles in the grid cells
    its cone's bounding box overlaps (a crowd would otherwise cost sensors x robots); the nearest
    distance is a minimum, so the grid gives the all-circles result bit for bit. None: never (numba
    then prunes the grid's code, which need not be compiled for a world of a few circles);
    `rare_parts` None likewise where no wall is a cylinder and no ray picks (numba then compiles
    no pick: `pick.pick_wall`, `pick.pick_tree`). Walls are taken
    from the walls' grid in the cells the cone's bounding box overlaps, in ascending order as a
    loop over every wall would meet them; only a wall whose box meets the cone's can give a
    distance within `length` (every nearest point and edge-ray hit that counts lies in the cone),
    so the others are skipped without changing a bit."""
    origins, looks, cones, owner, picks = rays.origins, rays.look, rays.cone, rays.owner, rays.pick
    vertices, spans, boxes = walls.vertices, walls.spans, walls.boxes
    use_grid = grid_above is not None and circles.shape[0] > grid_above
    cell, x0, y0, cols, rows, order, sorted_key, widest = 1.0, 0.0, 0.0, 1, 1, np.empty(0, np.int64), np.empty(0, np.int64), 0.0
    if use_grid:
        cell, x0, y0, cols, rows, order, sorted_key, widest = circle_grid(circles, length)
    for k in range(origins.shape[0]):
        ox, oy = origins[k, 0], origins[k, 1]
        look, cone = looks[k], cones[k]
        cx, cy = math.cos(look), math.sin(look)
        cos_cone = math.cos(cone)
        l1x, l1y = math.cos(look - cone), math.sin(look - cone)
        l2x, l2y = math.cos(look + cone), math.sin(look + cone)
        view = (ox, oy, cx, cy, cos_cone, l1x, l1y, l2x, l2y)
        best = math.inf
        # a wall counts only where it meets the cone within `length` (inside the wall: at the apex)
        lo_x, lo_y, hi_x, hi_y = _cone_box(view, cone, length)
        if rare_parts is not None and tree is not None and picks[k] and tree.lower.shape[0] > 0:  # a c't-Sim parcours: the walls its bounds tree lets the pick reach
            best = pick_tree((ox, oy, cx, cy, length), math.tan(cone), walls, tree, rare_parts)
        else:
            for w in walls_near(lo_x, lo_y, hi_x, hi_y, walls.frame, walls.cells):
                box = boxes[w]
                if box.xmin > hi_x or box.xmax < lo_x or box.ymin > hi_y or box.ymax < lo_y:
                    continue
                start, end = spans[w].start, spans[w].end
                if rare_parts is not None and picks[k]:
                    best = min(best, pick_wall((ox, oy, cx, cy, length), math.tan(cone), vertices, start, end, box.cylinder, rare_parts))
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
                    circle = circles[order[p]]
                    if circle.owner == owner[k] or circle.owner == GHOST:
                        continue
                    best = _circle_in_view(view, circle.x, circle.y, circle.radius, best)
                    if best < 0.0:
                        inside = True
                        break
        else:
            for j in range(circles.shape[0]):
                circle = circles[j]
                if circle.owner == owner[k] or circle.owner == GHOST:
                    continue
                best = _circle_in_view(view, circle.x, circle.y, circle.radius, best)
                if best < 0.0:
                    break
        best = max(best, 0.0)  # -1: inside a circle
        out[k] = best if best <= length or picks[k] else math.inf  # a pick's rim reaches past the axis's end


@numba.njit(cache=True, **INNER)
def _cone_box(view: tuple, cone: float, length: float):
    """(xmin, ymin, xmax, ymax) holding the cone of `length` (`view`: apex, axis, edges as in
    `_circle_in_view`): the box of its apex and its arc's ends and middle, grown by the arc's
    sagitta (a cone wider than 45 degrees: the box of the whole disc)."""
    ox, oy, cx, cy, _, l1x, l1y, l2x, l2y = view
    if cone > 0.25 * math.pi:
        margin = length + 1e-9
        return ox - margin, oy - margin, ox + margin, oy + margin
    ax, bx, mx = ox + length * l1x, ox + length * l2x, ox + length * cx
    ay, by, my = oy + length * l1y, oy + length * l2y, oy + length * cy
    margin = length * (1.0 - math.cos(cone)) + 1e-9
    return min(ox, ax, bx, mx) - margin, min(oy, ay, by, my) - margin, max(ox, ax, bx, mx) + margin, max(oy, ay, by, my) + margin


@numba.njit(cache=True)
def ir_values(distance: np.ndarray, sensors: np.ndarray, noise: Noise, curves: Curves, raw: np.ndarray, believed: np.ndarray) -> None:
    """Raw value and believed distance of each IR sensor (SENSORS rows) from its true `distance` (m).

    A sensor with noise (its noise_row q >= 0) and something in view reads its distance plus
    noise.std[q] times its next standard normal (normals[q, used[q]], `used` advanced), not below
    0. The raw value is `IRCurve.lookup` on its curve c (the per-centimetre float32 table
    tables[c, :last + 1] and the value beyond it), the believed distance the curve's inverse for
    the sensor's range tabulated per raw value from its lowest one (`IRCurve.inverse_table`): the
    same arithmetic, so the same bits."""
    std, normals, used = noise.std, noise.normals, noise.used
    tables, beyond = curves.tables, curves.beyond
    for k in range(distance.shape[0]):
        d = distance[k]
        q = sensors[k].noise_row
        if q >= 0 and d < math.inf:
            d = max(0.0, d + (0.0 + std[q] * normals[q, used[q]]))  # as rng.normal(0.0, std)
            used[q] += 1
        c = sensors[k].curve
        last = curves.ends[c].last
        cm = d * 100.0
        value = np.float64(beyond[c])
        if cm >= 0.0 and cm <= last:
            i = int(math.floor(cm))
            here = tables[c, i]
            value = np.float64(here)
            if here != beyond[c] and i < last:
                value = value + (cm - i) * np.float64(tables[c, i + 1] - here)  # a float32 difference, as in Java
        r = int(math.floor(value + 0.5))
        raw[k] = r
        believed[k] = curves.inverse[c, r - curves.ends[c].lowest]


@numba.njit(cache=True, **INNER)
def read_ir(pose: np.ndarray, sensing: Sensing, walls: Walls, curves: Curves, noise: Noise, out: Readout, rare_parts: bool | None) -> None:
    """Every IR reading of a world whose robots are all circles, in one call: the IR sensors'
    rays (the last len(out.believed) of SENSING's sensors, `ir_rays`), the robots (the first of
    its circles, positions taken from `pose`) and the other circles and walls they see
    (`sense_ir`, through its bounds tree), and noise and curves (`ir_values`) into `out`'s raw
    values and believed distances. `rare_parts` None: the world has no more circles than
    CIRCLE_GRID_ABOVE, no cylinder wall and no sensor of the pick view (numba then prunes their code)."""
    sensors, circles = sensing.sensors[sensing.sensors.shape[0] - out.believed.shape[0] :], sensing.circles
    m = sensors.shape[0]
    origins, look, distance = np.empty((m, 2)), np.empty(m), np.empty(m)
    ir_rays(pose, sensors, origins, look)
    for i in range(pose.shape[0]):
        circles[i].x, circles[i].y = pose[i, 0], pose[i, 1]
    rays = Rays(origins, look, sensors.opening, sensors.owner, sensors.pick)
    if rare_parts is None:
        sense_ir(rays, walls, circles, curves.length, distance, None, None, sensing.tree)
    else:
        sense_ir(rays, walls, circles, curves.length, distance, CIRCLE_GRID_ABOVE, True, sensing.tree)
    ir_values(distance, sensors, noise, curves, out.values, out.believed)


@numba.njit(cache=True, **INNER)
def sense_light(pose: np.ndarray, sensors: np.ndarray, lights: np.ndarray, tree: BoundsTree | None, out: np.ndarray,
                picking: bool | None = True) -> None:  # fmt: skip
    """LDR darkness (0..1023) of light SENSORS, `height` m up, looking horizontally along their
    body-frame `direction` (rad): the distance from the sensor to the surface of the nearest of
    the LIGHTS whose centre is within the sensor's half opening of the view axis in 3-D, over its
    `reach`, truncated; 1023 with none (c't-Sim `World.sensLight`). A sensor whose `pick` is set
    measures to what c't-Sim's Java3D pick finds on the lamps' mesh (`light_pick.pick_lamps`,
    through the TREE of a c't-Sim parcours; None in other worlds); `picking` None: none does (numba
    then compiles no pick)."""
    owner = sensors.owner
    points = np.empty((sensors.shape[0], 2))
    to_world(pose, sensors.at, owner, points)
    for k in range(points.shape[0]):
        sensor = sensors[k]
        nearest = math.inf
        look = pose[owner[k], 2] + sensor.direction
        cx, cy = math.cos(look), math.sin(look)
        cos_limit = math.cos(sensor.opening)
        if picking is not None and sensor.pick:
            at, u = np.array((points[k, 0], points[k, 1], sensor.height)), np.array((cx, cy, 0.0))  # (here: a world without picks allocates none)
            nearest = pick_lamps(at, u, math.tan(sensor.opening), lights, tree)
        else:
            for j in range(lights.shape[0]):
                lamp = lights[j]
                ox, oy, oz = lamp.x - points[k, 0], lamp.y - points[k, 1], lamp.height - sensor.height
                centre = math.sqrt(ox * ox + oy * oy + oz * oz)
                if ox * cx + oy * cy >= cos_limit * centre - 1e-12:
                    nearest = min(nearest, max(centre - lamp.radius, 0.0))
        out[k] = int(math.floor(min(nearest / sensor.reach, 1.0) * 1023))


@numba.njit(cache=True)
def read_sensors(pose: np.ndarray, sensing: Sensing, floor: Floor, walls: Walls, curves: Curves, noise: Noise, rare_parts: bool | None,
                 out: Readout) -> None:  # fmt: skip
    """Every floor, light and IR reading of the world in one call: the first `sensing.floor`
    SENSORS rows are floor sensors (`sample_floor`), the last len(out.believed) IR sensors
    (`read_ir`), the rows between light sensors (`sense_light`); `out.values` gets each row's
    integer reading. A world that reads its IR sensors with pymunk passes only the floor and
    light rows and no `believed`. `rare_parts`: as `read_ir`'s."""
    sensors, values, believed = sensing.sensors, out.values, out.believed
    lo, hi = sensing.floor, sensors.shape[0] - believed.shape[0]
    sample_floor(pose, sensors[:lo], floor, values[:lo])
    move_robot_leaves(sensing.tree, pose)  # (c't-Sim's bots in its scene's bounds tree, which its picks walk)
    sense_light(pose, sensors[lo:hi], sensing.lights, sensing.tree, values[lo:hi], rare_parts)
    if believed.shape[0]:
        read_ir(pose, sensing, walls, curves, noise, Readout(values[hi:], believed), rare_parts)
