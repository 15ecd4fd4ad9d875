"""Robots: their descriptions, and the code that runs on them (controllers, behaviours, odometry).

Code here sees the kinematics core and sensor readings only, never the world or ground truth.
"""
