"""The batched default odometry (`bots.odometry.batch`) against the Python estimators it stands in
for: the same poses, fused state and contact counts, bit for bit.

Exact equality, no tolerance: the kernel does the Python expressions' IEEE operations in the same
order with nothing fused (numba sets no fastmath flag), and its sin, cos and exp are the C
library's, as Python's math module's are."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import pose
from test_odometry import OPEN_FLOOR, Wanderer, curves

from bots.controller import FunctionController
from bots.ctbot import CTBOT
from bots.noise import with_noise
from bots.odometry.base import COUNT_VARIANCE, parameters, quantisation_lag
from bots.odometry.batch import COVARIANCES, DefaultOdometry, batched
from bots.odometry.defaults import default_estimators
from bots.odometry.encoder import EncoderOdometry
from bots.odometry.layout import DEAD_RECKONERS, ESTIMATE, ESTIMATES, SLIDE_WATCH, STATE
from bots.odometry.propagation import mouse_terms, wheel_terms
from bots.readings import Readings
from bots.uncertainty import ERRORS, square
from bots.wheeled import MECANUM4
from sim.kinematics import advance
from sim.kinematics.batch import advance_one
from sim.run.loop import RobotSetup, run
from sim.world.files import load_world

ROBOTS = {
    "ctbot": CTBOT,
    "no mouse": CTBOT.with_changes(mouse=None),
    "mouse on the axle": CTBOT.with_changes(mouse={"mount": (0.0, 0.01)}),
    "fine, mouse behind": CTBOT.with_changes(encoders={"ticks_per_rev": 2000}, mouse={"dpi": 1600.0, "mount": (-0.03, -0.005)}),
}


@given(pose, st.floats(-0.5, 0.5, allow_nan=False), st.one_of(st.floats(-3, 3, allow_nan=False), st.floats(-2e-4, 2e-4)), st.booleans())
def test_compiled_advance_is_advance_bit_for_bit(start, s, alpha, end_heading):
    assert advance_one(*start, s, alpha, end_heading) == tuple(advance(start, s, alpha, end_heading).tolist())


@st.composite
def tallies(draw, robot) -> tuple[int, int, int, int]:
    """One step's (ticks left, right, counts forward, lateral): wheels turning up to 20 ticks, the
    mouse reading about what they imply (off by a few counts, as quantisation and noise leave it)
    or, now and then, sliding sideways by up to 300 counts (wall contact)."""
    left, right = draw(st.integers(-20, 20)), draw(st.integers(-20, 20))
    per_tick = math.pi * robot.wheel_diameter / robot.encoders.ticks_per_rev
    s, alpha = 0.5 * (left + right) * per_tick, (right - left) * per_tick / robot.track_width
    if robot.mouse is None:
        return left, right, draw(st.integers(-300, 300)), draw(st.integers(-300, 300))
    per_metre = robot.mouse.dpi / 0.0254
    mount_x, mount_y = robot.mouse.mount
    forward = round((s - alpha * mount_y) * per_metre) + draw(st.integers(-3, 3))
    lateral = round(alpha * mount_x * per_metre) + draw(st.one_of(st.integers(-3, 3), st.integers(-300, 300)))
    return left, right, forward, lateral


@st.composite
def robots_and_steps(draw):
    """A few robots (some kinds twice), their start poses, each step's time and every robot's
    tallies; the batch takes its robots' rows out of a world's tallies that hold one more robot."""
    names = draw(st.lists(st.sampled_from(sorted(ROBOTS)), min_size=1, max_size=4))
    robots = [ROBOTS[name] for name in names]
    starts = [draw(pose) for _ in robots]
    count = draw(st.integers(1, 40))
    # steps of 10 ms mostly; a repeated or earlier time (the rule forgets nothing then) now and then
    gaps = draw(st.lists(st.sampled_from((0.01, 0.01, 0.01, 0.0, -0.01, 0.5)), min_size=count, max_size=count))
    times = np.cumsum([0.0, *gaps[1:]]).tolist()
    steps = [np.array([draw(tallies(robot)) for robot in robots] + [(7, -7, 99, -99)], dtype=np.int64) for _ in range(count)]
    return robots, starts, times, steps


@settings(max_examples=200)
@given(robots_and_steps(), st.permutations(range(5)))
def test_batch_steps_as_the_python_estimators(case, order):
    """Random robots and readings: every estimate, its error covariance and the covariance it
    reports, the sigma points and their random parts, the fused estimator's state, calibration and
    contact count equal the Python estimators' after every step."""
    robots, starts, times, steps = case
    n = len(robots)
    rows = [r for r in order if r < n + 1][:n]  # each robot's row in the tallies, shuffled
    batch = DefaultOdometry(robots, np.array(starts), rows)
    python = []
    for robot, start in zip(robots, starts):
        chosen = default_estimators(robot)
        for estimator in chosen:
            estimator.reset(robot, start)
        python.append(chosen)
    assert batch.names == [[e.name for e in chosen] for chosen in python]
    for time, per_robot in zip(times, steps):
        world_tallies = np.empty((n + 1, 4), dtype=np.int64)
        world_tallies[rows + [sorted(set(range(n + 1)) - set(rows))[0]]] = per_robot
        out, cov_out = np.zeros((n, 1 + ESTIMATES, 3)), np.zeros((n, ESTIMATES, COVARIANCES))
        batch.update(world_tallies, time, np.zeros((n + 1, 3)), out, cov_out)
        for k, chosen in enumerate(python):
            readings = Readings(time, encoder_ticks=per_robot[k, :2].copy(), mouse_counts=per_robot[k, 2:].copy())
            for estimator in chosen:
                estimator.update(readings)
            estimates = batch.rows_of(k)
            assert len(estimates) == len(chosen)
            for j, (estimator, estimate) in enumerate(zip(chosen, estimates)):
                assert estimate.tolist() == estimator.pose.tolist(), estimator.name
                assert batch.errors[k, j].tolist() == estimator.errors.tolist(), estimator.name
                assert square(cov_out[k, j]).tolist() == estimator.covariance.tolist(), estimator.name
            if len(chosen) == 4:
                fused = chosen[ESTIMATE.fused]
                detectors = [f.name for f in STATE.fields if f.kind == np.float64 and f.width == 1]
                assert [batch.state[k][name] for name in detectors] == [fused.state[name] for name in detectors], "the detectors' state"
                for estimator, watch in ((chosen[ESTIMATE.mouse], "mouse_watch"), (fused, "fused_watch")):
                    for field in SLIDE_WATCH.dtype.names:  # (field by field: the hypothesis is a pose)
                        assert np.asarray(batch.state[k][watch][field]).tolist() == np.asarray(estimator.state[watch][field]).tolist(), f"the slide watch's {field}"
                assert batch.calibration[k].tolist() == fused.calibration.tolist()
                assert batch.contact_steps[k] == fused.contact_steps
            for j, estimator in enumerate(chosen[:DEAD_RECKONERS]):
                assert batch.state[k]["sigmas"][j].tolist() == estimator.sigmas.tolist(), "the sigma points"
                assert batch.state[k]["sigma_noises"][j].tolist() == estimator.noises.tolist(), "the sigma points' random parts"

