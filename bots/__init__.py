"""Robots: their descriptions, and the code that runs on them (controllers, behaviours, odometry).

Code here sees the kinematics core and sensor readings only (it may import `sim.kinematics` and
`sim.world.readings`), never the world or ground truth.
"""
