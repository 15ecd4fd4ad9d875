"""Kinematics-core benchmarks: batch throughput and step-size independence."""

from __future__ import annotations

import time

import numpy as np

from bots.ctbot import CTBOT
from sim.kinematics import (
    counts_per_metre,
    integrate_arcs,
    mouse_count_series,
    mouse_displacement,
    ticks_from_arc_series,
    ticks_per_metre,
    twist_from_wheel_speeds,
    wheel_arcs_to_arc,
)
from sim.kinematics.batch import step_batch


def kinematics_batch(robots: int = 10_000, steps: int = 2_000, seed: int = 0) -> float:
    """Robot-steps per second of the fused kernel (arc + encoders + mouse, one call per step) for
    a batch of c't-Bots whose random wheel speeds change every step."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    v_max = CTBOT.max_wheel_surface_speed
    pool = rng.uniform(-v_max, v_max, size=(64, robots, 2)) * dt
    pose = np.zeros((robots, 3))
    heading_dir = np.tile([1.0, 0.0], (robots, 1))
    tick_carry, mouse_carry = np.zeros((robots, 2)), np.zeros((robots, 2))
    ticks, counts = np.zeros((robots, 2), np.int64), np.zeros((robots, 2), np.int64)
    mount = np.asarray(CTBOT.mouse.mount, dtype=np.float64)
    per_metre = float(ticks_per_metre(CTBOT.wheel_radius, CTBOT.encoders.ticks_per_rev))
    per_count = float(counts_per_metre(CTBOT.mouse.dpi))

    def step(k: int) -> None:
        step_batch(pose, heading_dir, pool[k % 64], CTBOT.track_width, per_metre, tick_carry, ticks,
                   mount, per_count, mouse_carry, counts)

    step(0)  # compile (or load the cached machine code) before timing
    start = time.perf_counter()
    for k in range(steps):
        step(k)
    return robots * steps / (time.perf_counter() - start)


def kinematics_batch_numpy(robots: int = 10_000, steps: int = 2_000, chunk: int = 50, seed: int = 0) -> float:
    """The same work with the numpy reference functions, `chunk` steps per call (for comparison)."""
    rng = np.random.default_rng(seed)
    b, r = CTBOT.track_width, CTBOT.wheel_radius
    mount = np.asarray(CTBOT.mouse.mount)
    dt = 0.01
    v_max = CTBOT.max_wheel_surface_speed
    wheel_arcs = rng.uniform(-v_max, v_max, size=(chunk, robots, 2)) * dt
    pose = np.zeros((robots, 3))
    tick_carry = np.zeros((robots, 2))
    mouse_carry = np.zeros((robots, 2))
    start = time.perf_counter()
    for _ in range(steps // chunk):
        s, alpha = wheel_arcs_to_arc(wheel_arcs[..., 0], wheel_arcs[..., 1], b)
        poses = integrate_arcs(pose, s, alpha)
        pose = poses[-1]
        ticks, tick_carry = ticks_from_arc_series(wheel_arcs, tick_carry, r)
        counts, mouse_carry = mouse_count_series(mouse_displacement(s, alpha, mount), mouse_carry, CTBOT.mouse.dpi)
    elapsed = time.perf_counter() - start
    return robots * (steps // chunk) * chunk / elapsed


def arc_circle_error(dt: float = 0.1, duration: float = 10.0) -> float:
    """Position error (m) of a 10 s circle at constant wheel speeds against the closed form."""
    v, omega = twist_from_wheel_speeds(0.2, 0.3, CTBOT.track_width)
    n = int(round(duration / dt))
    poses = integrate_arcs(np.zeros(3), np.full(n, v * dt), np.full(n, omega * dt))
    theta = omega * duration
    radius = v / omega
    exact = np.array([radius * np.sin(theta), radius * (1 - np.cos(theta))])
    return float(np.hypot(*(poses[-1, :2] - exact)))
