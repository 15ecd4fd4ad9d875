"""Suite-wide settings: no test is decided by the clock.

Hypothesis's per-example deadline (200 ms by default) fails a correct test on a loaded machine, and
the first example of many tests pays for numba compiling a kernel: the deadline is off for every
property test. A test that hangs is stopped by pytest-timeout (`timeout` in pyproject.toml), which
prints every thread's stack, instead of by a short timeout inside the test.
"""

from __future__ import annotations

from hypothesis import settings

settings.register_profile("ctsim", deadline=None, print_blob=True)
settings.load_profile("ctsim")
