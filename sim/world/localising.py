"""What a map-aided localiser may ask of the world's map (a prior the robot carries, never the
true state): how likely one scan of the robot's IR sensors is at each of many poses, and poses
drawn at random where the robot could stand.

The expected distances are cast against the map's walls by the world's own compiled kernel
(`kernels.sensing.sense_ir`, with each sensor's cone and view), so a particle at the true pose expects
exactly what the world measured before its noise. The likelihood of a raw value r given an
expected distance d is that of the world's noise model: the reading is d + N(0, sigma²) looked up
on the sensor's curve and rounded, so P(r | d) is the Gaussian's mass over the distances that
round to r (`raw_intervals`, found once per curve on a fine grid: the curve folds back below
9 cm and wiggles near its end, so a raw value may come from several intervals). Nothing within
the ray's length reads the curve's `beyond` value for sure. Other robots and cans are not on the
map: a floor `OUTLIER` keeps a reading of one from wiping out every particle.
"""

from __future__ import annotations

import math
import os
import threading

import numba
import numpy as np

from bots.ir_curve import IRCurve, ir_curve_for
from bots.spec import RobotSpec
from sim.world.kernels.contacts import clear_of_walls
from sim.world.kernels.sensing import sense_ir
from sim.world.layout import CIRCLES, SENSORS, Rays, ScanModel, Walls
from sim.world.spec import WorldSpec
from sim.world.tables import IR_RAY_LENGTH, walls_of

GRID_STEP = 0.00002
"""Distance step (m) of the grid on which each raw value's intervals are found: where the curve is
steepest (8 raw units a millimetre, on its fold-back below 9 cm) a step moves it by a sixth of a unit."""
GRID_END = 1.0
"""Where the grid ends (m): beyond every shipped curve's last row, so its last run is `beyond`."""
MODEL_STD = 0.004
"""Standard deviation (m) added to a sensor's own noise: the spread of the particles within one
update (a particle a few millimetres off sees a wall a few millimetres off) and the noise-free
sensors of `--noise none`, whose exact likelihood is a step no particle would sit on."""
OUTLIER = 0.01
"""Probability mass of a reading the map does not explain (another robot, a can), spread evenly
over the sensor's raw values."""
INTERVALS = 4
"""Most distance intervals one raw value comes from on any shipped curve (2 on the GP2D12's)."""
CLEARANCE = 0.01
"""How far (m) a particle's body may reach into a wall before the map rules it out: the contact
solver lets a body sink a millimetre, and the belief is a few millimetres off."""
SHARED_FROM = 2000
"""Particles from which `MapScan.likelihood` shares a scan among threads, one per core that is
free (numba's thread count, one per core or NUMBA_NUM_THREADS, less the load average beyond this
process: a sweep's processes already fill the cores, and a thread on a busy core made the scan
slower); the kernel releases the GIL and each thread takes a slice of the particles, so the result
is the same to the bit. A search's thousands of particles over hundreds of scans stall `ctsim
play` for seconds on one core; a tracking set of 500 costs less than a thread's start (some 50 µs)."""
FREE_TRIES = 250
"""Batches of candidates (four per pose still missing) `MapScan.free` draws before it gives up:
the free floor of a world is rarely below a tenth of its bounds."""


def raw_intervals(curve: IRCurve) -> tuple[int, np.ndarray]:
    """(lowest raw value, (values, INTERVALS, 2) array): for each raw value the intervals (m) of
    true distance plus noise that read it, nan-padded; a run at the grid's start reaches -inf (the
    noisy distance is clipped at 0) and one at its end +inf."""
    x = np.arange(0.0, GRID_END, GRID_STEP)
    raw = curve.lookup(x)
    low, high = curve.raw_range()
    table = np.full((high - low + 1, INTERVALS, 2), np.nan)
    count = np.zeros(high - low + 1, dtype=np.int64)
    edges = np.flatnonzero(np.diff(raw)) + 1
    for start, stop in zip(np.r_[0, edges], np.r_[edges, len(x)]):
        r = int(raw[start]) - low
        if count[r] == INTERVALS:
            raise ValueError(f"curve {curve.name}: raw value {raw[start]} comes from more than {INTERVALS} distance intervals")
        a = -math.inf if start == 0 else 0.5 * (x[start - 1] + x[start])
        b = math.inf if stop == len(x) else 0.5 * (x[stop - 1] + x[stop])
        table[r, count[r]] = a, b
        count[r] += 1
    return low, table


