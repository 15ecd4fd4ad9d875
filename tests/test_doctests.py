"""The runnable examples in the public entry points' docstrings (`simulate`, `Bot`, `sweep`) run as
written: an example a reader copies works."""

from __future__ import annotations

import doctest

import pytest

import sim.experiments.api
import sim.experiments.sweep


@pytest.mark.parametrize("module", [sim.experiments.api, sim.experiments.sweep], ids=lambda m: m.__name__)
def test_the_docstring_examples_run_as_written(module):
    finder = doctest.DocTestFinder()
    tests = [t for t in finder.find(module) if t.examples]
    assert tests, f"{module.__name__} has no examples"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in tests:
        runner.run(test)
    assert runner.failures == 0, f"{runner.failures} of {runner.tries} examples in {module.__name__} failed (see the output above)"
