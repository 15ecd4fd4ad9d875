"""Issue 16: robots are kept apart through a grid broad phase that cuts exactly the moves the check
of all pairs cut (same pairs, same order, same arithmetic)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.world.kernels.contacts import _contact_time, keep_apart
from sim.world.kernels.grids import near_pairs, stable_order


def keep_apart_all_pairs(pose: np.ndarray, move: np.ndarray, reach: np.ndarray) -> None:
    """The reference: every pair, in order, with the rule of `keep_apart`."""
    n = len(pose)
    for _ in range(100):
        changed = False
        for i in range(n):
            for j in range(i + 1, n):
                t = _contact_time(pose, move, reach, i, j)
                if t < 1.0 - 1e-12:
                    move[i] *= t
                    move[j] *= t
                    changed = True
        if not changed:
            return
    for i in range(n):
        for j in range(i + 1, n):
            if _contact_time(pose, move, reach, i, j) < 1.0:
                move[i] = move[j] = 0.0


def crowd(seed: int, count: int, spread: float, step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    pose = np.column_stack((rng.uniform(-spread, spread, (count, 2)), np.zeros(count)))
    move = rng.uniform(-step, step, (count, 2))
    reach = rng.uniform(0.03, 0.06, count)
    return pose, move, reach


@given(st.integers(0, 2**32 - 1), st.integers(2, 80), st.sampled_from([0.2, 0.5, 2.0, 500.0]), st.sampled_from([0.001, 0.01, 0.1]))
@settings(max_examples=120)
def test_grid_cuts_the_moves_all_pairs_cut(seed: int, count: int, spread: float, step: float) -> None:
    """Dense crowds (overlapping, many cuts), sparse ones, and moves up to 10 cm a step: bit-equal moves."""
    pose, move, reach = crowd(seed, count, spread, step)
    expected = move.copy()
    keep_apart_all_pairs(pose, expected, reach)
    keep_apart(pose, move, reach, np.zeros(len(reach), dtype=bool))
    assert move.tobytes() == expected.tobytes()


def test_pairs_at_exactly_the_conflict_distance_are_candidates() -> None:
    """Two robots whose conflict distance (reaches plus moves) equals their distance are neighbours in the grid."""
    reach = np.array([0.05, 0.05])
    pose = np.array([[0.0, 0.0, 0.0], [0.12, 0.0, 0.0]])
    move = np.array([[0.01, 0.0], [-0.01, 0.0]])
    assert near_pairs(pose, move, reach).tolist() == [[0, 1]]


def test_far_robots_are_never_paired() -> None:
    """1,000 robots 10 m apart on a line: no pair to check."""
    pose = np.column_stack((np.arange(1000) * 10.0, np.zeros(1000), np.zeros(1000)))
    assert len(near_pairs(pose, np.full((1000, 2), 0.01), np.full(1000, 0.06))) == 0


@settings(deadline=None, max_examples=60)
@given(st.lists(st.integers(-5, 40), max_size=300))
def test_stable_order_is_numpys_stable_argsort(keys: list[int]) -> None:
    """The grids' hand-written merge sort orders ties as numpy's stable sort does (the grids depend
    on the order of checking pairs and circles)."""
    key = np.array(keys, dtype=np.int64)
    order, sorted_key = stable_order(key)
    np.testing.assert_array_equal(order, np.argsort(key, kind="stable"))
    np.testing.assert_array_equal(sorted_key, np.sort(key, kind="stable"))
