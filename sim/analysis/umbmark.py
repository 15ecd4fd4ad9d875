"""UMBmark (Borenstein & Feng 1996): measure and correct a differential drive's two dominant
systematic odometry errors with a square driven clockwise and counter-clockwise.

Type A, the track width error: E_b = b_real / b_believed. A turn the odometry counts as 90 deg is
really 90 deg - alpha, alpha = 90 deg (1 - 1/E_b) > 0 for a track wider than believed.
Type B, the wheel diameter ratio: E_d = D_R / D_L (real, relative to the believed ratio). On a
leg the odometry counts as straight the robot curves by beta > 0 to the left for E_d > 1.
(UMBmark assumes the mean diameter right: a common scale error closes every square anyway. The
paper calibrates that scale, E_s = true distance / counted distance, apart, on a straight run of
known length: `scale_error`; a scale left wrong turns the robot by E_s more per tick, which the
squares take for a track 1/E_s as wide.)

Return-position error, to first order in alpha and beta, in the start frame (x along the first
leg, y to its left; epsilon = true end - odometry end, the paper's x_abs - x_calc). A heading
error d_theta gained at point c turns the rest of the path about c, moving the end by
d_theta * J (p_end - c), J = rotation by +90 deg. A leg that curves by beta acts as a turn by beta
about its midpoint; each of the three corners before the end adds -alpha (ccw) or +alpha (cw).
Summing over the legs' midpoints and the corners of a square of side L:

    ccw (left turns):  x = 2L(beta - alpha),   y = -2L(beta - alpha)
    cw (right turns):  x = -2L(beta + alpha),  y = -2L(beta + alpha)

so, from the centres of gravity of the n returns in each direction (the paper's eqs 10-11),

    alpha = (x_cw + x_ccw) / (-4L),   beta = (x_cw - x_ccw) / (-4L)   (rad),

and then R = (L/2) / sin(beta/2) (the arc of chord L that turns by beta), E_d = (R + b/2)/(R - b/2),
E_b = (pi/2) / (pi/2 - alpha). Corrected believed diameters D_L * 2/(E_d + 1),
D_R * 2/(1/E_d + 1) (ratio E_d, mean kept) and track b * E_b.

The model is first order: on the c't-Bot (97 mm track) a 1 % diameter ratio already curves a
1 m leg by 5 deg and the first round underestimates a 2 % track error by half; `calibrate` with
rounds=2 measures again with the corrected geometry, where the residual errors are small.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from statistics import NormalDist
from typing import Any

import numpy as np

from bots.commands import STOP, Command, Twist
from bots.controller import Status
from bots.odometry.base import Geometry
from bots.odometry.encoder import EncoderOdometry
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.run.loop import RobotSetup, run
from sim.world.spec import WorldSpec
from sim.world.step import DEFAULT_DT

HEADING_GAIN, CROSS_GAIN = 3.0, 20.0
"""A leg's steering by the odometry: turn rate (rad/s) per radian off the leg's heading, and per
metre off its line per m/s of speed."""


class OdometrySquare:
    """Drives `laps` squares of `side` metres by the robot's own encoder odometry (believing
    `geometry`): legs held on the believed square's edge (heading and cross-track feedback,
    slowing down before the corner), turns on the spot, stop when the odometry says so.

    Odometry-closed-loop, as UMBmark requires: a timed open-loop square would measure the motors,
    not the odometry."""

    def __init__(self, side_m: float = 1.0, clockwise: bool = False, laps: int = 1, geometry: Geometry | None = None,
                 speed: float = 0.3, turn_rate: float = 2.0):
        if not side_m > 0 or laps < 1:
            raise ValueError(f"a square needs side_m > 0 and laps >= 1, got {side_m!r}, {laps!r}")
        self.side, self.turn, self.laps = side_m, -1.0 if clockwise else 1.0, laps
        self.speed, self.turn_rate = speed, turn_rate
        self.odometry = EncoderOdometry(geometry)
        self.status = Status.RUNNING

    def reset(self, robot: RobotSpec) -> None:
        self.robot = robot
        self.odometry.reset(robot, np.zeros(3))
        self.segment, self.corner, self.status = 0, np.zeros(2), Status.RUNNING

    def step(self, t: float, readings: Readings) -> Command:
        self.odometry.update(readings)
        x, y, heading = self.odometry.pose
        while self.segment < 8 * self.laps:
            leg = self.segment // 2
            target = self.turn * math.pi / 2 * (leg + self.segment % 2)
            if self.segment % 2 == 0:
                along = np.array([math.cos(target), math.sin(target)])
                offset = np.array([x, y]) - self.corner
                remaining = self.side - offset @ along
                if remaining > 0:
                    lateral = along[0] * offset[1] - along[1] * offset[0]
                    v = min(self.speed, max(0.02, 4.0 * remaining))
                    return Twist(v, HEADING_GAIN * (target - heading) - CROSS_GAIN * v * lateral)
                self.corner = self.corner + self.side * along
            else:
                remaining = target - heading
                if remaining * self.turn > 0:
                    return Twist(0.0, math.copysign(min(self.turn_rate, max(0.1, 4.0 * abs(remaining))), remaining))
            self.segment += 1
        self.status = Status.SUCCESS
        return STOP

    def duration(self) -> float:
        """A bound on the time the square takes (s): full speed plus at most 1.5 s of slowing
        down per leg and per turn (the slow-down gain of 4/s decays from the top speed to the
        creep speed in ln(15)/4 s = 0.7 s, the creep covers the last 5 mm or 25 mrad in 0.25 s)."""
        per_lap = 4 * (self.side / self.speed + 1.5) + 4 * (math.pi / 2 / self.turn_rate + 1.5)
        return self.laps * per_lap + 1.0


class StraightRun:
    """Drives straight ahead for `length` / `speed` seconds by the robot's own encoder odometry
    (heading and cross-track held as `OdometrySquare`'s legs), then stops. Stopped by the clock,
    not at the count that reaches the length: there the counted distance would lead the true one
    by half a count on average (a counter started anywhere within a count reaches each count
    that far past the truth), 1.5 mm in 1 m on the c't-Bot, as large as the scale error sought."""

    def __init__(self, length: float = 1.0, geometry: Geometry | None = None, speed: float = 0.3):
        if not length > 0:
            raise ValueError(f"a straight run needs length > 0, got {length!r}")
        self.length, self.speed = length, speed
        self.odometry = EncoderOdometry(geometry)
        self.status = Status.RUNNING

    def reset(self, robot: RobotSpec) -> None:
        self.odometry.reset(robot, np.zeros(3))
        self.status = Status.RUNNING

    def step(self, t: float, readings: Readings) -> Command:
        self.odometry.update(readings)
        _, y, heading = self.odometry.pose
        if t >= self.length / self.speed:
            self.status = Status.SUCCESS
            return STOP
        return Twist(self.speed, -HEADING_GAIN * heading - CROSS_GAIN * self.speed * y)

    def duration(self) -> float:
        """The drive and a second to come to rest (s)."""
        return self.length / self.speed + 1.0


@dataclass(frozen=True)
class UMBmarkResult:
    """One UMBmark: return errors (n, 2) in the start frame (m), their centres of gravity, the
    error angles (rad), the systematic errors and the geometry that corrects them.

    max_error: the paper's measure of systematic odometric accuracy, E_max,syst =
    max(|cg_cw|, |cg_ccw|) (m)."""

    side: float
    errors_cw: np.ndarray
    errors_ccw: np.ndarray
    cg_cw: np.ndarray
    cg_ccw: np.ndarray
    alpha: float
    beta: float
    e_d: float
    e_b: float
    believed: Geometry
    corrected: Geometry
    seeds: tuple[int, ...] = ()
    """The run seeds its squares were driven with (`return_errors`)."""

    @property
    def max_error(self) -> float:
        return float(max(np.hypot(*self.cg_cw), np.hypot(*self.cg_ccw)))


def systematic_errors(cg_cw: np.ndarray, cg_ccw: np.ndarray, side: float, track: float) -> tuple[float, float, float, float]:
    """(alpha, beta, E_d, E_b) from the centres of gravity (x, y) of the cw and ccw returns (m),
    the square's side and the believed track (m): the module's formulas (paper eqs 10-17)."""
    alpha = (cg_cw[0] + cg_ccw[0]) / (-4.0 * side)
    beta = (cg_cw[0] - cg_ccw[0]) / (-4.0 * side)
    radius = (side / 2) / math.sin(beta / 2) if beta else math.inf
    e_d = (radius + track / 2) / (radius - track / 2) if math.isfinite(radius) else 1.0
    e_b = (math.pi / 2) / (math.pi / 2 - alpha)
    return alpha, beta, e_d, e_b


def corrected_geometry(believed: Geometry, e_d: float, e_b: float) -> Geometry:
    """Believed geometry with the paper's corrections: c_L = 2/(E_d + 1), c_R = 2/(1/E_d + 1),
    b_new = E_b * b (eqs 18-19)."""
    left, right = believed.wheel_diameters
    return Geometry((left * 2 / (e_d + 1), right * 2 / (1 / e_d + 1)), believed.track_width * e_b)


SQUARES_PER_WORLD = 64
"""Squares driven at once in one world (each by a robot of its own, on a floor cell of its own):
a run's fixed cost shared, 40 squares take some 6 s where one takes 1 s."""
BOOTSTRAP_KEY = 0x0B5
"""Spawn key of the bootstrap's generator beside a seed's run generators."""
CONFIDENCE = 0.95
"""Level of the intervals UMBmark reports."""
MAX_STD = 0.5
"""The largest relative std a belief takes (`bots.spec.BeliefSpec`)."""
BOOTSTRAP_DRAWS = 2000
"""Resamples of the return errors behind each interval (its end points then move by under a tenth
of its width from one set of draws to another)."""


def squares_floor(count: int, side: float) -> tuple[WorldSpec, list[tuple[float, float, float]]]:
    """Open floor for `count` squares of `side` m, one floor cell of 2 x `side` each in rows of
    eight, and their start poses facing +x: a ccw square (even index) starts at its cell's lower
    quarter, a cw one (odd) at its upper, so that either covers the cell's middle, `side` / 2 clear
    of its neighbours' (far beyond what a robot strays)."""
    per_row = min(count, 8)
    rows = -(-count // per_row)
    cell = 2.0 * side
    starts = []
    for k in range(count):
        x0, y0 = cell * (k % per_row), cell * (k // per_row)
        starts.append((x0 + side / 2, y0 + (1.5 if k % 2 else 0.5) * side, 0.0))
    return WorldSpec("umbmark floor", (0.0, 0.0, cell * per_row, cell * rows)), starts


def _driven(robot: RobotSpec, total: int, side: float, geometry: Geometry, seed: int, dt: float,
            driver: Callable[[int], OdometrySquare | StraightRun]) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:  # fmt: skip
    """`total` drives (`driver(k)` the k-th) by odometry believing `geometry`, SQUARES_PER_WORLD at
    once on a floor cell of `squares_floor` each: the (total, 2) true and odometry end positions
    relative to the start (m, the start facing +x), and the run seeds used (`seed`, `seed` + 1,
    ...: each robot with generators of its own spawned from its run's seed, so no two drives share
    noise)."""
    truth: list[np.ndarray] = []
    counted: list[np.ndarray] = []
    chunk = 0
    while len(truth) < total:
        count = min(SQUARES_PER_WORLD, total - len(truth))
        world, starts = squares_floor(count, side)
        drivers = [driver(len(truth) + k) for k in range(count)]
        setups = [RobotSetup(robot, d, "umbmark-square", start=s, estimators=[EncoderOdometry(geometry)]) for d, s in zip(drivers, starts)]
        result = run(world, setups, drivers[0].duration(), dt=dt, seed=seed + chunk)
        for made, log, start in zip(drivers, result.robots, starts):
            if made.status is not Status.SUCCESS:
                raise RuntimeError(f"a {type(made).__name__} did not finish ({result.reason}: {result.error})")
            truth.append(log.truth_array()[-1, :2] - start[:2])
            counted.append(log.estimate_arrays()["encoders"][-1, :2] - start[:2])
        chunk += 1
    return np.array(truth), np.array(counted), tuple(range(seed, seed + chunk))


def return_errors(robot: RobotSpec, runs: int, side: float, geometry: Geometry, seed: int,
                  dt: float = DEFAULT_DT) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """`runs` squares each way by odometry believing `geometry`: the (runs, 2) return errors of
    the cw and of the ccw squares, (x, y) true end minus odometry end in the start frame (m), and
    the run seeds used (`_driven`)."""
    truth, counted, seeds = _driven(robot, 2 * runs, side, geometry, seed, dt, lambda k: OdometrySquare(side, bool(k % 2), geometry=geometry))
    both = truth - counted
    return both[1::2], both[0::2], seeds


@dataclass(frozen=True)
class ScaleResult:
    """The common scale of both wheels from straight runs of known length: each run's true and
    counted distance, start to end (m), as a tape measures it; E_s = mean true / mean counted,
    its CONFIDENCE interval (bootstrap over the runs), and the believed geometry with both
    diameters scaled by E_s (their ratio kept)."""

    length: float
    true: np.ndarray
    counted: np.ndarray
    e_s: float
    interval: tuple[float, float]
    believed: Geometry
    corrected: Geometry
    seeds: tuple[int, ...]


def scale_error(robot: RobotSpec, runs: int, length: float = 1.0, geometry: Geometry | None = None, seed: int = 0,
                dt: float = DEFAULT_DT) -> ScaleResult:  # fmt: skip
    """E_s of `runs` straight runs of `length` m by odometry believing `geometry` (default:
    the robot's belief's, `Geometry.believed`), each on noise of its own (`_driven`). The paper's E_s, which UMBmark's squares cannot
    see: a mean diameter 0.15 % too large (the realistic c't-Bot's, whose right wheel alone is
    0.3 % larger) makes the squares report its +1 % track as +0.85 %."""
    if runs < 1:
        raise ValueError(f"a scale needs at least one straight run, got {runs!r}")
    believed = geometry or Geometry.believed(robot)
    truth, counted, seeds = _driven(robot, runs, length, believed, seed, dt, lambda k: StraightRun(length, believed))
    true, odometry = np.hypot(*truth.T), np.hypot(*counted.T)
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(BOOTSTRAP_KEY,)))
    picks = rng.integers(0, runs, (BOOTSTRAP_DRAWS, runs))
    ratios = true[picks].mean(axis=1) / odometry[picks].mean(axis=1)
    e_s = float(true.mean() / odometry.mean())
    left, right = believed.wheel_diameters
    corrected = Geometry((left * e_s, right * e_s), believed.track_width)
    return ScaleResult(length, true, odometry, e_s, _interval(ratios), believed, corrected, seeds)


def evaluate(errors_cw: np.ndarray, errors_ccw: np.ndarray, side: float, believed: Geometry,
             seeds: tuple[int, ...] = ()) -> UMBmarkResult:
    """The UMBmark of these return errors (n, 2) each way (m) of squares of `side` m driven by
    odometry believing `believed`."""
    cg_cw, cg_ccw = errors_cw.mean(axis=0), errors_ccw.mean(axis=0)
    alpha, beta, e_d, e_b = systematic_errors(cg_cw, cg_ccw, side, believed.track_width)
    return UMBmarkResult(side, errors_cw, errors_ccw, cg_cw, cg_ccw, alpha, beta, e_d, e_b, believed,
                         corrected_geometry(believed, e_d, e_b), seeds)


def umbmark(robot: RobotSpec, side: float = 1.0, runs: int = 5, geometry: Geometry | None = None,
            seed: int = 0, dt: float = DEFAULT_DT) -> UMBmarkResult:
    """Drive `runs` squares each way with the odometry believing `geometry` (default: its belief's),
    on fresh noise (`return_errors`), and evaluate them."""
    if runs < 1:
        raise ValueError(f"UMBmark needs at least one run each way, got {runs!r}")
    believed = geometry or Geometry.believed(robot)
    cw, ccw, seeds = return_errors(robot, runs, side, believed, seed, dt)
    return evaluate(cw, ccw, side, believed, seeds)


def confidence(result: UMBmarkResult, seed: int = 0, draws: int = BOOTSTRAP_DRAWS) -> dict[str, tuple[float, float]]:
    """CONFIDENCE intervals of "max_error", "e_d", "e_b", "alpha" and "beta" by the bootstrap:
    the runs of each direction resampled with replacement (`draws` times, from a generator of
    `seed`), each resample evaluated as the result was, the percentiles of what comes out. With
    one run a direction the intervals are a single point: there is no spread to resample."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(BOOTSTRAP_KEY,)))
    n_cw, n_ccw = len(result.errors_cw), len(result.errors_ccw)
    values = {name: np.empty(draws) for name in ("max_error", "e_d", "e_b", "alpha", "beta")}
    for k in range(draws):
        cw = result.errors_cw[rng.integers(0, n_cw, n_cw)].mean(axis=0)
        ccw = result.errors_ccw[rng.integers(0, n_ccw, n_ccw)].mean(axis=0)
        alpha, beta, e_d, e_b = systematic_errors(cw, ccw, result.side, result.believed.track_width)
        for name, value in (("max_error", max(np.hypot(*cw), np.hypot(*ccw))), ("e_d", e_d), ("e_b", e_b), ("alpha", alpha), ("beta", beta)):
            values[name][k] = value
    return {name: _interval(v) for name, v in values.items()}


def _interval(draws: np.ndarray) -> tuple[float, float]:
    """The CONFIDENCE interval of a bootstrap's `draws`: their central percentiles."""
    tail = 100 * (1 - CONFIDENCE) / 2
    return float(np.percentile(draws, tail)), float(np.percentile(draws, 100 - tail))


def recommended_runs(result: UMBmarkResult, tolerance: float = 0.002) -> int:
    """Runs each way after which the CONFIDENCE interval of both corrections, E_d and E_b, is at
    most +-`tolerance` wide (relative), from the spread of this result's return errors: the
    corrections depend on the x of the two centres of gravity alone, each the mean of n runs, so
    (delta method) var(E) = (dE/dx_cw² var(x_cw) + dE/dx_ccw² var(x_ccw)) / n, the slopes of
    `systematic_errors` taken numerically. ValueError with fewer than two runs a direction (no spread)."""
    if min(len(result.errors_cw), len(result.errors_ccw)) < 2:
        raise ValueError("a recommendation needs the spread of at least two runs each way")
    var_cw, var_ccw = result.errors_cw[:, 0].var(ddof=1), result.errors_ccw[:, 0].var(ddof=1)
    step, track = 1e-6, result.believed.track_width
    at = np.array(systematic_errors(result.cg_cw, result.cg_ccw, result.side, track)[2:])
    slope_cw = (np.array(systematic_errors(result.cg_cw + (step, 0.0), result.cg_ccw, result.side, track)[2:]) - at) / step
    slope_ccw = (np.array(systematic_errors(result.cg_cw, result.cg_ccw + (step, 0.0), result.side, track)[2:]) - at) / step
    per_run = slope_cw**2 * var_cw + slope_ccw**2 * var_ccw  # (E_d, E_b) variance of one run each way
    z = float(NormalDist().inv_cdf(0.5 + CONFIDENCE / 2))
    return max(2, math.ceil(z * z * float(per_run.max()) / tolerance**2))


def calibrate(robot: RobotSpec, rounds: int = 1, **options) -> list[UMBmarkResult]:
    """UMBmark `rounds` times, each starting from the geometry the previous one corrected (the
    paper does one round; a second one removes what the first-order formulas left); returns
    every round's result, the last one's `corrected` being the calibration. Each round drives on
    seeds of its own (those after the previous round's): a round that drove the first one's
    seeds again would measure the same noise and correct it as if it were systematic."""
    results: list[UMBmarkResult] = []
    geometry = options.pop("geometry", None)
    seed = options.pop("seed", 0)
    for _ in range(rounds):
        results.append(umbmark(robot, geometry=geometry, seed=seed, **options))
        geometry, seed = results[-1].corrected, results[-1].seeds[-1] + 1
    return results


def calibrated_belief(robot: RobotSpec, corrected: Geometry, interval: dict[str, tuple[float, float]], scale: ScaleResult | None) -> dict[str, Any]:
    """The `[belief]` a calibration gives (`bots.spec.BeliefSpec`): the corrections of the calibrated
    geometry against the nominal one, and standard deviations from the 95 % intervals of the last
    round's E_b and E_d and of the scale's E_s (the robot's stated tolerance where no scale was
    measured; so where one run a direction left no spread to measure). The belief gives each wheel
    one std, independent of the other's: the larger of what the ratio's (std_d / sqrt 2) and the
    scale's (std_s * sqrt 2) intervals ask, so that the estimators believe neither tighter than
    measured."""
    z = 2 * float(NormalDist().inv_cdf(0.5 + CONFIDENCE / 2))
    (left, right), track = corrected.wheel_diameters, corrected.track_width
    stated = robot.belief
    std_d = (interval["e_d"][1] - interval["e_d"][0]) / z or stated.wheel_diameter_std * math.sqrt(2)
    std_b = (interval["e_b"][1] - interval["e_b"][0]) / z or stated.track_std
    std_s = (scale.interval[1] - scale.interval[0]) / z if scale is not None else 0.0
    std_s = std_s or stated.wheel_diameter_std / math.sqrt(2)
    return {
        "diameter_correction": [left / robot.wheel_diameter - 1, right / robot.wheel_diameter - 1],
        "track_correction": track / robot.track_width - 1,
        "wheel_diameter_std": min(max(std_d / math.sqrt(2), std_s * math.sqrt(2)), MAX_STD),
        "track_std": min(std_b, MAX_STD),
    }
