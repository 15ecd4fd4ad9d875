"""What c't-Sim's light sensors see of its lamps: Java3D's cone-ray pick of the lamp spheres' mesh.

c't-Sim (`World.sensLight`) picks its lamps' group with a `PickConeRay` of 90° half-angle from the
sensor along its heading and reads the pick's closest distance over 1 m as darkness (0..1023,
truncated). Read in hharrison/java3d-core and hharrison/java3d-utils, and measured against the
real c't-Sim with its own `sensLight`:

- a lamp is Java3D's `Sphere` of 7 cm: triangle strips of 16 divisions round its axis, which
  lies along the world's y (c't-Sim only moves the sphere), in single precision (`LAMP_MESH`);
- a lamp whose centre lies behind the sensor is not picked (the cone's bounds test measures from
  the ray's start there, where its radius is 0);
- of each triangle, the first edge (in vertex order) whose closest approach to the ray lies within
  the cone counts, keyed by the distance along the ray to that approach, and found at the edge's
  point of it; a 90° cone takes any edge ahead. The closest approach is Java3D's own
  (`Utils.rayToSegment`): an edge within 1e-5 of parallel to the ray (|u x e|² < 1e-5, with e
  the edge's vector) counts from its start or end point as its direction runs, and where the
  nearest point lies past the edge's end the ray's point is the one nearest the edge's start;
- of a lamp the triangle of the smallest key gives its find, and the sensor reads the distance to
  the nearest find of all lamps;
- in a c't-Sim parcours the pick walks Java3D's bounds tree first (`pick_lamps`,
  `sim.world.bounds_tree`): a lamp in a node whose box's centre lies behind the sensor, and the
  sensor outside the sphere round that box, is not seen.

ctsim's own light sensors (view 'surface') measure to the sphere's surface instead.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.world.kernels.pick import leaves_met
from sim.world.layout import BoundsTree
from sim.world.spec import JAVA3D_FLOOR

LAMP_RADIUS = 0.07
"""m: c't-Sim's lamp sphere (ParcoursLoader.createLight)."""
PARALLEL = 1e-5
"""Java3D's tolerance below which a ray and an edge count as parallel (|u|²|e|² - (u.e)²)."""


def sphere_strips(radius: float, divisions: int = 16) -> np.ndarray:
    """The triangles (n, 3, 3; float32 corners, m) of Java3D's `Sphere` of `radius` with
    `divisions` round its axis (a multiple of 4: Java3D rounds up its default 15 to 16), in
    the order its pick meets them: for each quarter round the axis (local y) the upper half, then
    the lower, each of strips from the pole outwards, every strip's triangles its runs of three."""
    f = np.float32
    radius = float(f(radius))  # (Java3D's Sphere takes a float)
    steps = divisions // 4
    points: list[tuple[float, float, float]] = []
    strips: list[tuple[int, int]] = []
    for quarter in range(4):
        start, end = quarter * math.pi / 2, (quarter + 1) * math.pi / 2
        for upper in (True, False):
            turn = math.pi / (2 * steps) * (1 if upper else -1)
            theta = turn if upper else math.pi + turn
            pole = (0.0, float(f(radius if upper else -radius)), 0.0)
            for row in range(1, steps + 1):
                height, ring = math.cos(theta), math.sin(theta)
                first = len(points)
                step = (end - start) / row
                corners = [start + j * step for j in range(row)] if upper else [end - j * step for j in range(row)]
                for angle in corners:
                    points.append(tuple(float(f(v * radius)) for v in (ring * math.cos(angle), height, ring * math.sin(angle))))
                    points.append(points[len(points) - 2 * row] if row > 1 else pole)  # the row before's corner, or the pole
                last = end if upper else start
                points.append(tuple(float(f(v * radius)) for v in (ring * math.cos(last), height, ring * math.sin(last))))
                strips.append((first, len(points)))
                theta = theta + turn if row < steps else math.pi / 2
    return np.array([points[k : k + 3] for a, b in strips for k in range(a, b - 2)], dtype=np.float64)


LAMP_MESH = sphere_strips(LAMP_RADIUS)
"""c't-Sim's lamp sphere as Java3D's pick meets it: (triangles, corner, x y z) about its centre, m,
in the world's axes (the sphere's own y is the world's y)."""


