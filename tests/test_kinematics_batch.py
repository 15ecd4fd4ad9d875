"""Batches: N robots in one call give the numbers of N single calls, and the fused numba kernel
`step_batch` reproduces the numpy reference (poses to rounding, ticks and counts exactly)."""

from __future__ import annotations

import math

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
from sim.kinematics.batch import step_batch, step_batch_parallel

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
    """(steps, robots, 2) wheel arcs: ordinary driving, straight lines, spins, reversing, sharp turns
    beyond the series limit (|alpha| > 0.5 needs |s_r - s_l| > 48.6 mm), and standing still."""
    arcs = rng.uniform(-0.0045, 0.0045, size=(steps, robots, 2))
    kind = rng.integers(0, 6, size=(steps, robots))
    arcs[kind == 1, 1] = arcs[kind == 1, 0]  # straight
    arcs[kind == 2, 1] = -arcs[kind == 2, 0]  # spin on the spot
    arcs[kind == 3] = -np.abs(arcs[kind == 3])  # reversing
    arcs[kind == 4] = rng.uniform(-0.08, 0.08, size=(np.count_nonzero(kind == 4), 2))  # sharp
    arcs[kind == 5] = 0.0  # standing
    return arcs


@pytest.mark.parametrize("seed", (1, 2))
def test_step_batch_matches_the_numpy_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    robots, steps = 100, 300
    mount = np.array(CTBOT.mouse.mount)
    tpm = float(ticks_per_metre(WHEEL_RADIUS))
    cpm = float(counts_per_metre(CTBOT.mouse.dpi))
    start = np.column_stack((rng.uniform(-2, 2, (robots, 2)), rng.uniform(-math.pi, math.pi, robots)))
    arcs = _random_wheel_arcs(rng, steps, robots)

    pose = start.copy()
    heading_dir = np.column_stack((np.cos(pose[:, 2]), np.sin(pose[:, 2])))
    tick_carry = rng.uniform(0, 1, (robots, 2))
    mouse_carry = rng.uniform(0, 1, (robots, 2))
    ticks = np.zeros((robots, 2), dtype=np.int64)
    counts = np.zeros((robots, 2), dtype=np.int64)

    ref_pose, ref_tick_carry, ref_mouse_carry = start.copy(), tick_carry.copy(), mouse_carry.copy()
    total_ticks = np.zeros((robots, 2), dtype=np.int64)
    for k in range(steps):
        step_batch(pose, heading_dir, arcs[k], TRACK, tpm, tick_carry, ticks, mount, cpm, mouse_carry, counts)

        s, a = wheel_arcs_to_arc(arcs[k, :, 0], arcs[k, :, 1], TRACK)
        ref_pose = apply_increment(ref_pose, arc_increment(s, a))
        ref_ticks, ref_tick_carry = ticks_from_arcs(arcs[k], ref_tick_carry, WHEEL_RADIUS)
        ref_counts, ref_mouse_carry = mouse_counts(mouse_displacement(s, a, mount), ref_mouse_carry, CTBOT.mouse.dpi)

        np.testing.assert_allclose(pose, ref_pose, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(ticks, ref_ticks)
        np.testing.assert_array_equal(counts, ref_counts)
        np.testing.assert_allclose(tick_carry, ref_tick_carry, rtol=0, atol=1e-12)
        np.testing.assert_allclose(mouse_carry, ref_mouse_carry, rtol=0, atol=1e-12)
        assert np.all((tick_carry >= 0) & (tick_carry < 1)) and np.all((mouse_carry >= 0) & (mouse_carry < 1))
        total_ticks += ticks
    # the carried heading direction stayed a unit vector along the heading
    np.testing.assert_allclose(heading_dir, np.column_stack((np.cos(pose[:, 2]), np.sin(pose[:, 2]))), rtol=0, atol=1e-12)
    # and the encoders did not drift over the run
    travelled = arcs.sum(axis=0) * tpm
    assert np.all(np.abs(total_ticks - travelled) <= 1)


def test_step_batch_keeps_the_carry_below_one() -> None:
    """A total just below zero: floor gives -1 and the fraction rounds to 1.0; like `quantize`, the
    kernel counts 0 and carries 0."""
    tpm = float(ticks_per_metre(WHEEL_RADIUS))
    pose = np.zeros((1, 3))
    heading_dir = np.array([[1.0, 0.0]])
    tiny = -1e-20 / tpm
    arcs = np.array([[tiny, tiny]])
    tick_carry = np.zeros((1, 2))
    ticks = np.zeros((1, 2), dtype=np.int64)
    mouse_carry = np.zeros((1, 2))
    counts = np.zeros((1, 2), dtype=np.int64)
    step_batch(pose, heading_dir, arcs, TRACK, tpm, tick_carry, ticks, np.array([-0.015, 0.0]), 1.0, mouse_carry, counts)
    ref_ticks, ref_carry = ticks_from_arcs(arcs[0], np.zeros(2), WHEEL_RADIUS)
    np.testing.assert_array_equal(ticks[0], ref_ticks)
    np.testing.assert_array_equal(tick_carry[0], ref_carry)
    assert np.all((tick_carry >= 0) & (tick_carry < 1))


@pytest.mark.parametrize("robots", (1, 7, 5000))
def test_parallel_step_batch_is_bit_identical_to_the_serial_one(robots: int) -> None:
    """Split over threads (5000 robots: several chunks per thread), the parallel kernel gives the same
    bits for every pose, heading, carry, tick and count over 50 steps of mixed arcs, sharp turns
    (the trig branch) included."""
    rng = np.random.default_rng(robots)
    arcs = _random_wheel_arcs(rng, 50, robots)
    start = np.column_stack((rng.uniform(-2, 2, (robots, 2)), rng.uniform(-math.pi, math.pi, robots)))

    def state() -> list[np.ndarray]:
        pose = start.copy()
        heading_dir = np.column_stack((np.cos(pose[:, 2]), np.sin(pose[:, 2])))
        carries = np.random.default_rng(0).uniform(0, 1, (2, robots, 2))
        return [pose, heading_dir, carries[0], np.zeros((robots, 2), np.int64), carries[1], np.zeros((robots, 2), np.int64)]

    serial, parallel = state(), state()
    mount = np.array(CTBOT.mouse.mount)
    tpm, cpm = float(ticks_per_metre(WHEEL_RADIUS)), float(counts_per_metre(CTBOT.mouse.dpi))
    for k in range(50):
        for kernel, (pose, heading_dir, tick_carry, ticks, mouse_carry, counts) in ((step_batch, serial), (step_batch_parallel, parallel)):
            kernel(pose, heading_dir, arcs[k], TRACK, tpm, tick_carry, ticks, mount, cpm, mouse_carry, counts)
        for a, b in zip(serial, parallel):
            assert a.tobytes() == b.tobytes()
