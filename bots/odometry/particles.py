"""The particle set of the map-aided localiser (`bots.odometry.localiser`): what it asks of the
map, and the compiled steps every scan takes over thousands of particles (motion with noise,
low-variance resampling, the weighted mean and spread with headings kept continuous)."""

from __future__ import annotations

import math
from typing import Protocol

import numba
import numpy as np


class MapModel(Protocol):
    """What the localiser needs of the map (`sim.world.localising.MapScan` is one)."""

    def likelihood(self, particles: np.ndarray, raw: np.ndarray, out: np.ndarray) -> None:
        """out (n,) = likelihood of the raw IR values at each of the (n, 3) particles."""

    def best(self, raw: np.ndarray) -> float:
        """The most likelihood any pose could give these raw values."""

    def free(self, rng: np.random.Generator, count: int) -> np.ndarray:
        """(count, 3) poses drawn uniformly where the robot fits."""


@numba.njit(cache=True)
def move_particles(particles: np.ndarray, dx: float, dy: float, dtheta: float, std: np.ndarray, normals: np.ndarray, turns: np.ndarray) -> None:
    """Every particle moved by the body-frame increment (dx, dy m, dtheta rad), each part off by
    std (forward, lateral m; turn rad) times the particle's row of `normals` (n, 3), its turn
    taken from `turns` (n,) instead where that is not nan."""
    for i in range(particles.shape[0]):
        fx = dx + std[0] * normals[i, 0]
        fy = dy + std[1] * normals[i, 1]
        turn = (dtheta if math.isnan(turns[i]) else turns[i]) + std[2] * normals[i, 2]
        mid = particles[i, 2] + 0.5 * turn
        c, s = math.cos(mid), math.sin(mid)
        particles[i, 0] += c * fx - s * fy
        particles[i, 1] += s * fx + c * fy
        particles[i, 2] += turn


@numba.njit(cache=True)
def low_variance_resample(weights: np.ndarray, count: int, start: float) -> np.ndarray:
    """The indices of `count` particles drawn in proportion to their `weights` (summing to 1) by
    one comb of `count` equal teeth from `start` in [0, 1/count) (Probabilistic Robotics table
    4.4): a particle of weight w is drawn floor(count w) or ceil(count w) times."""
    n = weights.shape[0]
    out = np.empty(count, dtype=np.int64)
    total, j = weights[0], 0
    for i in range(count):
        tooth = start + i / count
        while tooth > total and j < n - 1:
            j += 1
            total += weights[j]
        out[i] = j
    return out


@numba.njit(cache=True)
def mean_and_covariance(particles: np.ndarray, weights: np.ndarray, reference: float, out_mean: np.ndarray, out_cov: np.ndarray) -> None:
    """Weighted mean pose and (3, 3) covariance of the particles, headings taken within pi of
    `reference` (each particle's heading is folded there too, so that it stays continuous)."""
    sx = sy = ss = sc = 0.0
    for i in range(particles.shape[0]):
        turn = particles[i, 2] - reference
        turn -= 2.0 * math.pi * math.floor((turn + math.pi) / (2.0 * math.pi))
        particles[i, 2] = reference + turn
        w = weights[i]
        sx += w * particles[i, 0]
        sy += w * particles[i, 1]
        ss += w * math.sin(turn)
        sc += w * math.cos(turn)
    out_mean[0], out_mean[1], out_mean[2] = sx, sy, reference + math.atan2(ss, sc)
    out_cov[:] = 0.0
    for i in range(particles.shape[0]):
        e0, e1 = particles[i, 0] - out_mean[0], particles[i, 1] - out_mean[1]
        e2 = particles[i, 2] - out_mean[2]
        e2 -= 2.0 * math.pi * math.floor((e2 + math.pi) / (2.0 * math.pi))
        w = weights[i]
        out_cov[0, 0] += w * e0 * e0
        out_cov[0, 1] += w * e0 * e1
        out_cov[0, 2] += w * e0 * e2
        out_cov[1, 1] += w * e1 * e1
        out_cov[1, 2] += w * e1 * e2
        out_cov[2, 2] += w * e2 * e2
    out_cov[1, 0], out_cov[2, 0], out_cov[2, 1] = out_cov[0, 1], out_cov[0, 2], out_cov[1, 2]