@numba.njit(cache=True)
def _ray_to_edge(o: np.ndarray, u: np.ndarray, p: np.ndarray, q: np.ndarray) -> tuple[float, float, float, float, float]:
    """Java3D's closest approach of the ray o + s u (s >= 0) to the edge p-q, with its quirks
    (module doc): (squared distance, s, the edge's point x, y, z)."""
    dx, dy, dz = o[0] - p[0], o[1] - p[1], o[2] - p[2]
    ex, ey, ez = q[0] - p[0], q[1] - p[1], q[2] - p[2]
    a = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
    b = -(u[0] * ex + u[1] * ey + u[2] * ez)
    c = ex * ex + ey * ey + ez * ez
    d = u[0] * dx + u[1] * dy + u[2] * dz
    e = -(ex * dx + ey * dy + ez * dz)
    det = abs(a * c - b * b)
    from_ray = 0.0 if d >= 0.0 else -d / a  # the ray's point nearest the edge's start
    on_edge = 0.0 if e >= 0.0 else (1.0 if -e >= c else -e / c)  # the edge's point nearest the ray's start
    if det < PARALLEL:
        if b > 0.0:  # the edge runs against the ray: its start
            s, t = from_ray, 0.0
        else:
            s, t = (0.0 if b + d >= 0.0 else -(b + d) / a), 1.0
    else:
        s, t = b * e - c * d, b * d - a * e
        if s >= 0.0 and 0.0 <= t <= det:
            s, t = s * (1.0 / det), t * (1.0 / det)
        elif s >= 0.0:
            s, t = from_ray, (1.0 if t > det else 0.0)
        elif t <= 0.0:
            s, t = (from_ray, 0.0) if d < 0.0 else (0.0, on_edge)
        elif t <= det or b + d >= 0.0:
            s, t = 0.0, on_edge
        else:
            s, t = -(b + d) / a, 1.0
    x, y, z = p[0] + t * ex, p[1] + t * ey, p[2] + t * ez
    gx, gy, gz = o[0] + s * u[0] - x, o[1] + s * u[1] - y, o[2] + s * u[2] - z
    return gx * gx + gy * gy + gz * gz, s, x, y, z


@numba.njit(cache=True)
def pick_lamp(at: np.ndarray, look: np.ndarray, tan_spread: float, centre: np.ndarray, mesh: np.ndarray) -> float:
    """Distance (m) c't-Sim's light pick reads from AT along the horizontal unit vector LOOK with a
    cone of half-angle atan(tan_spread) of the lamp sphere MESH (`LAMP_MESH`) at CENTRE (x, y,
    height; see the module doc); inf if it sees none of it. Computed in the sphere's own frame as
    Java3D computes it, to its roundings: of triangles whose keys differ in the last bits the
    first one's find is c't-Sim's."""
    if (centre[0] - at[0]) * look[0] + (centre[1] - at[1]) * look[1] + (centre[2] - at[2]) * look[2] <= 0.0:
        return math.inf  # its centre behind: the bounds test fails
    # the ray in the sphere's frame (Java3D's world moves the floor 2 m down; the sphere only moved)
    lift = JAVA3D_FLOOR + centre[2]
    o = np.array((at[0] - centre[0], at[1] - centre[1], (at[2] + JAVA3D_FLOOR) - lift))
    u = np.array(((at[0] + look[0]) - centre[0] - o[0], (at[1] + look[1]) - centre[1] - o[1], ((at[2] + JAVA3D_FLOOR) + look[2]) - lift - o[2]))
    scale = 1.0 / math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    u[0], u[1], u[2] = u[0] * scale, u[1] * scale, u[2] * scale
    key, fx, fy, fz = math.inf, 0.0, 0.0, 0.0
    for k in range(mesh.shape[0]):
        for i in range(3):
            squared, s, x, y, z = _ray_to_edge(o, u, mesh[k, i], mesh[k, (i + 1) % 3])
            rx, ry, rz = s * u[0] + o[0] - o[0], s * u[1] + o[1] - o[1], s * u[2] + o[2] - o[2]
            along = math.sqrt(rx * rx + ry * ry + rz * rz)
            if squared <= (tan_spread * along) ** 2:
                if along < key:
                    key, fx, fy, fz = along, x, y, z
                break
    if key == math.inf:
        return math.inf
    gx, gy, gz = fx + centre[0] - at[0], fy + centre[1] - at[1], (fz + lift) - (at[2] + JAVA3D_FLOOR)
    return math.sqrt(gx * gx + gy * gy + gz * gz)


REACH = 100.0
"""m: the length of segment that stands for the pick's unbounded ray in the bounds tree's test."""


@numba.njit(cache=True)
def pick_lamps(at: np.ndarray, look: np.ndarray, tan_spread: float, lights: np.ndarray, tree: BoundsTree | None) -> float:
    """Distance (m) c't-Sim's light pick reads from AT along LOOK of the nearest of the LIGHTS
    (`layout.LIGHTS`, each `pick_lamp`), those Java3D's bounds TREE lets it reach where the world
    has one (None: it has none); inf if it sees none. The lamps are taken nearest first, and one
    whose sphere lies wholly beyond the nearest find so far is skipped (every find lies on its
    sphere's mesh)."""
    reached = np.zeros(lights.shape[0], np.bool_)
    if tree is None or tree.lower.shape[0] == 0:
        reached[:] = True
    else:
        o = np.array((at[0], at[1], at[2] + JAVA3D_FLOOR))
        d = np.array((REACH * look[0], REACH * look[1], REACH * look[2]))
        for node in leaves_met(o, d, tan_spread, tree):
            if tree.lamp[node] >= 0:
                reached[tree.lamp[node]] = True
    gap = np.empty(lights.shape[0])
    for j in range(lights.shape[0]):
        gap[j] = math.sqrt((lights[j].x - at[0]) ** 2 + (lights[j].y - at[1]) ** 2 + (lights[j].height - at[2]) ** 2)
    best = math.inf
    centre = np.empty(3)
    for j in np.argsort(gap):
        if not reached[j] or gap[j] - 1.001 * LAMP_RADIUS > best:
            continue
        centre[0], centre[1], centre[2] = lights[j].x, lights[j].y, lights[j].height
        best = min(best, pick_lamp(at, look, tan_spread, centre, LAMP_MESH))
    return best
