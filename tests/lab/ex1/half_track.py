import math


def turn(v_left, v_right, track, x, y, theta):
    omega = (v_right - v_left) / (track / 2)
    if v_right == v_left:
        return math.inf, omega, math.inf, math.inf
    radius = track * (v_left + v_right) / (2 * (v_right - v_left))
    return radius, omega, x - radius * math.sin(theta), y + radius * math.cos(theta)
