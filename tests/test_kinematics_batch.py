"""Batches: N robots in one call give the numbers of N single calls, and the numba kernels
`step_batch` (fused) and `step_poses` reproduce the numpy reference (poses to rounding, ticks and
counts exactly), serial and parallel bit for bit."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import (
    TRACK,
    WHEEL_RADIUS,
    alpha,
    arc_length,
    floats,
    mount_point,
    pose,
    track_width,
    wheel_arc,
)

from bots.ctbot import CTBOT
from sim.kinematics import (
    MouseEstimator,
    apply_increment,
    arc_increment,
    counts_per_metre,
    integrate_arcs,
    mouse_counts,
    mouse_displacement,
    mouse_displacement_from_increment,
    quantize,
    ticks_from_arcs,
    ticks_per_metre,
    wheel_arcs_to_arc,
    wheel_increment,
)
from sim.kinematics.batch import Counters, Drive, step_batch, step_batch_parallel, step_poses, step_poses_parallel

carry = floats(0.0, 1.0, exclude_max=True)


@given(st.lists(st.tuples(arc_length, alpha), min_size=1, max_size=30))
@settings(max_examples=60)
def test_arc_increment_batch_equals_single_calls(arcs: list[tuple[float, float]]) -> None:
    s, a = np.array(arcs).T
    batch = arc_increment(s, a)
    assert batch.shape == (len(arcs), 3)
    for k, (s_k, a_k) in enumerate(arcs):
        np.testing.assert_array_equal(batch[k], arc_increment(s_k, a_k))


@given(st.lists(st.tuples(wheel_arc, wheel_arc, track_width), min_size=1, max_size=30))
@settings(max_examples=60)
def test_wheel_increment_with_per_robot_track_widths(wheels: list[tuple[float, float, float]]) -> None:
    s_l, s_r, track = np.array(wheels).T
    batch = wheel_increment(s_l, s_r, track)
    for k, (l_k, r_k, b_k) in enumerate(wheels):
        np.testing.assert_array_equal(batch[k], wheel_increment(l_k, r_k, b_k))


@given(st.lists(st.tuples(pose, arc_length, arc_length, alpha), min_size=1, max_size=30))
@settings(max_examples=60)
def test_apply_increment_batch_equals_single_calls(rows: list) -> None:
    poses = np.array([r[0] for r in rows])
    increments = np.array([r[1:] for r in rows])
    batch = apply_increment(poses, increments)
    for k in range(len(rows)):
        np.testing.assert_array_equal(batch[k], apply_increment(poses[k], increments[k]))
    # one pose, many increments, and many poses, one increment, broadcast the same way
    np.testing.assert_array_equal(apply_increment(poses[0], increments)[-1], apply_increment(poses[0], increments[-1]))
    np.testing.assert_array_equal(apply_increment(poses, increments[0])[-1], apply_increment(poses[-1], increments[0]))


@given(st.lists(st.tuples(floats(-1e4, 1e4), carry), min_size=1, max_size=30))
@settings(max_examples=60)
def test_quantize_batch_equals_single_calls(rows: list[tuple[float, float]]) -> None:
    values, carries = np.array(rows).T
    counts, rest = quantize(values, carries)
    for k, (v, c) in enumerate(rows):
        n_k, c_k = quantize(v, c)
        assert counts[k] == n_k and rest[k] == c_k


@given(st.lists(st.tuples(arc_length, alpha, mount_point(), st.tuples(carry, carry)), min_size=1, max_size=20))
@settings(max_examples=60)
def test_mouse_functions_batch_equal_single_calls(rows: list) -> None:
    s = np.array([r[0] for r in rows])
    a = np.array([r[1] for r in rows])
    mounts = np.array([r[2] for r in rows])
    carries = np.array([r[3] for r in rows])
    dpi = float(CTBOT.mouse.dpi)
    displacement = mouse_displacement(s, a, mounts)
    from_increment = mouse_displacement_from_increment(arc_increment(s, a), mounts)
    counts, rest = mouse_counts(displacement, carries, dpi)
    for k in range(len(rows)):
        np.testing.assert_array_equal(displacement[k], mouse_displacement(s[k], a[k], mounts[k]))
        np.testing.assert_array_equal(from_increment[k], mouse_displacement_from_increment(arc_increment(s[k], a[k]), mounts[k]))
        n_k, c_k = mouse_counts(displacement[k], carries[k], dpi)
        np.testing.assert_array_equal(counts[k], n_k)
        np.testing.assert_array_equal(rest[k], c_k)
        estimator = MouseEstimator(mount=tuple(mounts[k]), dpi=dpi)
        # one robot's estimator over a batch of steps equals step-by-step estimates
        np.testing.assert_array_equal(estimator.increment(counts)[k], estimator.increment(counts[k]))


@given(st.lists(st.tuples(wheel_arc, wheel_arc), min_size=1, max_size=40), st.integers(1, 8))
@settings(max_examples=30)
def test_integrate_arcs_over_a_batch_of_robots(wheels: list[tuple[float, float]], robots: int) -> None:
    rng = np.random.default_rng(len(wheels) * 10 + robots)
    wheel_arcs = np.array(wheels)[:, None, :] * rng.uniform(-1, 1, size=(1, robots, 2))
    starts = rng.uniform(-5, 5, size=(robots, 3))
    s, a = wheel_arcs_to_arc(wheel_arcs[..., 0], wheel_arcs[..., 1], TRACK)
    batch = integrate_arcs(starts, s, a)
    assert batch.shape == (len(wheels), robots, 3)
    for i in range(robots):
        np.testing.assert_allclose(batch[:, i], integrate_arcs(starts[i], s[:, i], a[:, i]), rtol=0, atol=1e-15)


def _random_wheel_arcs(rng: np.random.Generator, steps: int, robots: int) -> np.ndarray:
    """(steps, 2, robots) wheel arcs, rows s_l, s_r: ordinary driving, straight lines, spins,
    reversing, sharp turns beyond the series limit (|alpha| > 0.5 needs |s_r - s_l| > 48.6 mm), and
    standing still."""
    arcs = rng.uniform(-0.0045, 0.0045, size=(steps, robots, 2))
    kind = rng.integers(0, 6, size=(steps, robots))
    arcs[kind == 1, 1] = arcs[kind == 1, 0]  # straight
    arcs[kind == 2, 1] = -arcs[kind == 2, 0]  # spin on the spot
    arcs[kind == 3] = -np.abs(arcs[kind == 3])  # reversing
    arcs[kind == 4] = rng.uniform(-0.08, 0.08, size=(np.count_nonzero(kind == 4), 2))  # sharp
    arcs[kind == 5] = 0.0  # standing
    return np.ascontiguousarray(arcs.transpose(0, 2, 1))


def _heading_dir(pose: np.ndarray) -> np.ndarray:
    return np.stack((np.cos(pose[2]), np.sin(pose[2])))


@pytest.mark.parametrize("seed", (1, 2))
def test_step_batch_matches_the_numpy_reference(seed: int) -> None:
    """Poses within 1e-12 m (rad) of the reference over 300 steps: both round differently (the
    kernel carries cos/sin of the heading, the reference takes them fresh each step), a few 1e-16
    relative per step on coordinates of at most a few metres, and 300 steps keep that far below
    1e-12. Ticks, counts and carries equal the reference's exactly: the kernel counts with the
    reference's operations in the reference's order."""
    rng = np.random.default_rng(seed)
    robots, steps = 100, 300
    mount = np.array(CTBOT.mouse.mount)
    tpm = float(ticks_per_metre(WHEEL_RADIUS))
    cpm = float(counts_per_metre(CTBOT.mouse.dpi))
    start = np.stack((*rng.uniform(-2, 2, (2, robots)), rng.uniform(-math.pi, math.pi, robots)))
    arcs = _random_wheel_arcs(rng, steps, robots)

    pose = start.copy()
    heading_dir = _heading_dir(pose)
    tick_carry = rng.uniform(0, 1, (2, robots))
    mouse_carry = rng.uniform(0, 1, (2, robots))
    ticks = np.zeros((2, robots), dtype=np.int64)
    counts = np.zeros((2, robots), dtype=np.int64)

    ref_pose, ref_tick_carry, ref_mouse_carry = start.T.copy(), tick_carry.T.copy(), mouse_carry.T.copy()
    total_ticks = np.zeros((2, robots), dtype=np.int64)
    for k in range(steps):
        step_batch(pose, heading_dir, arcs[k], Drive(TRACK, tpm, *mount, cpm), Counters(tick_carry, ticks, mouse_carry, counts))

        s, a = wheel_arcs_to_arc(arcs[k, 0], arcs[k, 1], TRACK)
        ref_pose = apply_increment(ref_pose, arc_increment(s, a))
        ref_ticks, ref_tick_carry = ticks_from_arcs(arcs[k].T, ref_tick_carry, WHEEL_RADIUS)
        ref_counts, ref_mouse_carry = mouse_counts(mouse_displacement(s, a, mount), ref_mouse_carry, CTBOT.mouse.dpi)

        np.testing.assert_allclose(pose, ref_pose.T, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(ticks, ref_ticks.T)
        np.testing.assert_array_equal(counts, ref_counts.T)
        np.testing.assert_array_equal(tick_carry, ref_tick_carry.T)
        np.testing.assert_array_equal(mouse_carry, ref_mouse_carry.T)
        assert np.all((tick_carry >= 0) & (tick_carry < 1)) and np.all((mouse_carry >= 0) & (mouse_carry < 1))
        total_ticks += ticks
    # the carried heading direction stayed a unit vector along the heading
    np.testing.assert_allclose(heading_dir, _heading_dir(pose), rtol=0, atol=1e-12)
    # and the encoders did not drift over the run
    travelled = arcs.sum(axis=0) * tpm
    assert np.all(np.abs(total_ticks - travelled) <= 1)


def test_step_poses_moves_as_step_batch() -> None:
    """The pose-only kernel is the fused kernel's arc pass: the same bits."""
    rng = np.random.default_rng(3)
    robots = 700
    arcs = _random_wheel_arcs(rng, 20, robots)
    pose = np.stack((*rng.uniform(-2, 2, (2, robots)), rng.uniform(-math.pi, math.pi, robots)))
    fused = [pose.copy(), _heading_dir(pose)]
    alone = [pose.copy(), _heading_dir(pose)]
    counting = [np.zeros((2, robots)), np.zeros((2, robots), np.int64), np.zeros((2, robots)), np.zeros((2, robots), np.int64)]
    mount = np.array(CTBOT.mouse.mount)
    for k in range(20):
        step_batch(*fused, arcs[k], Drive(TRACK, 100.0, *mount, 1000.0), Counters(*counting))
        step_poses(*alone, arcs[k], TRACK)
    for a, b in zip(fused, alone):
        assert a.tobytes() == b.tobytes()


