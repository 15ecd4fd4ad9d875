"""Odometry estimators: what a robot believes about its pose, from its own readings only.

An estimator is reset with the robot's description and its start pose, then takes each step's
readings and exposes `pose` (x, y m, heading rad, continuous). The comparison against ground truth
happens in the run loop's consumers (`sim.analysis.metrics`), never here.

Every estimator turns one step's readings into an arc (centre arc length s, heading change alpha)
and lays it down either exactly (chord along the mid-angle, seed 002 eqs 1.7, 1.12) or as the
c't-Bot firmware does (chord along the end heading, ctsim-reference §5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bots.odometry.layout import HYPOTHESIS_WEIGHT, PARAMETERS, SIGMAS, fresh_state, watch_of, workspace
from bots.odometry.propagation import add_offset, add_point_noise, add_spread, mouse_terms, pose_covariance, wheel_terms
from bots.readings import Readings
from bots.spec import RobotSpec
from bots.uncertainty import COUNT_VARIANCE, COVARIANCE_FIELDS, ERRORS, Belief, entries_of, square
from sim.kinematics import MouseEstimator, advance
from sim.kinematics.mouse import counts_per_metre

TURN_MEMORY = 0.5
"""Time constant (s) over which the fused estimator forgets the mouse's and the encoders' rotation
disagreeing: long enough to see a slide build up (a robot driven along a wall in contact slides
its mouse sideways at 6 mm/s, read as 0.4 rad/s of turning, which over 0.25 s stayed under the
band and turned the estimate by 16 degrees in the maze, seeds 4 and 35), short enough that a wrong
track width (a few per cent of the turning) never adds up to the band."""
SLIP_MEMORY = 0.1
"""Metres of the mouse's path over which the fused estimator forgets the encoders' and the
mouse's distance disagreeing: a robot standing still forgets nothing (a wheel spinning against a
wall stays slip), one driving sees a slide of a few millimetres among 10 cm."""
GATE_SIGMAS = 5.0
"""Standard deviations of the random noise summed over the memory, and of the calibration still
unknown (per metre driven, per radian turned), that the two sensors may disagree by before the
fused estimator calls it slip or a slide: at 3 the detectors, whose sums are correlated from step
to step, fired often enough on noise alone to make the fused heading worse than the mouse's."""
SLIDE_WATCH_MEMORY = 2.0
"""Time constant (s) over which the mouse and fused estimates' slide watch
(`bots.odometry.mouse.watch_slides`) sums the mouse's rotation beyond the encoders': a slide of
a few millimetres a second along a wall lasts a second or two."""
SLIDE_WATCH_GATE = 2.0
"""Standard deviations of the believed calibration errors of the recent turning the slide watch
allows before it widens the heading's variance (a wrong alarm only widens it a little)."""
NOISE_COUNTS = 3.0
"""Mouse noise (counts) allowed over the memory: 0.2-0.5 counts per step add up to 1-2.5 counts."""


class Estimator(Protocol):
    """Dead reckoning from readings: `reset` at the start pose, `update` every step; `pose`
    (3,) x, y m, heading rad. Optional: `covariance`, the (3, 3) covariance of the pose's error
    (m², m·rad, rad²) after the last update; without it, the estimate is reported without one."""

    name: str
    pose: np.ndarray

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None: ...
    def update(self, readings: Readings) -> None: ...


@dataclass(frozen=True)
class Geometry:
    """What the robot's own code believes about its drive (m): the nominal values unless a
    calibration such as UMBmark corrected them."""

    wheel_diameters: tuple[float, float]
    track_width: float

    @classmethod
    def nominal(cls, robot: RobotSpec) -> Geometry:
        """The geometry the robot description states."""
        return cls((robot.wheel_diameter, robot.wheel_diameter), robot.track_width)

    @classmethod
    def believed(cls, robot: RobotSpec) -> Geometry:
        """The nominal geometry with the corrections of the robot's belief (a calibration's)."""
        left, right = robot.belief.diameter_correction
        return cls((robot.wheel_diameter * (1 + left), robot.wheel_diameter * (1 + right)), robot.track_width * (1 + robot.belief.track_correction))


