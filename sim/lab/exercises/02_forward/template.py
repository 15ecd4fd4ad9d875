"""Exercise 2: one step of the forward kinematics of a differential drive (seed 003, eq 4).

Check your work with:  ctsim lab check 2 forward.py
"""



def step(x, y, theta, v_left, v_right, track, dt):
    """Return the pose (x', y', theta') after `dt` seconds at constant rim speeds v_left, v_right
    (m/s), track width `track` (m), starting at (x, y, theta) (m, m, rad). Exact for any dt:
    rotate about the ICC (eq 4); handle v_left == v_right (straight line)."""
    raise NotImplementedError("your code here")
