"""What c't-Sim's IR sensors see of a wall: Java3D's cone pick (`PickConeSegment`) on its wall boxes.

c't-Sim (`World.watchObstacle`) picks the closest geometry its obstacle group has in a cone of 3°
half-angle along a segment of 0.85 m from the sensor. Its walls are Java3D `Box` primitives from
the floor to 0.4 m up, each vertical face a strip of two triangles split by a diagonal, and
Java3D tests a triangle against a cone segment this way (its `intersectCone`, read in
hharrison/java3d-core, and measured against the real c't-Sim with its own `watchObstacle`):

- if the cone's axis pierces the triangle, the triangle's key is the distance to the piercing
  point, and that point its find;
- otherwise the first of its edges, in vertex order, whose closest approach to the axis lies
  within the cone's radius there gives the key (the distance along the axis to that approach)
  and its find (the edge's point of that approach);
- of a face's two triangles the smaller key wins, and the face reads the distance from the sensor
  to that find; the pick reads the nearest face. (Java3D's source keys a piercing by its axis
  parameter, 0..1; the real c't-Sim's readings fit the distance.)

So a corner is seen within the full cone, a face where the axis meets it or, near the face's
diagonal, at the diagonal's nearest point, and a sensor inside a wall sees the face it looks out
through. The IR sensors sit at the bot's centre, 75 mm up. The vertex order of a face follows
Java3D's Box: for a wall polygon's edge k (counter-clockwise from its lowest-left corner, as
`sim.world.spec.box` gives it) an even edge's diagonal rises from its start to its end and its
first triangle tests the start's vertical edge before the diagonal; an odd edge's diagonal falls
(`FACES`).

c't-Sim's lamp pillars are Java3D cylinders (`pick_cylinder`): one shape whose side is a single
triangle strip round the 15 corners, top and bottom corner of each in turn from due north counter-
clockwise back to north (Java3D's `Quadrics.cylinder` and `GeomBuffer`, read in
hharrison/java3d-utils), each triangle tested as above and the strip's smallest key, the first of
equal ones, giving its find; 0.5 m tall, so the cone never reaches its caps.

Before a shape's triangles, Java3D tests its bounding box (`_cone_meets_bounds`: each face of a
Box is a shape of its own, a pillar's side one): a face the cone grazes without its corners or the
axis ray meeting its bounds is not seen at all. In a c't-Sim parcours it tests the same on the
boxes of its bounds tree above the shapes first (`pick_tree`, `sim.world.bounds_tree`: the whole
scene, bots included), which skips a few more such faces; cans (movable, not walls) are seen by
ctsim's own cone rule.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.world.kernels.contacts import CTBOT_PARTS
from sim.world.layout import BoundsTree, Walls
from sim.world.spec import JAVA3D_FLOOR

WALL_BOTTOM, WALL_TOP = 0.0, 0.4
"""m: c't-Sim's wall boxes stand on the floor and are 0.4 m tall (ParcoursLoader's 0.2 m half-height)."""
SENSOR_HEIGHT = 0.075
"""m: c't-Sim's IR sensors lie in the plane of the bot's centre, 75 mm over the floor."""
CYLINDER_TOP = 0.5
"""m: c't-Sim's lamp pillar stands 0.5 m tall on the floor (ParcoursLoader's LIGHTZ)."""
TIE = 1e-12
"""m: keys this close are equal, which happens where an axis meets a face square on beside its
diagonal; the real c't-Sim then reads the diagonal on a face whose diagonal rises and the first
triangle's find on one whose diagonal falls (measured: Java's roundings decide there)."""


@numba.njit(cache=True)
def _closest(o: tuple[float, float, float], d: tuple[float, float, float], p: tuple[float, float, float], q: tuple[float, float, float]) -> tuple:
    """Closest points of the segment o + s d (0 <= s <= 1) and the segment p-q (points and
    direction as (x, y, z)): (squared distance, distance from o along d to the first, the second's
    x, y, z)."""
    (ox, oy, oz), (dx, dy, dz), (px, py, pz), (qx, qy, qz) = o, d, p, q
    ex, ey, ez = qx - px, qy - py, qz - pz
    rx, ry, rz = ox - px, oy - py, oz - pz
    a, c, b = dx * dx + dy * dy + dz * dz, ex * ex + ey * ey + ez * ez, dx * ex + dy * ey + dz * ez
    f, g = dx * rx + dy * ry + dz * rz, ex * rx + ey * ry + ez * rz
    den = a * c - b * b
    s = min(max((b * g - f * c) / den, 0.0), 1.0) if den > 1e-15 * a * c else 0.0
    t = (b * s + g) / c if c > 0.0 else 0.0  # (a point: a flat box's upright edge)
    if t < 0.0:
        t, s = 0.0, min(max(-f / a, 0.0), 1.0)
    elif t > 1.0:
        t, s = 1.0, min(max((b - f) / a, 0.0), 1.0)
    x, y, z = px + t * ex, py + t * ey, pz + t * ez
    gx, gy, gz = ox + s * dx - x, oy + s * dy - y, oz + s * dz - z
    return gx * gx + gy * gy + gz * gz, s * math.sqrt(a), x, y, z


@numba.njit(cache=True)
def _triangle(o: np.ndarray, d: np.ndarray, tan_spread: float, v: np.ndarray, edge_bonus: float) -> tuple[float, float, float, float]:
    """Java3D's cone test of the triangle v (3, 3) against the segment o + s d: (key, point x, y,
    z), key inf if missed; an edge's key less `edge_bonus`."""
    ux, uy, uz = v[1, 0] - v[0, 0], v[1, 1] - v[0, 1], v[1, 2] - v[0, 2]
    wx, wy, wz = v[2, 0] - v[0, 0], v[2, 1] - v[0, 1], v[2, 2] - v[0, 2]
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    across = nx * d[0] + ny * d[1] + nz * d[2]
    if across != 0.0:
        s = (nx * (v[0, 0] - o[0]) + ny * (v[0, 1] - o[1]) + nz * (v[0, 2] - o[2])) / across
        if 0.0 <= s <= 1.0:
            hx, hy, hz = o[0] + s * d[0], o[1] + s * d[1], o[2] + s * d[2]
            sides = 0
            for k in range(3):
                j = (k + 1) % 3
                ex, ey, ez = v[j, 0] - v[k, 0], v[j, 1] - v[k, 1], v[j, 2] - v[k, 2]
                px, py, pz = hx - v[k, 0], hy - v[k, 1], hz - v[k, 2]
                turn = (ey * pz - ez * py) * nx + (ez * px - ex * pz) * ny + (ex * py - ey * px) * nz
                sides |= 1 if turn > 0.0 else (2 if turn < 0.0 else 0)
            if sides != 3:
                return s * math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), hx, hy, hz
    for k in range(3):
        j = (k + 1) % 3
        squared, along, x, y, z = _closest((o[0], o[1], o[2]), (d[0], d[1], d[2]), (v[k, 0], v[k, 1], v[k, 2]), (v[j, 0], v[j, 1], v[j, 2]))
        if squared <= (tan_spread * along) ** 2:
            return along - edge_bonus, x, y, z
    return math.inf, 0.0, 0.0, 0.0


