"""The propagated covariance of the odometry against Monte Carlo: 1,000 robots with their own
noise (each its own generators, spawned from the run's seed as every robot's are) drive the same
commands on open floor; the spread of their estimates' errors at the end must be the covariance
each estimator propagated.

Three robots: one whose encoders and mouse are fine enough that quantisation is below a
nanometre, so that what is compared is the random noise alone (slip on the wheels, count noise on
the mouse); the c't-Bot's own 60 ticks and 400 dpi with counters starting anywhere within a count
(`start_phase`), so that the quantisation is in the spread too (each robot drives 0.3 % faster or
slower, so that the wheels' turns end at every fraction of a tick); and that robot with systematic
errors on, each robot's wheels, track and mouse resolution off by its own draw from the belief
(the spread of many robots built to the stated tolerances, which is what a belief states).
Every robot believes what it is: the random noise as it is, and the systematic errors by the
spread they are drawn from (none where they are off).

Sampling error: whitened by the propagated covariance, the errors' sample covariance is the
identity within sampling error, its diagonal entries with a standard deviation of sqrt(2/N) =
0.045 and the others 1/sqrt(N) = 0.032 for N = 1,000; the test allows 4 of them (a false alarm
once in about 5,000 runs per entry).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.commands import Twist
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from bots.noise import NOISE_PRESETS, with_settings
from bots.odometry.defaults import default_estimators
from bots.readings import Readings
from bots.spec import BeliefSpec
from bots.uncertainty import square
from sim.kinematics import wrap_angle
from sim.run.loop import RobotSetup, run
from sim.world.spec import WorldSpec

ROBOTS = 1000
SPACING = 0.6  # m between robots: a 0.2 m circle and the body fit
RANDOM = {"encoders.slip_std": 0.002, "mouse.noise_std": 0.0003}  # 2 mm of slip a metre rolled; 0.3 mm of mouse noise a metre passed
BARE = CTBOT.with_changes(ir=(), line=(), border=(), light=())
TOLERANCES = BeliefSpec(0.003, 0.01, 0.0375, slip_std=0.002, tick_noise=0.0, mouse_noise_std=0.0003)
ROBOTS_OF = {
    "fine": with_settings(BARE.with_changes(encoders={"ticks_per_rev": 10**9}, mouse={"dpi": 1e9}), RANDOM)
    .with_changes(belief=BeliefSpec(0.0, 0.0, 0.0, slip_std=0.002, tick_noise=0.0, mouse_noise_std=0.0003)),
    "quantised": with_settings(BARE, {**RANDOM, "encoders.start_phase": "random", "mouse.start_phase": "random"})
    .with_changes(belief=BeliefSpec(0.0, 0.0, 0.0, slip_std=0.002, tick_noise=0.0, mouse_noise_std=0.0003)),
    "systematic": with_settings(BARE, {**RANDOM, "encoders.start_phase": "random", "mouse.start_phase": "random"}).with_changes(belief=TOLERANCES),
    "counted": with_settings(BARE, {"encoders.start_phase": "random", "mouse.start_phase": "random"})
    .with_changes(belief=BeliefSpec(0.0, 0.0, 0.0, slip_std=0.0, tick_noise=0.0, mouse_noise_std=0.0)),
}
SPEED_SPREAD = 0.003
"""Relative speed of each robot about the commanded one (uniform): the wheels of a 5 s run turn some
400 ticks, so 0.3 % spreads where they end within a tick over all fractions."""


def _robots(kind: str, rng: np.random.Generator) -> list:
    """ROBOTS descriptions of this kind: with systematic errors, each its own draw of them."""
    robot = ROBOTS_OF[kind]
    if kind != "systematic":
        return [robot] * ROBOTS
    said = robot.belief
    return [robot.with_changes(encoders={"diameter_error": tuple(rng.normal(0.0, said.wheel_diameter_std, 2)), "track_error": rng.normal(0.0, said.track_std)},
                               mouse={"scale_error": rng.normal(0.0, said.mouse_scale_std)}) for _ in range(ROBOTS)]  # fmt: skip


def _spread(kind: str, twist: Twist, duration: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Estimator -> (errors (N, 3) at the end, propagated covariances (N, 3, 3))."""
    side = math.ceil(math.sqrt(ROBOTS))
    world = WorldSpec("open floor", (-1.0, -1.0, side * SPACING + 1.0, side * SPACING + 1.0))
    starts = [((k % side) * SPACING, (k // side) * SPACING, 0.0) for k in range(ROBOTS)]
    rng = np.random.default_rng(49)
    speeds = 1.0 + SPEED_SPREAD * rng.uniform(-1.0, 1.0, ROBOTS) if kind != "fine" else np.ones(ROBOTS)
    setups = [RobotSetup(robot, FunctionController(lambda t, readings, f=f: Twist(f * twist.v, f * twist.omega)), start=start)
              for robot, start, f in zip(_robots(kind, rng), starts, speeds)]  # fmt: skip
    result = run(world, setups, duration, seed=3)
    out: dict[str, tuple[list, list]] = {}
    for log in result.robots:
        truth = log.truth_array()[-1]
        covariances = log.covariance_arrays()
        for label, poses in log.estimate_arrays().items():
            error = poses[-1] - truth
            error[2] = wrap_angle(error[2])
            errors, covs = out.setdefault(label, ([], []))
            errors.append(error)
            covs.append(square(covariances[label][-1]))
    return {label: (np.array(errors), np.array(covs)) for label, (errors, covs) in out.items()}


def _whitened_covariance(errors: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """The sample covariance of the errors, each whitened by its own propagated covariance (each
    robot's, linearised at its own estimate, differs a little; with systematic errors drawn, its
    estimate saw a path as much longer or shorter as its own errors make it)."""
    white = np.linalg.solve(np.linalg.cholesky(covs), errors[..., None])[..., 0]
    return np.cov(white - white.mean(axis=0), rowvar=False)


@pytest.fixture(scope="module", params=[("fine", "straight", Twist(0.2, 0.0), 5.0), ("fine", "circle", Twist(0.2, 1.0), 2 * math.pi),
                                        ("quantised", "circle", Twist(0.2, 1.0), 2 * math.pi), ("systematic", "circle", Twist(0.2, 1.0), 2 * math.pi)],
                ids=lambda p: f"{p[0]}-{p[1]}")  # fmt: skip
def spread(request):
    kind, _, twist, duration = request.param
    return _spread(kind, twist, duration)


FIRST_ORDER_FAILS = {
    ("systematic", "mouse"): "a 3.75 % resolution unknown over a full turn is 13.5 degrees of heading: the position error bends "
                             "away from the first-order covariance's direction (whitened spread 1.20 / 0.56 / 0.99 in x, y, heading)",
}
"""The scenarios whose covariance the Monte Carlo spread refutes, and why (see docs/odometry.md)."""


@pytest.mark.parametrize("label", ["encoders", "mouse", "fused"])
def test_propagated_covariance_is_the_monte_carlo_spread(spread, label, request):
    kind = request.node.callspec.params["spread"][0]
    if (kind, label) in FIRST_ORDER_FAILS:
        request.applymarker(pytest.mark.xfail(reason=FIRST_ORDER_FAILS[kind, label], strict=True))
    errors, covs = spread[label]
    assert np.linalg.eigvalsh(covs).min() > 0.0
    white = _whitened_covariance(errors, covs)
    n = len(errors)
    diagonal, off = 4 * math.sqrt(2 / (n - 1)), 4 / math.sqrt(n)
    assert np.abs(np.diag(white) - 1.0).max() < diagonal, np.round(white, 3)
    assert np.abs(white[~np.eye(3, dtype=bool)]).max() < off, np.round(white, 3)


def test_counters_started_anywhere_leave_an_offset_that_the_path_carries():
    """Encoders whose only error is counting (no slip, no calibration error; each counter started
    anywhere within a tick), 2 m straight: where the wheels' counters started turns the estimated
    heading by up to a tick's difference for the whole run, and the position drifts sideways by it
    (about 12 mm at 2 m); the covariance carries that (`bots.odometry.base.phase_offset`). Taken as
    the lag beside the covariance only, as before, the lateral error was not in it at all."""
    errors, covs = _spread("counted", Twist(0.2, 0.0), 10.0)["encoders"]
    assert np.std(errors[:, 1]) > 0.005  # (the drift is there to be carried)
    white = _whitened_covariance(errors, covs)
    n = len(errors)
    assert np.abs(np.diag(white) - 1.0).max() < 4 * math.sqrt(2 / (n - 1)), np.round(white, 3)
    assert np.abs(white[~np.eye(3, dtype=bool)]).max() < 4 / math.sqrt(n), np.round(white, 3)


def test_reported_covariances_ignore_the_simulated_errors():
    """The estimators believe the robot's stated tolerances (`RobotSpec.belief`), not the errors
    the simulation draws: robots that differ only in those, given the same readings, report the
    same covariances, bit for bit."""
    robots = [with_settings(CTBOT, NOISE_PRESETS[preset]) for preset in ("none", "realistic", "harsh")]
    robots.append(with_settings(CTBOT, {"encoders.track_error": -0.05, "encoders.diameter_error": [0.02, -0.01], "mouse.scale_error": 0.1}))
    rng = np.random.default_rng(49)
    readings = [Readings(time=0.01 * k, encoder_ticks=rng.integers(-1, 3, 2), mouse_counts=rng.integers(-3, 9, 2)) for k in range(300)]
    reported = []
    for robot in robots:
        estimators = default_estimators(robot)
        for estimator in estimators:
            estimator.reset(robot, np.zeros(3))
        covariances = []
        for step in readings:
            for estimator in estimators:
                estimator.update(step)
                covariances.append(estimator.covariance)
        reported.append(np.array(covariances))
    assert reported[0].any()
    for other in reported[1:]:
        np.testing.assert_array_equal(other, reported[0])


def test_a_belief_given_changes_the_covariance():
    """The belief is the robot's own (`[belief]`, an API change): a wider one reports more."""
    wide = with_settings(CTBOT, {"belief.track_std": 0.03})
    steps = [Readings(time=0.01 * k, encoder_ticks=np.array([-1, 1]), mouse_counts=np.array([0, 5])) for k in range(200)]
    spreads = []
    for robot in (CTBOT, wide):
        estimator = default_estimators(robot)[0]
        estimator.reset(robot, np.zeros(3))
        for step in steps:
            estimator.update(step)
        spreads.append(estimator.covariance[2, 2])
    assert spreads[1] > 4 * spreads[0]


def test_a_calibrated_belief_is_the_geometry_the_estimators_believe():
    """A belief that knows the robot's wheels and track (what `ctsim umbmark` writes) removes their
    systematic error: without random noise, over a minute of the maze, the encoders end within
    quantisation of the truth where the nominal belief ends far off."""
    from sim.experiments import Bot, simulate

    errors = {"encoders.diameter_error": (-0.004, 0.006), "encoders.track_error": 0.02}
    known = {"belief.diameter_correction": (-0.004, 0.006), "belief.track_correction": 0.02}
    ends = []
    for belief in ({}, known):
        result = simulate("maze", Bot("solve_maze", changes={**errors, **belief}), duration=60.0, noise="none")
        ends.append(result.robots[0].metrics["encoders"]["final_position_error"])
    assert ends[1] < 0.02 and ends[0] > 0.1  # (seen: 3 mm, some ticks of quantisation, against 0.64 m)


@pytest.mark.parametrize("phase", ["zero", "random", "realistic", "harsh"])
def test_counters_started_anywhere_carry_no_bias(phase):
    """c't-Sim starts each counter on an edge: the count then lags the wheel by half a tick on
    average (1.5 mm along the track on the c't-Bot), a bias no seed averages away. Started anywhere
    within a tick (`start_phase = "random"`, as a real wheel stops, and as the noise presets
    start them), the encoders' mean error along the track over 400 robots (each 0.3 % faster or
    slower, so that the wheels end at every fraction of a tick) is within 3 standard errors of
    zero; on an edge, half a tick behind."""
    robots = 400
    phases = {key: value for key, value in NOISE_PRESETS.get(phase, {}).items() if key.endswith("start_phase")}
    robot = with_settings(BARE, phases or {"encoders.start_phase": phase})
    rng = np.random.default_rng(4)
    speeds = 1.0 + SPEED_SPREAD * rng.uniform(-1.0, 1.0, robots)
    world = WorldSpec("open floor", (-1.0, -1.0, 21 * SPACING, 21 * SPACING))
    setups = [RobotSetup(robot, FunctionController(lambda t, readings, f=f: Twist(0.2 * f, 0.0)), start=((k % 20) * SPACING, (k // 20) * SPACING, 0.0))
              for k, f in enumerate(speeds)]  # fmt: skip
    result = run(world, setups, 3.0, seed=5)
    along = np.array([log.estimate_arrays()["encoders"][-1, 0] - log.truth_array()[-1, 0] for log in result.robots])
    tick = math.pi * BARE.wheel_diameter / BARE.encoders.ticks_per_rev
    mean, standard_error = along.mean(), along.std(ddof=1) / math.sqrt(robots)
    if robot.encoders.start_phase == "random":
        assert abs(mean) < 3 * standard_error, (mean, standard_error)
    else:
        assert mean == pytest.approx(-0.5 * tick, abs=3 * standard_error)
