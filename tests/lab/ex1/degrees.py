import math


def turn(v_left, v_right, track, x, y, theta):
    omega = (v_right - v_left) / track
    if v_right == v_left:
        return math.inf, omega, math.inf, math.inf
    radius = track * (v_left + v_right) / (2 * (v_right - v_left))
    heading = math.radians(theta)
    return radius, omega, x - radius * math.sin(heading), y + radius * math.cos(heading)
