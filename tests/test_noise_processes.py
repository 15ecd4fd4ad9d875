"""Random errors are processes in distance, not in steps: the same spread of slip, spurious ticks
and mouse noise comes out at dt 1, 10 and 50 ms, and it is the closed form of each process.

Each case drives ROBOTS c't-Bots straight side by side in one world whose robots do not meet
(each with its own generators, so each is one independent sample) and compares the sample
variance of three quantities with the model's variance, inside the chi-square interval that
sampling error leaves (two-sided, 1 in 10,000 for a right model; the seed is fixed, so the
test gives the same answer every run):
- the true heading change, which only slip moves: 2 slip_std^2 D / b^2 for D metres rolled per wheel;
- each wheel's tick count, which only spurious ticks move (encoders count the wheel's turn, not
  its slip): tick_noise N for N ticks counted (each wrong tick is +1 or -1);
- the mouse's forward distance against the true one: noise_std^2 D for D metres of floor.
Under the per-step model these were off by the ratio of the steps (x10 and x5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.ctbot import CTBOT
from sim.world import World
from sim.world.files import load_world

ROBOTS = 300
DURATION_S = 2.0
"""Driving time (s): about 0.6 m at the command below."""
COMMAND = 150.0
SLIP, TICKS, MOUSE = 0.002, 0.02, 0.0008
"""The harsh preset's figures, so that each process stands well clear of the others' traces."""
Z = 3.89
"""Standard normal quantile for a two-sided 1 in 10,000."""


def chi_square_interval(dof: int) -> tuple[float, float]:
    """The range of sample variance / true variance for `dof` degrees of freedom, two-sided Z
    (Wilson and Hilferty's cube-root approximation: within 0.1 % of the exact quantile here)."""
    a = 2.0 / (9.0 * dof)
    return ((1 - a - Z * math.sqrt(a)) ** 3, (1 - a + Z * math.sqrt(a)) ** 3)


def drive(dt: float) -> dict[str, np.ndarray]:
    robot = CTBOT.with_changes(encoders={"slip_std": SLIP, "tick_noise": TICKS}, mouse={"noise_std": MOUSE})
    world = World(load_world("empty"), dt=dt, seed=11, robots_meet=False)
    for _ in range(ROBOTS):
        world.add_robot(robot, start=(1.0, 1.5, 0.0))
    start = world.poses()
    tallies = np.zeros((ROBOTS, 4))
    for _ in range(round(DURATION_S / dt)):
        world.step(np.full((ROBOTS, 2), COMMAND))
        tallies += world.tallies
    end = world.poses()
    return {"turn": end[:, 2] - start[:, 2], "ticks": tallies[:, :2], "mouse": tallies[:, 2], "chord": np.hypot(*(end[:, :2] - start[:, :2]).T)}


@pytest.mark.parametrize("dt", [0.001, 0.01, 0.05])
def test_slip_spurious_ticks_and_mouse_noise_spread_as_their_processes_at_any_step(dt):
    run = drive(dt)
    low, high = chi_square_interval(ROBOTS - 1)
    metres_per_tick = 2 * math.pi * CTBOT.wheel_radius / CTBOT.encoders.ticks_per_rev
    counted = run["ticks"].mean()
    rolled = counted * metres_per_tick
    mouse = CTBOT.mouse
    metres_per_count = 0.0254 / mouse.dpi
    expected = {
        "slip": (run["turn"].var(ddof=1), 2 * SLIP**2 * rolled / CTBOT.track_width**2),
        "left ticks": (run["ticks"][:, 0].var(ddof=1), TICKS * counted),
        "right ticks": (run["ticks"][:, 1].var(ddof=1), TICKS * counted),
        "mouse": ((run["mouse"] * metres_per_count - run["chord"]).var(ddof=1), MOUSE**2 * run["chord"].mean()),
    }
    for name, (seen, model) in expected.items():
        assert low < seen / model < high, f"{name}: variance {seen:.3g} against the model's {model:.3g} at dt {dt} s"


@pytest.mark.parametrize("n, p", [(1, 0.002), (3, 0.02), (5, 0.5), (4, 1.0), (0, 0.3)])
def test_a_uniform_picks_each_count_of_spurious_ticks_with_its_binomial_probability(n, p):
    """The compiled kernels draw a step's wrong ticks from one uniform each (`sim.world.kernels.noise`):
    over an even grid of M uniforms each count k comes out for a share of them within 1/M of the
    binomial probability C(n, k) p^k (1-p)^(n-k) (the grid's own step; no sampling error)."""
    from sim.world.kernels.noise import _binomial

    m = 20_000
    counts = np.bincount([_binomial(n, p, (i + 0.5) / m) for i in range(m)], minlength=n + 1)
    probability = [math.comb(n, k) * p**k * (1 - p) ** (n - k) for k in range(n + 1)]
    assert np.allclose(counts / m, probability, atol=1.5 / m)


def test_the_normal_a_uniform_is_made_of_is_uniform():
    """Phi(z) of standard normals is uniform: its deciles of 100,000 draws each hold a tenth of
    them within five standard errors (sqrt(0.09 / 100,000) = 0.00095)."""
    from sim.world.kernels.noise import _uniform

    z = np.random.default_rng(5).standard_normal(100_000)
    shares = np.bincount((np.array([_uniform(v) for v in z]) * 10).astype(int), minlength=10) / len(z)
    assert np.all(np.abs(shares - 0.1) < 5 * 0.00095)
