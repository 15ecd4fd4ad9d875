"""Robots: their descriptions, and the code that runs on them (controllers, behaviours, odometry).

Code here sees the kinematics core and sensor readings only (it may import `sim.kinematics` and
its own modules; the readings are `bots.readings`, numpy only), never the world or ground truth:
`import bots.controller` loads no physics.
"""

import sim.kernel_cache  # noqa: F401 (importing it keeps numba's cache true to the modules kernels freeze, before any of bots' kernels loads)