@numba.njit(cache=True)
def _ray_meets_box(o: np.ndarray, d: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> bool:
    """Whether the ray from o along d (unbounded beyond the segment) meets the box lower-upper:
    slabs in Java3D's order and roundings (its `BoundingBox.intersect(origin, direction, position)`)."""
    norm = 1.0 / math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    near, far = -math.inf, math.inf
    for c in range(3):
        unit = d[c] * norm
        if unit == 0.0:
            if o[c] < lower[c] or o[c] > upper[c]:
                return False
            continue
        t1, t2 = (lower[c] - o[c]) * (1.0 / unit), (upper[c] - o[c]) * (1.0 / unit)
        if t1 > t2:
            t1, t2 = t2, t1
        near, far = max(near, t1), min(far, t2)
        if far < 0.0 or near > far:
            return False
    return True


@numba.njit(cache=True)
def _cone_meets_bounds(o: np.ndarray, d: np.ndarray, tan_spread: float, lower: np.ndarray, upper: np.ndarray) -> bool:
    """Java3D's test of a cone segment against a shape's bounding box, which its pick makes before
    it tests the shape's triangles (`PickConeSegment.intersect(Bounds)`): the box's centre near the
    axis, the unbounded axis ray through the box, or one of the box's edges within the cone.
    A face the cone grazes with none of these (the axis beside the face's plane, the cone reaching
    the face between its ends) is not tested at all: c't-Sim sees nothing of it."""
    # (in scalars: numba's array expressions cost this kernel seconds of every first run's compile,
    # and an allocation each a call)
    seg = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    widest = tan_spread * math.sqrt(seg)
    if upper[2] < o[2] - widest or lower[2] > o[2] + widest:
        return False  # wholly above or below the cone (a level cone: floor, lamps, a wall's top)
    cx, cy, cz = 0.5 * (lower[0] + upper[0]), 0.5 * (lower[1] + upper[1]), 0.5 * (lower[2] + upper[2])
    along = (cx - o[0]) * d[0] + (cy - o[1]) * d[1] + (cz - o[2]) * d[2]
    s = 0.0 if along <= 0.0 else (1.0 if along >= seg else along / seg)
    gx, gy, gz = cx - (o[0] + s * d[0]), cy - (o[1] + s * d[1]), cz - (o[2] + s * d[2])
    squared = gx * gx + gy * gy + gz * gz
    radius = tan_spread * s * math.sqrt(seg)
    reach = (cx - lower[0] + radius) ** 2 + (cy - lower[1] + radius) ** 2 + (cz - lower[2] + radius) ** 2
    if squared > reach:
        return False
    if squared < radius * radius or _ray_meets_box(o, d, lower, upper):
        return True
    for corner in range(4):  # its 4 upright edges (the 8 level ones of a box the cone reaches lie too far above or below it to count)
        x = upper[0] if corner & 1 else lower[0]
        y = upper[1] if corner & 2 else lower[1]
        squared, along, _, _, _ = _closest((o[0], o[1], o[2]), (d[0], d[1], d[2]), (x, y, lower[2]), (x, y, upper[2]))
        if squared <= (tan_spread * along) ** 2:
            return True
    return False


@numba.njit(cache=True)
def pick_polygon(ray: tuple[float, float, float, float, float], tan_spread: float, vertices: np.ndarray, start: int, end: int) -> float:
    """Distance (m) c't-Sim's pick reads along RAY (sensor x, y, unit look x, y, length) of the
    wall polygon vertices[start:end] (see the module doc); inf if it sees none of it."""
    ox, oy, ux, uy, length = ray
    o = np.array((ox, oy, SENSOR_HEIGHT))
    d = np.array((length * ux, length * uy, 0.0))
    best = math.inf
    scratch = np.empty((7, 3))
    lower, upper = np.array((0.0, 0.0, WALL_BOTTOM)), np.array((0.0, 0.0, WALL_TOP))
    for k in range(start, end):
        nxt = k + 1 if k + 1 < end else start
        lower[0], lower[1] = min(vertices[k, 0], vertices[nxt, 0]), min(vertices[k, 1], vertices[nxt, 1])
        upper[0], upper[1] = max(vertices[k, 0], vertices[nxt, 0]), max(vertices[k, 1], vertices[nxt, 1])
        if _cone_meets_bounds(o, d, tan_spread, lower, upper):  # (each face of a Java3D Box is a shape of its own, with its own bounds)
            best = min(best, _face(o, d, tan_spread, vertices, start, end, k, scratch))
    return best


@numba.njit(cache=True)
def _face(o: np.ndarray, d: np.ndarray, tan_spread: float, vertices: np.ndarray, start: int, end: int, k: int, scratch: np.ndarray) -> float:
    """Distance (m) c't-Sim's pick reads along the cone segment o + s d (sensor at SENSOR_HEIGHT)
    of the upright face over edge k of the wall polygon vertices[start:end], its bounds test
    passed (see the module doc); inf if it sees none of it. SCRATCH (7, 3): a triangle, then the
    face's corners."""
    tri, corner = scratch[:3], scratch[3:]
    nxt = k + 1 if k + 1 < end else start
    for c, (v, z) in enumerate(((k, WALL_BOTTOM), (k, WALL_TOP), (nxt, WALL_BOTTOM), (nxt, WALL_TOP))):
        corner[c, 0], corner[c, 1], corner[c, 2] = vertices[v, 0], vertices[v, 1], z  # 0 start bottom, 1 start top, 2 end bottom, 3 end top
    side = (k - start) % 4
    rising = side % 2 == 0
    order = FACES[side]
    key, px, py, pz = math.inf, 0.0, 0.0, 0.0
    for t in range(2):
        for j in range(3):
            for c in range(3):  # (element by element: a row assignment compiles numba's whole shape-mismatch message)
                tri[j, c] = corner[order[t, j], c]
        found, x, y, z = _triangle(o, d, tan_spread, tri, TIE if rising else 0.0)
        if found < key - (0.0 if rising else TIE):
            key, px, py, pz = found, x, y, z
    if key == math.inf:
        return math.inf
    return math.sqrt((px - o[0]) ** 2 + (py - o[1]) ** 2 + (pz - o[2]) ** 2)


@numba.njit(cache=True)
def pick_cylinder(ray: tuple[float, float, float, float, float], tan_spread: float, vertices: np.ndarray, start: int, end: int) -> float:
    """Distance (m) c't-Sim's pick reads along RAY (sensor x, y, unit look x, y, length) of the
    Java3D cylinder whose corners are vertices[start:end], counter-clockwise with due north last
    (`sim.world.files.grid`): its side's triangle strip from north round to north (see the module
    doc); inf if it sees none of it."""
    ox, oy, ux, uy, length = ray
    o = np.array((ox, oy, SENSOR_HEIGHT))
    d = np.array((length * ux, length * uy, 0.0))
    corners = end - start
    strip = np.empty((2 * corners + 2, 3))
    for i in range(corners + 1):  # (element by element: a row assignment compiles numba's whole shape-mismatch message, seconds)
        k = end - 1 if i == 0 else start + i - 1
        strip[2 * i, 0], strip[2 * i, 1], strip[2 * i, 2] = vertices[k, 0], vertices[k, 1], CYLINDER_TOP
        strip[2 * i + 1, 0], strip[2 * i + 1, 1], strip[2 * i + 1, 2] = vertices[k, 0], vertices[k, 1], 0.0
    lower = np.array((vertices[start:end, 0].min(), vertices[start:end, 1].min(), 0.0))
    upper = np.array((vertices[start:end, 0].max(), vertices[start:end, 1].max(), CYLINDER_TOP))
    if not _cone_meets_bounds(o, d, tan_spread, lower, upper):
        return math.inf
    key, px, py, pz = math.inf, 0.0, 0.0, 0.0
    for t in range(strip.shape[0] - 2):
        found, x, y, z = _triangle(o, d, tan_spread, strip[t : t + 3], 0.0)
        if found < key:
            key, px, py, pz = found, x, y, z
    if key == math.inf:
        return math.inf
    return math.sqrt((px - ox) ** 2 + (py - oy) ** 2 + (pz - SENSOR_HEIGHT) ** 2)


@numba.njit(cache=True)
def pick_wall(ray: tuple[float, float, float, float, float], tan_spread: float, vertices: np.ndarray, start: int, end: int, cylinder: bool,
              cylinders: bool | None = True) -> float:  # fmt: skip
    """Distance (m) c't-Sim's pick reads along RAY (sensor x, y, unit look x, y, length) of the
    wall vertices[start:end]: a Java3D cylinder's (`pick_cylinder`) or a box's (`pick_polygon`);
    inf if it sees none of it. `cylinders` None: the world has no cylinder (numba then prunes
    `pick_cylinder`, which need not be compiled)."""
    if cylinders is not None and cylinder:
        return pick_cylinder(ray, tan_spread, vertices, start, end)
    return pick_polygon(ray, tan_spread, vertices, start, end)


FACES = np.array((
    ((1, 0, 3), (0, 3, 2)),  # bottom (y = min): its diagonal rises from the edge's start to its end
    ((0, 2, 1), (2, 1, 3)),  # right (x = max): falls
    ((1, 0, 3), (0, 3, 2)),  # top: rises
    ((3, 1, 2), (1, 2, 0)),  # left: falls
))
"""Java3D Box's faces as the two triangles of their strips, in its vertex order (corner indices as
in `pick_polygon`), by the polygon edge's place counter-clockwise from the lowest-left corner."""


@numba.njit(cache=True)
def leaves_met(o: np.ndarray, d: np.ndarray, tan_spread: float, tree: BoundsTree) -> np.ndarray:
    """The bounds tree's leaves the cone (apex `o`, axis `d` in Java3D's world) reaches, in
    Java3D's order: from the root, a node's children only where the cone meets its box
    (`_cone_meets_bounds`), the right child first."""
    leaves = np.empty(tree.lower.shape[0], np.int64)
    found = 0
    stack = np.empty(2 * tree.lower.shape[0] + 1, np.int64)  # (at most every node once)
    stack[0], top = 0, 1
    while top > 0 and tree.lower.shape[0] > 0:
        top -= 1
        node = stack[top]
        if not _cone_meets_bounds(o, d, tan_spread, tree.lower[node], tree.upper[node]):
            continue
        if tree.kids[node, 0] >= 0:
            stack[top], stack[top + 1] = tree.kids[node, 1], tree.kids[node, 0]  # the right child on top: visited first
            top += 2
        else:
            leaves[found] = node
            found += 1
    return leaves[:found]


@numba.njit(cache=True)
def pick_tree(ray: tuple[float, float, float, float, float], tan_spread: float, walls: Walls, tree: BoundsTree, cylinders: bool | None = True) -> float:
    """Distance (m) c't-Sim's pick reads along RAY (sensor x, y, unit look x, y, length) of the
    walls of a c't-Sim parcours: Java3D's walk of its bounds TREE (`BHTree.doSelect`: a node's
    children only if the cone meets its box, right child first), each wall face or pillar side
    whose own box the cone meets picked (`pick_polygon`'s rule for one face, `pick_cylinder`); inf if it sees none."""
    ox, oy, ux, uy, length = ray
    o = np.array((ox, oy, SENSOR_HEIGHT + JAVA3D_FLOOR))  # in Java3D's world, the floor 2 m down
    at = np.array((ox, oy, SENSOR_HEIGHT))  # in ctsim's, as the faces are
    d = np.array((length * ux, length * uy, 0.0))
    scratch = np.empty((7, 3))
    best = math.inf
    for node in leaves_met(o, d, tan_spread, tree):
        wall = tree.wall[node]
        if wall < 0:
            continue
        start, end = walls.spans[wall].start, walls.spans[wall].end
        if cylinders is not None and walls.boxes[wall].cylinder:
            best = min(best, pick_cylinder(ray, tan_spread, walls.vertices, start, end))
        else:
            best = min(best, _face(at, d, tan_spread, walls.vertices, start, end, tree.face[node], scratch))
    return best


CTBOT_SHAPES = CTBOT_PARTS[[1, 0, 2]].reshape(-1, 2, 2)
"""c't-Sim's CtBotShape's three shapes in the order they go live (right cheek, left cheek, the
middle: `kernels.contacts.CTBOT_PARTS`), each its (forward, left) lower and upper corner (m)."""
CTBOT_BOTTOM, CTBOT_TOP = JAVA3D_FLOOR + 0.075 - 0.06, JAVA3D_FLOOR + 0.075 + 0.06
"""m: the z range of c't-Sim's bot shapes in Java3D's world (120 mm tall round its centre 75 mm up: World.addBot, CtBotShape)."""


@numba.njit(cache=True)
def robot_boxes(x: float, y: float, heading: float, shapes: np.ndarray, bottom: float, top: float, lower: np.ndarray, upper: np.ndarray) -> None:
    """Java3D's bounds of a bot's shapes at pose (x, y m, heading rad): each shape's box (SHAPES
    (k, 2, 2): body-frame x, y lower and upper) turned with the bot, its corners' bounds
    (`BoundingBox.transform`), z from `bottom` to `top`, into LOWER and UPPER (k, 3)."""
    c, s = math.cos(heading), math.sin(heading)
    for k in range(shapes.shape[0]):
        lower[k, 0], lower[k, 1], upper[k, 0], upper[k, 1] = math.inf, math.inf, -math.inf, -math.inf
        for corner in range(4):
            bx, by = shapes[k, corner & 1, 0], shapes[k, corner >> 1, 1]
            wx, wy = x + c * bx - s * by, y + s * bx + c * by
            lower[k, 0], lower[k, 1] = min(lower[k, 0], wx), min(lower[k, 1], wy)
            upper[k, 0], upper[k, 1] = max(upper[k, 0], wx), max(upper[k, 1], wy)
        lower[k, 2], upper[k, 2] = bottom, top


@numba.njit(cache=True)
def move_robot_leaves(tree: BoundsTree | None, pose: np.ndarray) -> None:
    """The bots' leaves of the bounds tree to their robots' poses (robots, 3; `CTBOT_SHAPES`), and
    every box above them to its children's again, as Java3D updates its tree when a bot moves.
    None: the world has no tree (numba then compiles nothing else)."""
    if tree is None:
        return
    lower, upper = np.empty((CTBOT_SHAPES.shape[0], 3)), np.empty((CTBOT_SHAPES.shape[0], 3))
    for r in range(tree.robot_leaves.shape[0]):
        if tree.robot_leaves[r, 0] < 0:
            continue
        robot_boxes(pose[r, 0], pose[r, 1], pose[r, 2], CTBOT_SHAPES, CTBOT_BOTTOM, CTBOT_TOP, lower, upper)
        for k in range(CTBOT_SHAPES.shape[0]):
            node = tree.robot_leaves[r, k]
            for c in range(3):
                tree.lower[node, c], tree.upper[node, c] = lower[k, c], upper[k, c]
            node = tree.parent[node]
            while node >= 0:
                right, left = tree.kids[node, 0], tree.kids[node, 1]
                for c in range(3):
                    tree.lower[node, c] = min(tree.lower[right, c], tree.lower[left, c])
                    tree.upper[node, c] = max(tree.upper[right, c], tree.upper[left, c])
                node = tree.parent[node]
