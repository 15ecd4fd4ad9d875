"""The propagated covariance of the odometry against Monte Carlo: 1,000 robots with their own
noise (each its own generators, spawned from the run's seed as every robot's are) drive the same
commands on open floor; the spread of their estimates' errors at the end must be the covariance
each estimator propagated.

The robot's encoders and mouse are fine enough that quantisation is below a nanometre (its lag,
a bias shared by all robots, would not show in a spread anyway), so what is compared is the
random noise: slip on the wheels, count noise on the mouse. Sampling error: whitened by the
propagated covariance, the errors' sample covariance is the identity within sampling error, its
diagonal entries with a standard deviation of sqrt(2/N) = 0.045 and the others 1/sqrt(N) = 0.032
for N = 1,000; the test allows 4 of them (a false alarm once in about 5,000 runs per entry).
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
NOISY = with_settings(
    CTBOT.with_changes(encoders={"ticks_per_rev": 10**9}, mouse={"dpi": 1e9}, ir=(), line=(), border=(), light=()),
    {"encoders.slip_std": 0.002, "mouse.noise_std": 0.0003},  # 2 mm of slip a metre rolled; 0.3 mm of mouse noise a metre passed
).with_changes(belief=BeliefSpec(0.0, 0.0, 0.0, slip_std=0.002, tick_noise=0.0, mouse_noise_std=0.0003))  # told the truth: what is tested is the propagation


def _spread(twist: Twist, duration: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Estimator -> (errors (N, 3) at the end, propagated covariances (N, 3, 3))."""
    side = math.ceil(math.sqrt(ROBOTS))
    world = WorldSpec("open floor", (-1.0, -1.0, side * SPACING + 1.0, side * SPACING + 1.0))
    starts = [((k % side) * SPACING, (k // side) * SPACING, 0.0) for k in range(ROBOTS)]
    setups = [RobotSetup(NOISY, FunctionController(lambda t, readings: twist), start=start) for start in starts]
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


def _whitened_covariance(errors: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """The sample covariance of the errors whitened by the propagated covariance."""
    whiten = np.linalg.inv(np.linalg.cholesky(cov))
    return np.cov((errors - errors.mean(axis=0)) @ whiten.T, rowvar=False)


@pytest.fixture(scope="module", params=[("straight", Twist(0.2, 0.0), 5.0), ("circle", Twist(0.2, 1.0), 2 * math.pi)], ids=lambda p: p[0])
def spread(request):
    _, twist, duration = request.param
    return _spread(twist, duration)


@pytest.mark.parametrize("label", ["encoders", "mouse", "fused"])
def test_propagated_covariance_is_the_monte_carlo_spread(spread, label):
    errors, covs = spread[label]
    mean = covs.mean(axis=0)  # (each robot's, linearised at its own estimate, differs a little)
    assert np.linalg.norm(covs - mean, axis=(1, 2)).max() < 0.05 * np.linalg.norm(mean)
    assert np.linalg.eigvalsh(mean).min() > 0.0
    white = _whitened_covariance(errors, mean)
    n = len(errors)
    diagonal, off = 4 * math.sqrt(2 / (n - 1)), 4 / math.sqrt(n)
    assert np.abs(np.diag(white) - 1.0).max() < diagonal, np.round(white, 3)
    assert np.abs(white[~np.eye(3, dtype=bool)]).max() < off, np.round(white, 3)


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
