"""Compiled noise of the world's sensors: every random error of a step drawn in two or three kernel
calls from standard normals held in blocks (`sim.world.noise.NormalBlocks`, one row per sensor's
own generator), not in a Python call into numpy per sensor and step.

A kernel takes a row's next values and advances its `used`; the caller has reserved them
(`NormalBlocks.reserve`) before the call. The draws are those of the models in `bots.noise`:
each wheel's slip slip_std * N(0, 1) per step (scaled by the square root of its arc in
`drive`), each counted tick one too many or one too few with probability tick_noise, the mouse's
counts noise_std * N(0, 1) per axis (scaled by the floor passed in `measure`), the floor and
light sensors' values N(0, std) rounded. A uniform draw is a normal's Phi(z), exactly uniform,
so that one block of normals serves every kind.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.world.kernels.motion import first_bad
from sim.world.layout import Noise

ENCODER_DRAWS = 6
"""Normals an encoder's row gives each step: the two wheels' slip, then per wheel two uniforms
(how many ticks were wrong, how many of those one too many)."""
MOUSE_DRAWS = 2
"""Normals a mouse's row gives each step: its x and y count noise."""


@numba.njit(cache=True, inline="always")
def _uniform(z: float) -> float:
    """Phi(z): a standard normal's value as a uniform in (0, 1)."""
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


@numba.njit(cache=True, inline="always")
def _binomial(n: int, p: float, u: float) -> int:
    """The count of successes of `n` trials of probability `p` that uniform `u` picks (the inverse
    of the binomial distribution function: exact for the few ticks of a step)."""
    if n <= 0 or p <= 0.0:
        return 0
    if p >= 1.0:
        return n
    ratio = p / (1.0 - p)
    probability = (1.0 - p) ** n
    below = probability
    k = 0
    while u > below and k < n:
        probability *= (n - k) / (k + 1) * ratio
        k += 1
        below += probability
    return k


@numba.njit(cache=True)
def draw_step(commands: np.ndarray, draws: Noise, encoders: int, state: np.ndarray, tick_uniforms: np.ndarray) -> int:
    """A step's draws before it moves, where every command (n, 2) is finite (else nothing is
    drawn, and the first robot with a non-finite one is returned; -1: drawn). Rows k < `encoders`
    of `draws` are encoders': robot `draws.rows[k]`'s STATE slip, `draws.std[k]` (its slip_std)
    times two normals, and the uniforms `tick_uniforms[k]` of its spurious ticks; the rest are
    mice: the robot's STATE mouse_noise, `draws.std[k]` (counts per sqrt m) times two normals."""
    bad = first_bad(commands)
    if bad >= 0:
        return bad
    scale, normals, used = draws.std, draws.normals, draws.used
    for k in range(len(draws.rows)):
        now, j = state[draws.rows[k]], used[k]
        if k < encoders:
            slip = now.slip
            slip[0] = scale[k] * normals[k, j]
            slip[1] = scale[k] * normals[k, j + 1]
            for c in range(4):
                tick_uniforms[k, c] = _uniform(normals[k, j + 2 + c])
            used[k] = j + ENCODER_DRAWS
        else:
            noise = now.mouse_noise
            noise[0] = 0.0 + scale[k] * normals[k, j]
            noise[1] = 0.0 + scale[k] * normals[k, j + 1]
            used[k] = j + MOUSE_DRAWS
    return -1


@numba.njit(cache=True)
def spurious_ticks(encoder_robot: np.ndarray, tick_noise: np.ndarray, tick_uniforms: np.ndarray, tallies: np.ndarray) -> None:
    """Each of the step's TALLIES ticks of robot `encoder_robot[k]` one too many or one too few
    with probability `tick_noise[k]`, each way alike (a light barrier's edge that bounces or is
    missed: a process in the ticks counted, the same per wheel turn at any step)."""
    for k in range(len(encoder_robot)):
        ticks = tallies[encoder_robot[k]].ticks
        for wheel in range(2):
            wrong = _binomial(abs(ticks[wheel]), tick_noise[k], tick_uniforms[k, 2 * wheel])
            if wrong:
                ticks[wheel] += 2 * _binomial(wrong, 0.5, tick_uniforms[k, 2 * wheel + 1]) - wrong


@numba.njit(cache=True)
def add_rounded(values: np.ndarray, draws: Noise, top: np.ndarray) -> None:
    """Gaussian noise on noisy sensors' integer `values` (the floor and light sensors'): value
    `draws.rows[k]` gets N(0, draws.std[k]) from normals row k, rounded (half to even, as Python's
    round) into 0..top[k]."""
    rows, std, normals, used = draws.rows, draws.std, draws.normals, draws.used
    for k in range(len(rows)):
        noisy = np.rint(values[rows[k]] + (0.0 + std[k] * normals[k, used[k]]))
        values[rows[k]] = int(min(max(noisy, 0.0), float(top[k])))
        used[k] += 1