@numba.njit(cache=True)
def _normal_cdf(z: float) -> float:
    return 0.5 * math.erfc(-z * 0.7071067811865476)


@numba.njit(cache=True, nogil=True)
def scan_likelihood(particles: np.ndarray, sensors: np.ndarray, walls: Walls, nothing: np.ndarray, model: ScanModel, out: np.ndarray) -> None:
    """out[i] = the likelihood of one scan at particles[i] (x, y, heading): the product over the
    IR sensors (SENSORS rows: mount, body-frame direction, cone, pick view) of P(raw | expected
    distance), the raw value's distance intervals (`ScanModel`) under N(0, sigma[k]²), mixed with
    the outlier mass per raw value; 0 for a particle whose body (the model's radius) lies in a
    wall. `nothing`: no CIRCLES (the map has no robots or cans)."""
    n, m = particles.shape[0], sensors.shape[0]
    origins, look = np.empty((n * m, 2)), np.empty(n * m)
    cones, views, owner = np.empty(n * m), np.empty(n * m, dtype=np.bool_), np.full(n * m, -1, dtype=np.int64)
    for i in range(n):
        c, s = math.cos(particles[i, 2]), math.sin(particles[i, 2])
        for k in range(m):
            j, at = i * m + k, sensors[k].at
            origins[j, 0] = particles[i, 0] + c * at[0] - s * at[1]
            origins[j, 1] = particles[i, 1] + s * at[0] + c * at[1]
            look[j], cones[j], views[j] = particles[i, 2] + sensors[k].direction, sensors[k].opening, sensors[k].pick
    distance = np.empty(n * m)
    sense_ir(Rays(origins, look, cones, owner, views), walls, nothing, model.length, distance)
    intervals, sigma, outlier = model.intervals, model.sigma, model.outlier
    for i in range(n):
        if not clear_of_walls(particles[i, 0], particles[i, 1], model.radius, walls):
            out[i] = 0.0
            continue
        likelihood = 1.0
        for k in range(m):
            d = distance[i * m + k]
            p = 0.0
            for q in range(intervals.shape[1]):
                a, b = intervals[k, q, 0], intervals[k, q, 1]
                if math.isnan(a):
                    break
                if d == math.inf:
                    p += 1.0 if b == math.inf else 0.0
                else:
                    p += _normal_cdf((b - d) / sigma[k]) - _normal_cdf((a - d) / sigma[k])
            likelihood *= p + outlier[k]
        out[i] = likelihood


@numba.njit(cache=True)
def free_poses(bounds: np.ndarray, radius: float, walls: Walls, uniform: np.ndarray, out: np.ndarray) -> int:
    """Poses (x, y, heading in [0, 2 pi)) uniform over the places within `bounds` (xmin, ymin,
    xmax, ymax) where a body of `radius` is clear of every wall, by rejection: each row of
    `uniform` (k, 3) in [0, 1) is a candidate; the accepted ones fill `out` in order. Returns how
    many were written."""
    count = 0
    for j in range(uniform.shape[0]):
        if count == out.shape[0]:
            break
        x = bounds[0] + uniform[j, 0] * (bounds[2] - bounds[0])
        y = bounds[1] + uniform[j, 1] * (bounds[3] - bounds[1])
        if clear_of_walls(x, y, radius, walls):
            out[count, 0], out[count, 1], out[count, 2] = x, y, uniform[j, 2] * 2.0 * math.pi
            count += 1
    return count


def _free_cores() -> int:
    """Threads a shared scan may take (`SHARED_FROM`): numba's count less the cores other work
    holds (the load average beyond this process's one), at least 1."""
    busy = os.getloadavg()[0] - 1.0 if hasattr(os, "getloadavg") else 0.0
    return max(1, min(numba.config.NUMBA_NUM_THREADS, round(numba.config.NUMBA_NUM_THREADS - busy)))


