import math


def step(x, y, theta, v_left, v_right, track, dt):
    omega = (v_right - v_left) / (track / 2)
    v = (v_left + v_right) / 2
    if v_left == v_right:
        return x + v * dt * math.cos(theta), y + v * dt * math.sin(theta), theta
    radius = v / omega
    icc_x, icc_y = x - radius * math.sin(theta), y + radius * math.cos(theta)
    c, s = math.cos(omega * dt), math.sin(omega * dt)
    return (c * (x - icc_x) - s * (y - icc_y) + icc_x, s * (x - icc_x) + c * (y - icc_y) + icc_y, theta + omega * dt)
