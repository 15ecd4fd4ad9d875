"""The lab's checkers hold their tolerance exactly: an answer just inside it passes, one just
outside fails (a checker that accepted ten times its tolerance would pass wrong solutions)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from sim.lab import check_file, exercise
from sim.lab.checking import close

SOLUTIONS = Path(__file__).parent / "lab"

values = arrays(np.float64, st.integers(1, 6), elements=st.floats(-100, 100))
tolerances = st.floats(1e-6, 1.0)


@given(values, tolerances, st.floats(0.0, 0.99), st.data())
def test_close_accepts_within_and_refuses_beyond_the_tolerance(expected, tolerance, inside, data):
    """Every component within the tolerance passes; one component 1 % beyond it fails. Values up to
    100 and tolerances from 1e-6 keep the rounding of expected + offset (1.4e-14) far below 1 %."""
    signs = data.draw(arrays(np.float64, expected.shape, elements=st.sampled_from([-1.0, 1.0])))
    assert close(expected + signs * inside * tolerance, expected, tolerance)
    beyond = expected + signs * inside * tolerance
    k = data.draw(st.integers(0, len(expected) - 1))
    beyond[k] = expected[k] + signs[k] * 1.01 * tolerance
    assert not close(beyond, expected, tolerance)


def _shifted(number: int, function: str, component: int, shift: float, tmp_path: Path) -> Path:
    """The exercise's reference solution with one component of its answer moved by `shift`."""
    reference = (SOLUTIONS / f"ex{number}" / "reference.py").read_text()
    path = tmp_path / exercise(number).file
    path.write_text(
        f"{reference}\n\n_reference = {function}\n\n\ndef {function}(*args):\n"
        f"    answer = list(_reference(*args))\n    answer[{component}] += {shift!r}\n    return tuple(answer)\n"
    )
    return path


@pytest.mark.parametrize(("number", "function", "component"), [(1, "turn", 1), (2, "step", 2)])
@pytest.mark.parametrize(("factor", "passes"), [(0.5, True), (2.0, False)])
def test_an_answer_off_by_a_multiple_of_the_tolerance(tmp_path, number, function, component, factor, passes):
    """ω (exercise 1) or θ (exercise 2) moved by half the tolerance passes every scenario, by twice
    the tolerance fails every one: the checker compares with the tolerance the sheet states."""
    ex = dataclasses.replace(exercise(number), hidden=2)
    tolerance = ex.tolerance["absolute"]
    report = check_file(ex, _shifted(number, function, component, factor * tolerance, tmp_path), seed=7)
    assert [row.passed for row in report.rows] == [passes] * len(report.rows), [(r.scenario, r.expected, r.got) for r in report.rows]
