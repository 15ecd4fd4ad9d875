"""UMBmark (Borenstein & Feng 1996): measure and correct a differential drive's two dominant
systematic odometry errors with a square driven clockwise and counter-clockwise.

Type A, the track width error: E_b = b_real / b_believed. A turn the odometry counts as 90 deg is
really 90 deg - alpha, alpha = 90 deg (1 - 1/E_b) > 0 for a track wider than believed.
Type B, the wheel diameter ratio: E_d = D_R / D_L (real, relative to the believed ratio). On a
leg the odometry counts as straight the robot curves by beta > 0 to the left for E_d > 1.
(UMBmark assumes the mean diameter right: a common scale error closes every square anyway.)

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
from dataclasses import dataclass

import numpy as np

from bots.commands import STOP, Command, Twist
from bots.controller import Status
from bots.odometry.base import Geometry
from bots.odometry.encoder import EncoderOdometry
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.run.loop import RobotSetup, run
from sim.world.files import load_world
from sim.world.spec import WorldSpec
from sim.world.step import DEFAULT_DT


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
                    return Twist(v, 3.0 * (target - heading) - 20.0 * v * lateral)
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


def square_world() -> WorldSpec:
    """worlds/square.toml: 4 m x 4 m, start at (0.5, 1.5) facing +x."""
    return load_world("square")


def return_error(robot: RobotSpec, clockwise: bool, side: float, geometry: Geometry, world: WorldSpec,
                 start: tuple[float, float, float], seed: int, dt: float = DEFAULT_DT) -> np.ndarray:
    """One square by odometry: (x, y) true end minus odometry end, in the start frame (m)."""
    driver = OdometrySquare(side, clockwise, geometry=geometry)
    setup = RobotSetup(robot, driver, "umbmark-square", start=start, estimators=[EncoderOdometry(geometry)])
    result = run(world, [setup], driver.duration(), dt=dt, seed=seed)
    if driver.status is not Status.SUCCESS:
        raise RuntimeError(f"the {'cw' if clockwise else 'ccw'} square did not finish ({result.reason}: {result.error})")
    log = result.robots[0]
    gap = log.truth_array()[-1, :2] - log.estimate_arrays()["encoders"][-1, :2]
    c, s = math.cos(start[2]), math.sin(start[2])
    return np.array([c * gap[0] + s * gap[1], -s * gap[0] + c * gap[1]])


def umbmark(robot: RobotSpec, side: float = 1.0, runs: int = 5, geometry: Geometry | None = None,
            world: WorldSpec | None = None, seed: int = 0) -> UMBmarkResult:
    """Run `runs` squares each way with the odometry believing `geometry` (default: nominal) and
    evaluate them. Default world: worlds/square.toml; the ccw square starts at the world's start
    pose, the cw one `side` to its left, so that both squares cover the same floor."""
    world = world or square_world()
    believed = geometry or Geometry.nominal(robot)
    home = world.start_for(0)
    x, y, h = home.x, home.y, home.heading
    starts = {False: (x, y, h), True: (x - side * math.sin(h), y + side * math.cos(h), h)}
    errors = {
        cw: np.array([return_error(robot, cw, side, believed, world, starts[cw], seed + 2 * i + cw) for i in range(runs)])
        for cw in (True, False)
    }
    cg_cw, cg_ccw = errors[True].mean(axis=0), errors[False].mean(axis=0)
    alpha, beta, e_d, e_b = systematic_errors(cg_cw, cg_ccw, side, believed.track_width)
    return UMBmarkResult(side, errors[True], errors[False], cg_cw, cg_ccw, alpha, beta, e_d, e_b, believed,
                         corrected_geometry(believed, e_d, e_b))


def calibrate(robot: RobotSpec, rounds: int = 1, **options) -> list[UMBmarkResult]:
    """UMBmark `rounds` times, each starting from the geometry the previous one corrected (the
    paper does one round; a second one removes what the first-order formulas left); returns
    every round's result, the last one's `corrected` being the calibration. Each round drives on
    seeds of its own (`seed` + 2 runs per round before it): a round that drove the first one's
    seeds again would measure the same noise and correct it as if it were systematic."""
    results: list[UMBmarkResult] = []
    geometry = options.pop("geometry", None)
    seed, runs = options.pop("seed", 0), options.get("runs", 5)
    for done in range(rounds):
        results.append(umbmark(robot, geometry=geometry, seed=seed + 2 * runs * done, **options))
        geometry = results[-1].corrected
    return results
