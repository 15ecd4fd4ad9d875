"""Suite-wide settings: no test is decided by the clock.

Hypothesis's per-example deadline (200 ms by default) fails a correct test on a loaded machine, and
the first example of many tests pays for numba compiling a kernel: the deadline is off for every
property test. A test that hangs is stopped by pytest-timeout (`timeout` in pyproject.toml), which
prints every thread's stack, instead of by a short timeout inside the test.
"""

from __future__ import annotations

import signal

import pandas  # noqa: F401  (see below)
import pytest
from hypothesis import settings

settings.register_profile("ctsim", deadline=None, print_blob=True)
settings.load_profile("ctsim")

# `ctsim run` keeps pyarrow from importing pandas for the rest of its process
# (`sim.views.recording.arrow.keep_pandas_out_of_arrow`), which suits a command that ends with its run but
# not a test process that calls the command line in-process and reads Arrow data in later tests:
# with pandas loaded from the start that trick steps aside, whatever order the tests run in.


@pytest.fixture()
def ctrl_c():
    """SIGINT raising KeyboardInterrupt during the test, as in a Python started at a terminal (one
    started in the background by a shell without job control ignores it), for tests whose code
    sends itself Ctrl-C: a KeyboardInterrupt raised with no signal is that code's error, not an
    interrupt (`sim.interrupts`)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def pytest_addoption(parser) -> None:  # noqa: ANN001 (pytest's Parser)
    parser.addoption("--slow", action="store_true", help="also run the tests marked slow (minutes each: the maze NEES over 40 seeds)")


def pytest_collection_modifyitems(config, items) -> None:  # noqa: ANN001 (pytest's Config, Items)
    """Tests marked slow run only with --slow: the suite's 10-20 minutes stay that."""
    if config.getoption("--slow"):
        return
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(pytest.mark.skip(reason="slow (minutes): run with --slow"))