def parameters(robot: RobotSpec, geometry: Geometry | None = None) -> np.void:
    """The robot's PARAMETERS row (`bots.odometry.layout`): what its estimators believe of its
    drive (`geometry`, None: its belief's, `Geometry.believed`), its mouse and its noise (`Belief.of`)."""
    p = PARAMETERS.new(1)[0]
    believed = geometry or Geometry.believed(robot)
    p["tick_left"], p["tick_right"] = (math.pi * d / robot.encoders.ticks_per_rev for d in believed.wheel_diameters)
    p["track"] = believed.track_width
    belief = Belief.of(robot)
    p["slip_var"] = belief.slip_var
    p["wheel_std"], p["track_std"], p["mouse_scale_std"] = belief.wheel_scale_std, belief.track_std, belief.mouse_scale_std
    # a metre rolled is 1/tick ticks, each one off by a tick with probability tick_rate: m² per metre
    p["tick_var_left"], p["tick_var_right"] = belief.tick_rate * p["tick_left"], belief.tick_rate * p["tick_right"]
    if mouse_applies(robot):
        mount_x, mount_y = (float(m) for m in robot.mouse.mount)
        p["per_metre"], p["mount_x"], p["mount_y"] = float(counts_per_metre(robot.mouse.dpi)), mount_x, mount_y
        count = 1.0 / p["per_metre"]
        # the fused estimator's detectors (see FusedOdometry)
        p["tolerance"] = max(p["tick_left"], p["tick_right"]) + count * (1.0 + abs(mount_y) / abs(mount_x))
        p["turn_tolerance"] = 2.0 * (max(p["tick_left"], p["tick_right"]) / p["track"] + count / abs(mount_x)) + NOISE_COUNTS * count / abs(mount_x)
        p["memory"], p["gate"], p["distance_memory"] = TURN_MEMORY, GATE_SIGMAS, SLIP_MEMORY
        p["slide_memory"], p["slide_gate"] = SLIDE_WATCH_MEMORY, SLIDE_WATCH_GATE
        p["mouse_var"] = belief.mouse_var
        p["has_mouse"] = True
    return p


def quantisation_lag(p: np.void, mouse: bool) -> np.ndarray:
    """(2, 2) covariance of the (s, alpha) error of carried counts (each COUNT_VARIANCE counts²,
    `bots.uncertainty`): the encoders' or the mouse's. (Through the kernels' Python functions, the
    same operations: once a reset, where the compiled ones would each compile in this process at
    the first run, beside the compile processes that compile them into the odometry's step.)"""
    lag, jac = np.zeros((2, 2)), np.zeros((2, ERRORS))
    if mouse:
        mouse_terms.py_func(0.0, 0.0, p["mount_x"], p["mount_y"], COUNT_VARIANCE / p["per_metre"] ** 2, jac, lag)
    else:
        wheel_terms.py_func(0.0, 0.0, 0.0, p["track"], COUNT_VARIANCE * p["tick_left"] ** 2, COUNT_VARIANCE * p["tick_right"] ** 2, jac, lag)
    return lag


def phase_offset(lag: np.ndarray, heading: float) -> np.ndarray:
    """(ERRORS, ERRORS) error covariance at the start of a dead reckoning whose calibration the
    sigma points carry: the pose error of counters started at unknown phases, `lag` ((s, alpha),
    count²/12 a counter) laid at the start heading. A count is off its wheel's or floor's truth by
    where it started within a count less where it stands now, each uniform (count²/12 each, count²/6
    together: COUNT_VARIANCE). Where it stands now is reported beside the covariance (`lag`); where
    it started is an offset the estimate carries from the first step, whose heading part turns
    every later move (taken as reported only, the lag left the path's lateral drift out: drawn
    robots read a mean NEES of 3.98 over 240 maze runs 6 s in, where chi-square's is 3)."""
    entries, errors = np.zeros(len(COVARIANCE_FIELDS)), np.zeros((ERRORS, ERRORS))
    pose_covariance.py_func(errors, heading, lag, entries)
    errors[:3, :3] = square(entries)
    return errors


