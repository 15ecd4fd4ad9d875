import math


def step(x, y, theta, v_left, v_right, track, dt):
    v, omega = (v_left + v_right) / 2, (v_right - v_left) / track
    alpha = omega * dt
    chord = v * dt * (math.sin(alpha / 2) / (alpha / 2) if alpha else 1.0)
    mid = theta + alpha / 2
    return x + chord * math.sin(mid), y + chord * math.cos(mid), theta + alpha
