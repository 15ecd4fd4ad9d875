"""The world layer: physics and sensors.

The pymunk world that drives robots along exact arcs (`physics`), its compiled per-step kernels
(`kernels`), the floor raster (`floor`), the sensors' transfer functions (`sensors`), one step's
`Readings`, the world as plain data (`spec`) and its files (`files`: TOML, c't-Sim parcours, grid).
It may import the kinematics core and the robots' descriptions (`bots.spec`), nothing above.
"""

from sim.world.physics import IR_RAY_LENGTH, CommandError, World
from sim.world.readings import Readings
from sim.world.spec import Start, WorldFileError, WorldSpec

__all__ = ["IR_RAY_LENGTH", "CommandError", "Readings", "Start", "World", "WorldFileError", "WorldSpec"]
