import math


def mean(points):
    return [sum(p[i] for p in points) / len(points) for i in range(2)]


def corrections(errors_cw, errors_ccw, side, diameters, track):
    x_cw, x_ccw = mean(errors_cw)[0], mean(errors_ccw)[0]
    alpha = (x_cw + x_ccw) / (-4 * side)
    beta = (x_cw - x_ccw) / (-4 * side)
    e_d = 1.0
    if beta:
        radius = (side / 2) / math.sin(beta / 2)
        e_d = (radius + track / 2) / (radius - track / 2)
    e_b = (math.pi / 2) / (math.pi / 2 - alpha)
    left, right = diameters
    return left * 2 / (e_d + 1), right * 2 / (1 / e_d + 1), track * e_b