@numba.njit
def _drive(pose: np.ndarray, heading_dir: np.ndarray, arcs: np.ndarray, track: float) -> None:
    for k in range(arcs.shape[0]):
        step_poses(pose, heading_dir, arcs[k], track)


def test_carried_heading_direction_does_not_drift_over_a_million_steps() -> None:
    """heading_dir is rotated, never recomputed from θ, so its rounding could build up. Each step
    rotates it twice by the half angle (four products and two sums per component, a relative error
    of at most about 3ε each with ε = 2⁻⁵³), the half-angle series itself is good to
    about 2ε, and the Newton step puts back the length to within about 2ε: at most 16ε of direction
    error per step, so 1.8e-9 rad over 10⁶ steps in the worst case (rounding errors that all push
    the same way; a random walk would stay near 1e-13). The heading to compare with is the exactly
    rounded sum of the steps' α (math.fsum), so that θ's own rounding does not enter."""
    steps, robots = 1_000_000, 4
    rng = np.random.default_rng(7)
    arcs = rng.uniform(-0.0045, 0.0045, size=(steps, 2, robots))
    arcs[: steps // 2, 1, 0] = arcs[: steps // 2, 0, 0] + 0.004  # a robot turning one way for half the run
    pose = np.zeros((3, robots))
    heading_dir = np.stack((np.ones(robots), np.zeros(robots)))
    _drive(pose, heading_dir, arcs, TRACK)
    alpha = (arcs[:, 1] - arcs[:, 0]) / TRACK
    for i in range(robots):
        theta = math.fsum(alpha[:, i])
        c, s = heading_dir[:, i]
        error = math.atan2(s * math.cos(theta) - c * math.sin(theta), c * math.cos(theta) + s * math.sin(theta))
        assert abs(error) <= steps * 16 * 2.0**-53
        assert abs(math.hypot(c, s) - 1.0) <= 4 * 2.0**-53


def test_step_batch_keeps_the_carry_below_one() -> None:
    """A total just below zero: floor gives -1 and the fraction rounds to 1.0; like `quantize`, the
    kernel counts 0 and carries 0."""
    tpm = float(ticks_per_metre(WHEEL_RADIUS))
    pose = np.zeros((3, 1))
    heading_dir = np.array([[1.0], [0.0]])
    tiny = -1e-20 / tpm
    arcs = np.array([[tiny], [tiny]])
    tick_carry = np.zeros((2, 1))
    ticks = np.zeros((2, 1), dtype=np.int64)
    mouse_carry = np.zeros((2, 1))
    counts = np.zeros((2, 1), dtype=np.int64)
    step_batch(pose, heading_dir, arcs, Drive(TRACK, tpm, -0.015, 0.0, 1.0), Counters(tick_carry, ticks, mouse_carry, counts))
    ref_ticks, ref_carry = ticks_from_arcs(arcs[:, 0], np.zeros(2), WHEEL_RADIUS)
    np.testing.assert_array_equal(ticks[:, 0], ref_ticks)
    np.testing.assert_array_equal(tick_carry[:, 0], ref_carry)
    assert np.all((tick_carry >= 0) & (tick_carry < 1))


def test_kernels_refuse_rows_of_the_wrong_shape() -> None:
    """Robots in rows (N, 3) instead of columns (3, N) would be read past their end: a clear error."""
    pose = np.zeros((5, 3))
    with pytest.raises(ValueError, match=r"pose must be \(3, N\)"):
        step_poses(pose, np.zeros((2, 3)), np.zeros((2, 3)), TRACK)
    with pytest.raises(ValueError, match=r"pose must be \(3, N\)"):
        step_batch(np.zeros((3, 4)), np.zeros((2, 4)), np.zeros((2, 4)), Drive(TRACK, 1.0, 0.0, 0.0, 1.0),
                   Counters(np.zeros((2, 4)), np.zeros((2, 3), np.int64), np.zeros((2, 4)), np.zeros((2, 4), np.int64)))


# robot counts where the threads' parts and their SIMD remainders (4 or 8 lanes) fall differently
robot_counts = st.one_of(st.sampled_from((0, 1, 2, 3, 5, 7, 9, 17, 511, 513, 2051)), st.integers(0, 1600))


@given(robot_counts, st.integers(0, 2**32 - 1))
@settings(max_examples=40)
def test_parallel_kernels_are_bit_identical_to_the_serial_ones(robots: int, seed: int) -> None:
    """Split over threads, the parallel kernels give the same bits for every pose, heading, carry,
    tick and count over 12 steps of mixed arcs, sharp turns (the trig path) included."""
    rng = np.random.default_rng(seed)
    arcs = _random_wheel_arcs(rng, 12, robots)
    start = np.stack((*rng.uniform(-2, 2, (2, robots)), rng.uniform(-math.pi, math.pi, robots)))

    def state() -> list[np.ndarray]:
        carries = np.random.default_rng(seed).uniform(0, 1, (2, 2, robots))
        return [start.copy(), _heading_dir(start), carries[0], np.zeros((2, robots), np.int64), carries[1], np.zeros((2, robots), np.int64)]

    serial, parallel = state(), state()
    poses_serial, poses_parallel = state()[:2], state()[:2]
    mount = np.array(CTBOT.mouse.mount)
    tpm, cpm = float(ticks_per_metre(WHEEL_RADIUS)), float(counts_per_metre(CTBOT.mouse.dpi))
    for k in range(12):
        for kernel, (poses, heading_dir, tick_carry, ticks, mouse_carry, counts) in ((step_batch, serial), (step_batch_parallel, parallel)):
            kernel(poses, heading_dir, arcs[k], Drive(TRACK, tpm, *mount, cpm), Counters(tick_carry, ticks, mouse_carry, counts))
        step_poses(*poses_serial, arcs[k], TRACK)
        step_poses_parallel(*poses_parallel, arcs[k], TRACK)
        for a, b in zip(serial + poses_serial, parallel + poses_parallel):
            assert a.tobytes() == b.tobytes()
