"""The default simulation step, in the core so that the world and a robot's own code share one.

c't-Sim steps every 10 ms, and so does every ctsim run unless told otherwise; a behaviour assumes
it until two readings have shown the step that really runs. The range a run may take and its check
live with the world (`sim.world.step`).
"""

DEFAULT_DT = 0.01
"""The step (s) of a run, a world and the command line when none is given: c't-Sim's 10 ms."""