def test_general_chassis_stays_with_the_python_estimators():
    assert batched(CTBOT) and not batched(MECANUM4)


def test_tallies_of_the_wrong_shape_are_refused():
    batch = DefaultOdometry([CTBOT, CTBOT], np.zeros((2, 3)), [0, 2])
    for wrong in (np.zeros((2, 4), dtype=np.int64), np.zeros((3, 2), dtype=np.int64)):
        with pytest.raises(ValueError, match="tallies must be"):
            batch.update(wrong, 0.0)


def test_noisy_run_logs_the_python_estimators_estimates():
    """The naive Wanderer in the maze with realistic noise (slip, spurious ticks, mouse noise
    and scale error) scraping walls: the run's default estimates (batched) equal those of the same
    run with the Python estimators given as its own."""
    robot = with_noise(CTBOT, "realistic")

    def estimates(chosen):
        result = run(load_world("maze"), [RobotSetup(robot, Wanderer(), estimators=chosen)], 30.0, seed=7)
        return result.robots[0]

    batched_log, python_log = estimates(None), estimates(default_estimators(robot))
    np.testing.assert_array_equal(batched_log.truth_array(), python_log.truth_array())
    assert batched_log.estimate_arrays().keys() == python_log.estimate_arrays().keys()
    for name, poses in batched_log.estimate_arrays().items():
        np.testing.assert_array_equal(poses, python_log.estimate_arrays()[name], err_msg=name)
    # the walls were met and the slide rule took over: the fused heading left the mouse's
    fused, mouse = batched_log.estimate_arrays()["fused"], batched_log.estimate_arrays()["mouse"]
    assert batched_log.collisions > 0 and not np.array_equal(fused[:, 2], mouse[:, 2])


def test_robots_with_own_and_default_estimators_side_by_side():
    """Three robots in one run, the first with its own estimator list: the other two's batched
    defaults (one with a mouse, one without) land in their own logs, as their Python defaults do."""
    robots = [CTBOT, CTBOT, CTBOT.with_changes(mouse=None)]
    starts = [(0.0, 0.0, 0.3), (0.0, 5.0, 0.0), (0.0, -5.0, 1.0)]

    def logs(defaults):
        setups = [
            RobotSetup(robot, FunctionController(curves), start=start, estimators=[EncoderOdometry()] if k == 0 else defaults(robot))
            for k, (robot, start) in enumerate(zip(robots, starts))
        ]
        return run(OPEN_FLOOR, setups, 5.0).robots

    batched_logs, python_logs = logs(lambda robot: None), logs(default_estimators)
    assert [list(log.estimate_arrays()) for log in batched_logs] == [["encoders"], ["encoders", "firmware", "mouse", "fused"], ["encoders", "firmware"]]
    for batched_log, python_log in zip(batched_logs, python_logs):
        for name, poses in batched_log.estimate_arrays().items():
            np.testing.assert_array_equal(poses, python_log.estimate_arrays()[name], err_msg=name)


@pytest.mark.parametrize("noise", ["none", "realistic", "harsh"])
def test_the_reset_lag_is_the_compiled_error_models_without_compiling_them(noise):
    """`quantisation_lag` runs the error models' Python functions at a reset (so that the first
    run compiles every kernel in the compile processes, none here): the same numbers, bit for bit."""
    p = parameters(with_noise(CTBOT, noise))
    for mouse, kernel, arguments in ((False, wheel_terms, (0.0, 0.0, 0.0, p["track"], COUNT_VARIANCE * p["tick_left"] ** 2, COUNT_VARIANCE * p["tick_right"] ** 2)),
                                     (True, mouse_terms, (0.0, 0.0, p["mount_x"], p["mount_y"], COUNT_VARIANCE / p["per_metre"] ** 2))):  # fmt: skip
        compiled, jac = np.zeros((2, 2)), np.zeros((2, ERRORS))
        kernel(*arguments, jac, compiled)
        assert quantisation_lag(p, mouse).tobytes() == compiled.tobytes()
