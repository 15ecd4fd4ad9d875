"""The world layer: physics and sensors.

The pymunk world that drives robots along exact arcs (`physics`), its compiled per-step kernels
(`kernels`, one module per job, reading the tables of `layout`), the floor raster (`floor`), the
sensors' transfer functions (`sensors`), the world as plain data (`spec`) and its files (`files`:
TOML, c't-Sim parcours, grid). It may import the kinematics core, the robots' descriptions
(`bots.spec`) and the readings it fills (`bots.readings`), nothing above.
"""

from sim.world.physics import CommandError, World
from sim.world.spec import Start, WorldFileError, WorldSpec
from sim.world.tables import IR_RAY_LENGTH

__all__ = ["IR_RAY_LENGTH", "CommandError", "Start", "World", "WorldFileError", "WorldSpec"]
