"""The runnable examples in the public entry points' docstrings (`simulate`, `Bot`, `sweep`) run as
written: an example a reader copies works."""

from __future__ import annotations

import doctest

import pytest

from sim.experiments import Bot, simulate, sweep  # (the names a reader imports: sweep's module loads on demand)


@pytest.mark.parametrize("entry", [simulate, Bot, sweep], ids=lambda e: e.__name__)
def test_the_docstring_examples_run_as_written(entry):
    tests = [t for t in doctest.DocTestFinder().find(entry) if t.examples]
    assert tests, f"{entry.__name__} has no examples"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in tests:
        runner.run(test)
    assert runner.failures == 0, f"{runner.failures} of {runner.tries} examples of {entry.__name__} failed (see the output above)"
