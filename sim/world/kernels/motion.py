"""Compiled kernels of a robot's motion over one step, one pass over all robots each: the motor
model, encoder ticks and the exact arc (`drive`, `plan`), a quiet step's move without pymunk
(`glide`), and what the mouse measures of the true motion (`measure`). The same maths as
`sim.kinematics` (tests compare them with the reference functions)."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import exact_arc, half_angle, quantize_one
from sim.world.kernels.floor import in_hole
from sim.world.layout import (
    ALPHA,
    CELL,
    COMMAND_MAX,
    COUNTS,
    COUNTS_PER_METRE,
    LAG,
    MASS,
    MAX_CHANGE,
    MAX_SPEED,
    MAX_STEP,
    MOMENT,
    MOUNT,
    MOUSE_CARRY,
    MOUSE_NOISE,
    MOVE,
    ORIGIN,
    OUTSIDE_IS_HOLE,
    REAL_RADIUS,
    SLIP,
    TICK_CARRY,
    TICKS,
    TICKS_PER_RAD,
    TRACK,
    WHEEL_SPEED,
)


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
    ticks: np.ndarray,
    real_radius: np.ndarray,
    slip: np.ndarray,
    track: np.ndarray,
    pose: np.ndarray,
    move: np.ndarray,
    alpha: np.ndarray,
) -> None:
    """Motor model, encoder ticks and the exact-arc motion of every robot for one step.

    Writes wheel_speed (rad/s at the end of the step), ticks/tick_carry, and the unobstructed
    world displacement `move` (n, 2) and heading change `alpha` (n,) of the arc. Random slip
    `slip` (n, 2) (sqrt m, drawn per step) puts each wheel's arc s off by slip * sqrt(|s|): the
    variance grows with the distance rolled, whatever the step (Chong and Kleeman's model)."""
    for i in range(commands.shape[0]):
        for w in range(2):
            c = min(max(commands[i, w], -command_max[i]), command_max[i])
            target = c / command_max[i] * max_speed[i]
            current = wheel_speed[i, w]
            change = (target - current) * lag[i]
            change = min(max(change, -max_change[i]), max_change[i])
            wheel_speed[i, w] = current + change
            whole, fraction = quantize_one(wheel_speed[i, w] * dt * ticks_per_rad[i] + tick_carry[i, w])
            ticks[i, w] = whole
            tick_carry[i, w] = fraction
        s_l = wheel_speed[i, 0] * dt * real_radius[i, 0]
        s_r = wheel_speed[i, 1] * dt * real_radius[i, 1]
        s_l += slip[i, 0] * math.sqrt(abs(s_l))
        s_r += slip[i, 1] * math.sqrt(abs(s_r))
        chord, a, _, _ = exact_arc(s_l, s_r, track[i])
        mid = pose[i, 2] + 0.5 * a
        move[i, 0] = chord * math.cos(mid)
        move[i, 1] = chord * math.sin(mid)
        alpha[i] = a


@numba.njit(cache=True)
def first_bad(commands: np.ndarray) -> int:
    """Index of the first robot with a non-finite command (n, 2); -1 if none."""
    for i in range(commands.shape[0]):
        if not (math.isfinite(commands[i, 0]) and math.isfinite(commands[i, 1])):
            return i
    return -1


@numba.njit(cache=True)
def plan(commands: np.ndarray, params: np.ndarray, state: np.ndarray, tallies: np.ndarray, pose: np.ndarray, dt: float) -> int:
    """`drive` on the packed arrays (column layout above) when every command (n, 2) is finite;
    otherwise nothing changes and the first robot with a non-finite one is returned (-1: none)."""
    bad = first_bad(commands)
    if bad < 0:
        drive(
            commands, state[:, WHEEL_SPEED : WHEEL_SPEED + 2], params[:, COMMAND_MAX], params[:, MAX_SPEED], params[:, LAG],
            params[:, MAX_CHANGE], dt, params[:, TICKS_PER_RAD], state[:, TICK_CARRY : TICK_CARRY + 2],
            tallies[:, TICKS : TICKS + 2], params[:, REAL_RADIUS : REAL_RADIUS + 2],
            state[:, SLIP : SLIP + 2], params[:, TRACK], pose, state[:, MOVE : MOVE + 2], state[:, ALPHA],
        )  # fmt: skip
    return bad


@numba.njit(cache=True)
def glide(pose: np.ndarray, params: np.ndarray, motion: np.ndarray, rows: np.ndarray, dt: float) -> np.ndarray:
    """The poses (n, 3) after a quiet step (`settle`): what pymunk's step and its position update
    give a body that enters the step at rest and meets nothing, the same operations in the same
    order (`cpBodyUpdateVelocity` with no gravity and no damping, then `cpBodyUpdatePosition`), so
    that they agree bit for bit."""
    after = np.empty_like(pose)
    for i in range(pose.shape[0]):
        r = rows[i]
        m_inv, i_inv = 1.0 / params[i, MASS], 1.0 / params[i, MOMENT]
        # velocity 0 times damping 1 plus (gravity 0 + force / mass) dt, and the position plus
        # (velocity + bias 0) dt: the zeros written out, as adding one can change the sign of a zero
        vx = 0.0 * 1.0 + (0.0 + motion[r, 3] * m_inv) * dt
        vy = 0.0 * 1.0 + (0.0 + motion[r, 4] * m_inv) * dt
        w = 0.0 * 1.0 + motion[r, 5] * i_inv * dt
        after[i, 0] = pose[i, 0] + (vx + 0.0) * dt
        after[i, 1] = pose[i, 1] + (vy + 0.0) * dt
        after[i, 2] = pose[i, 2] + (w + 0.0) * dt
    return after


@numba.njit(cache=True)
def measure(
    before: np.ndarray,
    after: np.ndarray,
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
    """Mouse counts from each body's true motion `before` -> `after`, read as the constant twist
    between them; a mouse over a hole reads nothing.

    counts_per_metre is 0 for a robot without a mouse; max_step the longest displacement per
    step (m) the sensor tracks; noise (n, 2) counts per sqrt m of floor passed (drawn per step):
    the error's variance grows with the distance the sensor moved, whatever the step."""
    for i in range(before.shape[0]):
        c0, s0 = math.cos(before[i, 2]), math.sin(before[i, 2])
        c1, s1 = math.cos(after[i, 2]), math.sin(after[i, 2])
        if counts_per_metre[i] == 0.0:
            continue
        dx, dy = after[i, 0] - before[i, 0], after[i, 1] - before[i, 1]
        bx, by = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
        dth = after[i, 2] - before[i, 2]
        h = 0.5 * dth
        cos_h, sinc_h = half_angle(h)
        sin_h = sinc_h * h
        tx, ty = (cos_h * bx + sin_h * by) / sinc_h, (-sin_h * bx + cos_h * by) / sinc_h
        fx, fy = tx - dth * mount[i, 1], ty + dth * mount[i, 0]
        mx, my = mount[i, 0], mount[i, 1]
        lifted = in_hole(after[i, 0] + c1 * mx - s1 * my, after[i, 1] + s1 * mx + c1 * my, hole, origin, cell, outside_is_hole)
        if lifted or fx * fx + fy * fy > max_step[i] * max_step[i]:
            fx = fy = 0.0
        passed = math.sqrt(math.hypot(fx, fy))
        for axis, metres in enumerate((fx, fy)):
            whole, fraction = quantize_one(metres * counts_per_metre[i] + noise[i, axis] * passed + mouse_carry[i, axis])
            counts[i, axis] = whole
            mouse_carry[i, axis] = fraction


@numba.njit(cache=True)
def measure_all(
    before: np.ndarray, after: np.ndarray, params: np.ndarray, state: np.ndarray, tallies: np.ndarray, hole: np.ndarray, scalars: np.ndarray
) -> None:
    """`measure` on the packed arrays (column layout above)."""
    measure(
        before, after, params[:, MOUNT : MOUNT + 2], params[:, COUNTS_PER_METRE], params[:, MAX_STEP], state[:, MOUSE_NOISE : MOUSE_NOISE + 2],
        state[:, MOUSE_CARRY : MOUSE_CARRY + 2], tallies[:, COUNTS : COUNTS + 2], hole, scalars[ORIGIN : ORIGIN + 2], scalars[CELL],
        scalars[OUTSIDE_IS_HOLE] != 0.0,
    )  # fmt: skip
