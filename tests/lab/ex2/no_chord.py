import math


def step(x, y, theta, v_left, v_right, track, dt):
    v, omega = (v_left + v_right) / 2, (v_right - v_left) / track
    heading = theta + omega * dt
    mid = theta + omega * dt / 2
    return x + v * dt * math.cos(mid), y + v * dt * math.sin(mid), heading