class MapScan:
    """One robot's IR sensors against one world's map: the likelihood of a scan at many poses
    (`likelihood`) and random poses where the robot fits (`free`). What a localiser gets from the
    run loop (`bots.odometry.particles.MapModel`); it holds the map, never the robot's true pose."""

    def __init__(self, world: WorldSpec, robot: RobotSpec):
        self.walls = walls_of(world)
        ir = robot.ir
        self.sensors = SENSORS.new(len(ir))
        """The IR sensors as the world's kernels see them (mount, direction, cone, pick view)."""
        self.sensors["at"] = np.array([s.position for s in ir], dtype=np.float64).reshape(-1, 2)
        self.sensors["direction"] = [s.direction for s in ir]
        self.sensors["opening"] = [s.cone for s in ir]
        self.sensors["pick"] = [s.view == "pick" for s in ir]
        self._nothing = CIRCLES.new(0)
        self.sigma = np.array([math.hypot(s.noise_std, MODEL_STD) for s in ir])
        tables = [raw_intervals(ir_curve_for(s.curve, s.side)) for s in ir]
        self._lowest = [low for low, _ in tables]
        self._tables = [table for _, table in tables]
        self.outlier = np.array([OUTLIER / len(table) for table in self._tables])
        self.radius = robot.body_radius - CLEARANCE
        self.bounds = np.array(world.bounds, dtype=np.float64)

    def _intervals(self, raw: np.ndarray) -> np.ndarray:
        """(sensors, INTERVALS, 2) the distance intervals of each sensor's raw value (nan: none)."""
        intervals = np.full((len(raw), INTERVALS, 2), np.nan)
        for k, value in enumerate(np.asarray(raw).tolist()):
            row = value - self._lowest[k]
            if 0 <= row < len(self._tables[k]):
                intervals[k] = self._tables[k][row]
        return intervals

    def likelihood(self, particles: np.ndarray, raw: np.ndarray, out: np.ndarray) -> None:
        """out (n,) = the likelihood of the raw IR values `raw` (one per sensor) at each of the
        (n, 3) `particles`; ValueError for other shapes (a user's localiser calls this too: the
        kernel does not check its indices, and a short `out` would be written past its end)."""
        particles = np.ascontiguousarray(particles, dtype=np.float64)  # (the kernel's one compiled type)
        if particles.ndim != 2 or particles.shape[1] != 3 or np.shape(out) != (len(particles),) or np.shape(raw) != (len(self.sensors),):
            raise ValueError(f"likelihood takes (n, 3) particles, an (n,) out and ({len(self.sensors)},) raw values, "
                             f"got {particles.shape}, {np.shape(out)} and {np.shape(raw)}")  # fmt: skip
        if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.flags.writeable):
            raise ValueError(f"likelihood writes into `out`: a writeable float64 array, got {type(out).__name__} {getattr(out, 'dtype', '')}")
        model = ScanModel(IR_RAY_LENGTH, self._intervals(raw), self.sigma, self.outlier, self.radius)
        parts = min(_free_cores(), len(particles) // (SHARED_FROM // 2)) if len(particles) >= SHARED_FROM else 1
        cuts = [len(particles) * k // parts for k in range(parts + 1)]
        threads = [threading.Thread(target=scan_likelihood, args=(particles[a:b], self.sensors, self.walls, self._nothing, model, out[a:b]), daemon=True)
                   for a, b in zip(cuts[1:-1], cuts[2:])]  # fmt: skip
        for thread in threads:
            thread.start()
        scan_likelihood(particles[: cuts[1]], self.sensors, self.walls, self._nothing, model, out[: cuts[1]])
        for thread in threads:
            thread.join()

    def best(self, raw: np.ndarray) -> float:
        """The most likelihood any pose could give the raw values `raw` (`likelihood`'s scale): per
        sensor, the Gaussian's mass over the widest of the raw value's intervals centred on it."""
        product = 1.0
        for k, rows in enumerate(self._intervals(raw)):
            widths = (rows[:, 1] - rows[:, 0])[~np.isnan(rows[:, 0])]
            mass = max((math.erf(width / (2.0 * math.sqrt(2.0) * self.sigma[k])) for width in widths), default=0.0)
            product *= mass + self.outlier[k]
        return product

    def free(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """(count, 3) poses drawn uniformly where the robot's body is clear of every wall (fewer
        where FREE_TRIES candidates per pose find no room)."""
        out = np.empty((count, 3))
        done = 0
        for _ in range(FREE_TRIES):
            if done == count:
                break
            done += free_poses(self.bounds, self.radius + CLEARANCE, self.walls, rng.random((4 * (count - done), 3)), out[done:])
        return out[:done]