class ArcOdometry:
    """Shared dead reckoning: `step(readings)` gives (s, alpha) for the step, laid by `advance`,
    and propagates the error covariance `errors` (`bots.uncertainty`) in the same compiled step
    (`bots.odometry.propagation`); `lag` is the quantisation lag reported beside it.

    An estimator with `sigma_count` sigma points (`bots.odometry.encoder.sigma_encoders`,
    `bots.odometry.mouse.sigma_mouse`) carries its calibration's part of the error there instead: each point
    dead-reckons the same readings with its calibration errors off by nodes of Gauss-Hermite
    quadrature (`bots.odometry.layout.NODES`), and
    the covariance adds their spread about the estimate. A wrong track turns the heading by tens
    of degrees over a maze, and the position error then bends away from where a first-order
    covariance puts it (it has no variance along the track from a heading error); the points
    follow the bend exactly. `errors` then holds the random noise alone, carried along the
    estimate's path, and each point carries it along its own path too (`noises`): a heading error
    turns every later move, and a robot whose calibration turns its heading far from the
    estimate's spreads its random error across its own path; the covariance reports the random
    part's mean over the points (`add_noise`). An estimator with a slide
    watch (`watch`, its ESTIMATE: the mouse's and the fused one's) adds its hypothesis's offset
    (`bots.odometry.mouse.watch_slides`)."""

    name = "arc"
    end_heading = False
    uses_mouse = False
    sigma_count = 0
    watch: int | None = None
    caveat = ""
    """Where its covariance is known not to tell the truth, in one line for a run's summary and
    table (docs/odometry.md, "Where the covariance holds", measures it)."""

    def __init__(self, geometry: Geometry | None = None):
        self.geometry = geometry

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        if self.uses_mouse and not mouse_applies(robot):
            raise ValueError(f"robot {robot.name!r} has no mouse sensor that sees rotation: {self.name} odometry does not apply")
        self.robot = robot
        self.pose = np.asarray(pose, dtype=np.float64).copy()
        self.params = parameters(robot, self.geometry)
        self.lag = quantisation_lag(self.params, self.uses_mouse)
        self.errors = Belief.of(robot).prior()
        if self.sigma_count:  # (the calibration on the sigma points; the count's error split into where it started and where it stands)
            self.lag = 0.5 * self.lag
            self.errors = phase_offset(self.lag, float(self.pose[2]))
        self.sigmas = np.repeat(self.pose[None], SIGMAS, axis=0)
        """(SIGMAS, 3) the sigma points' poses (the first `sigma_count` used)."""
        self.noises = np.repeat(entries_of(self.errors)[:, None], SIGMAS, axis=1)
        """(COVARIANCE_FIELDS, SIGMAS) each sigma point's random part, carried along its own path (`carry_noise`)."""
        self.turns = np.zeros((3, SIGMAS))
        self.state = fresh_state()
        """The compiled steps' STATE row (`bots.odometry.layout`: the fused detectors, the slide watches)."""
        self.state["mouse_watch"]["hypothesis"] = self.state["fused_watch"]["hypothesis"] = self.pose
        self._entries = np.zeros(len(COVARIANCE_FIELDS))
        self.work = workspace()  # (the compiled steps' scratch)

    def step(self, readings: Readings) -> tuple[float, float]:
        raise NotImplementedError

    def update(self, readings: Readings) -> None:
        s, alpha = self.step(readings)
        self.pose = advance(self.pose, s, alpha, self.end_heading)

    @property
    def covariance(self) -> np.ndarray:
        """(3, 3) covariance of the pose's error (m², m·rad, rad²): propagated plus the lag, plus
        the sigma points' spread and the slide hypothesis's offset."""
        pose_covariance(self.errors, float(self.pose[2]), self.lag, self._entries)
        add_spread(self.sigmas, self.sigma_count, self.pose, self._entries)
        self.add_noise(self._entries)
        if self.watch is not None:
            add_offset(watch_of(self.state, self.watch)["hypothesis"], self.pose, HYPOTHESIS_WEIGHT, self._entries)
        return square(self._entries)

    def add_noise(self, entries: np.ndarray) -> None:
        """Where the sigma points carry their own random part: put its mean over their paths
        (`add_point_noise`) into the covariance `entries` in place of the estimate's own."""
        if self.sigma_count:
            add_point_noise(self.noises, self.sigma_count, self.errors, entries)


def mouse_applies(robot: RobotSpec) -> bool:
    """A mouse that can see rotation: present and off the wheel axle line."""
    return robot.mouse is not None and math.isfinite(robot.mouse.mount[0]) and abs(robot.mouse.mount[0]) >= MouseEstimator.min_lever
