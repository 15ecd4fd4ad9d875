"""Issue 16: the rewritten hot paths (broad phase, run loop, estimators, readings) compute what the
code before them did: noise-free runs reproduce trajectories and readings stored before the change
(`tests/reference_runs.py` wrote them). A refactoring guard: it holds the code to what it did,
not to what is right; the closed-form, spec and c't-Sim tests hold that."""

from __future__ import annotations

import numpy as np
import pytest

from tests.reference_runs import READING_FIELDS, STORE, crowd, maze_solve

ROUND_OFF = 1e-9
"""Poses (m, rad) may differ by accumulated floating-point rounding only: 1500 steps of sums of
terms near 1e-3 m carry errors near 1e-13; a changed decision of a controller or a cut would
differ by millimetres."""


@pytest.fixture(scope="module")
def stored() -> dict[str, np.ndarray]:
    with np.load(STORE) as data:
        return dict(data)


def test_crowd_of_robots_kept_apart_as_before(stored):
    """40 robots in a 1 m square driving into each other: every pose of every step as before."""
    np.testing.assert_allclose(crowd()["crowd/poses"], stored["crowd/poses"], rtol=0, atol=ROUND_OFF)


def test_maze_solve_run_as_before(stored):
    """A whole `run` solving the maze: truth, the four estimates and every reading as before
    (readings are integers from the same poses: exactly equal; believed IR distances to round-off)."""
    now = maze_solve()
    assert now.keys() == stored.keys() - {"crowd/poses"}
    for key, value in now.items():
        if key.split("/")[-1] in READING_FIELDS and value.dtype.kind == "i":
            np.testing.assert_array_equal(value, stored[key], err_msg=key)
        else:
            np.testing.assert_allclose(value, stored[key], rtol=0, atol=ROUND_OFF, equal_nan=True, err_msg=key)
