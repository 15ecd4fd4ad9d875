"""Compiled per-step kernels of the world, one pass over all robots each.

A world step is a handful of scalar formulas per robot (motor, encoders, arc, mouse, floor and
light sensors). Written with numpy they cost a few microseconds of call overhead each, which
dominates for one robot; these numba kernels do the same maths from `sim.kinematics` in one call
per step for any number of robots (tests compare them with the reference functions).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import _half_angle, quantize_one


@numba.njit(cache=True)
def drive(
    commands: np.ndarray,
    wheel_speed: np.ndarray,
    command_max: np.ndarray,
    max_speed: np.ndarray,
    lag: np.ndarray,
    max_change: np.ndarray,
    dt: float,
    ticks_per_rad: np.ndarray,
    tick_carry: np.ndarray,
    tick_offset: np.ndarray,
    ticks: np.ndarray,
    real_radius: np.ndarray,
    slip: np.ndarray,
    track: np.ndarray,
    pose: np.ndarray,
    fallen: np.ndarray,
    move: np.ndarray,
    alpha: np.ndarray,
) -> None:
    """Motor model, encoder ticks and the exact-arc motion of every robot for one step.

    Writes wheel_speed (rad/s at the end of the step), ticks/tick_carry, and the unobstructed
    world displacement `move` (n, 2) and heading change `alpha` (n,) of the arc."""
    for i in range(commands.shape[0]):
        for w in range(2):
            c = min(max(commands[i, w], -command_max[i]), command_max[i])
            target = c / command_max[i] * max_speed[i]
            current = wheel_speed[i, w]
            change = (target - current) * lag[i]
            change = min(max(change, -max_change[i]), max_change[i])
            wheel_speed[i, w] = current + change
            whole, fraction = quantize_one(wheel_speed[i, w] * dt * ticks_per_rad[i] + tick_carry[i, w])
            ticks[i, w] = whole + tick_offset[i, w]
            tick_carry[i, w] = fraction
        if fallen[i]:
            move[i, 0] = move[i, 1] = alpha[i] = 0.0
            continue
        s_l = wheel_speed[i, 0] * dt * real_radius[i, 0] * (1.0 + slip[i, 0])
        s_r = wheel_speed[i, 1] * dt * real_radius[i, 1] * (1.0 + slip[i, 1])
        a = (s_r - s_l) / track[i]
        h = 0.5 * a
        cos_h, sinc_h = _half_angle(h)
        chord = 0.5 * (s_l + s_r) * sinc_h
        mid = pose[i, 2] + h
        move[i, 0] = chord * math.cos(mid)
        move[i, 1] = chord * math.sin(mid)
        alpha[i] = a


@numba.njit(cache=True)
def _in_hole(x: float, y: float, hole: np.ndarray, origin: np.ndarray, cell: float, outside_is_hole: bool) -> bool:
    ix = int(math.floor((x - origin[0]) / cell))
    iy = int(math.floor((y - origin[1]) / cell))
    if ix < 0 or iy < 0 or iy >= hole.shape[0] or ix >= hole.shape[1]:
        return outside_is_hole
    return hole[iy, ix]


@numba.njit(cache=True)
def measure(
    before: np.ndarray,
    after: np.ndarray,
    contacts: np.ndarray,
    fallen: np.ndarray,
    mount: np.ndarray,
    counts_per_metre: np.ndarray,
    max_step: np.ndarray,
    noise: np.ndarray,
    mouse_carry: np.ndarray,
    counts: np.ndarray,
    hole: np.ndarray,
    origin: np.ndarray,
    cell: float,
    outside_is_hole: bool,
) -> None:
    """Ground contact (a wheel or the skid over a hole: fallen) and mouse counts from each
    body's true motion `before` -> `after`, read as the constant twist between them.

    counts_per_metre is 0 for a robot without a mouse; max_step the longest displacement per
    step (m) the sensor tracks; noise (n, 2) counts to add."""
    for i in range(before.shape[0]):
        c0, s0 = math.cos(before[i, 2]), math.sin(before[i, 2])
        c1, s1 = math.cos(after[i, 2]), math.sin(after[i, 2])
        if not fallen[i]:
            for k in range(contacts.shape[1]):
                px, py = contacts[i, k, 0], contacts[i, k, 1]
                if _in_hole(after[i, 0] + c1 * px - s1 * py, after[i, 1] + s1 * px + c1 * py, hole, origin, cell, outside_is_hole):
                    fallen[i] = True
        if counts_per_metre[i] == 0.0:
            continue
        dx, dy = after[i, 0] - before[i, 0], after[i, 1] - before[i, 1]
        bx, by = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
        dth = after[i, 2] - before[i, 2]
        h = 0.5 * dth
        cos_h, sinc_h = _half_angle(h)
        sin_h = sinc_h * h
        tx, ty = (cos_h * bx + sin_h * by) / sinc_h, (-sin_h * bx + cos_h * by) / sinc_h
        fx, fy = tx - dth * mount[i, 1], ty + dth * mount[i, 0]
        mx, my = mount[i, 0], mount[i, 1]
        lifted = _in_hole(after[i, 0] + c1 * mx - s1 * my, after[i, 1] + s1 * mx + c1 * my, hole, origin, cell, outside_is_hole)
        if lifted or fx * fx + fy * fy > max_step[i] * max_step[i]:
            fx = fy = 0.0
        for axis, metres in enumerate((fx, fy)):
            whole, fraction = quantize_one(metres * counts_per_metre[i] + noise[i, axis] + mouse_carry[i, axis])
            counts[i, axis] = whole
            mouse_carry[i, axis] = fraction


@numba.njit(cache=True)
def to_world(pose: np.ndarray, offsets: np.ndarray, owner: np.ndarray, out: np.ndarray) -> None:
    """World positions of body-frame points `offsets` (m, 2) of robots `owner` (m,)."""
    for k in range(offsets.shape[0]):
        i = owner[k]
        c, s = math.cos(pose[i, 2]), math.sin(pose[i, 2])
        out[k, 0] = pose[i, 0] + c * offsets[k, 0] - s * offsets[k, 1]
        out[k, 1] = pose[i, 1] + s * offsets[k, 0] + c * offsets[k, 1]


@numba.njit(cache=True)
def sample_floor(points: np.ndarray, value: np.ndarray, origin: np.ndarray, cell: float, outside: int, out: np.ndarray) -> None:
    """Raster floor values at world points (m, 2)."""
    for k in range(points.shape[0]):
        ix = int(math.floor((points[k, 0] - origin[0]) / cell))
        iy = int(math.floor((points[k, 1] - origin[1]) / cell))
        if ix < 0 or iy < 0 or iy >= value.shape[0] or ix >= value.shape[1]:
            out[k] = outside
        else:
            out[k] = value[iy, ix]


@numba.njit(cache=True)
def sense_light(
    points: np.ndarray,
    look: np.ndarray,
    half_opening: np.ndarray,
    reach: np.ndarray,
    lights: np.ndarray,
    out: np.ndarray,
) -> None:
    """LDR darkness (0..1023) of sensors at world `points` looking along `look` (rad): distance
    to the nearest light inside the cone over `reach`, 1023 with none (c't-Sim `sensLight`)."""
    for k in range(points.shape[0]):
        nearest = math.inf
        for j in range(lights.shape[0]):
            ox, oy = lights[j, 0] - points[k, 0], lights[j, 1] - points[k, 1]
            off = math.atan2(oy, ox) - look[k]
            off = abs((off + math.pi) % (2 * math.pi) - math.pi)
            if off <= half_opening[k]:
                nearest = min(nearest, math.sqrt(ox * ox + oy * oy + lights[j, 2] * lights[j, 2]))
        out[k] = round(min(nearest / reach[k], 1.0) * 1023)
