"""Exercise 6: UMBmark, the corrections of a differential drive's systematic odometry errors.

Check your work with:  ctsim lab check 6 umbmark.py
"""

import math  # noqa: F401


def corrections(errors_cw, errors_ccw, side, diameters, track):
    """The corrected geometry (d_left, d_right, track) in m.

    errors_cw, errors_ccw: [[x, y], ...] return errors (true end minus odometry end, m) of the
        squares driven clockwise and counter-clockwise, in the start frame (x along the first
        leg, y to its left);
    side: the square's side L (m); diameters: the believed (d_left, d_right) (m); track: the
        believed track width b (m)."""
    raise NotImplementedError("your code here")
