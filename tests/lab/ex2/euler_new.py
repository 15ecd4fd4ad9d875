import math


def step(x, y, theta, v_left, v_right, track, dt):
    v, omega = (v_left + v_right) / 2, (v_right - v_left) / track
    heading = theta + omega * dt
    return x + v * dt * math.cos(heading), y + v * dt * math.sin(heading), heading
