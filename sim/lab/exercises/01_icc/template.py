"""Exercise 1: turn radius R, yaw rate ω and the ICC of a differential drive (seed 003, eqs 1-3).

Check your work with:  ctsim lab check 1 icc.py
"""



def turn(v_left, v_right, track, x, y, theta):
    """Return (R, omega, icc_x, icc_y) for wheel rim speeds v_left, v_right (m/s), track width
    `track` (m) and the pose (x, y, theta) (m, m, rad).

    R: signed turn radius (m), positive when the centre lies to the left; math.inf when driving
       straight (then icc_x = icc_y = math.inf), 0 when turning on the spot.
    omega: yaw rate (rad/s), counter-clockwise positive.
    """
    raise NotImplementedError("your code here")
