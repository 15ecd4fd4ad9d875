"""Compiled kernels of a robot's motion over one step, one pass over all robots each: the motor
model, encoder ticks and the exact arc (`drive`, `plan`), a quiet step's move without pymunk
(`glide`), and what the mouse measures of the true motion (`measure`). The same maths as
`sim.kinematics` (tests compare them with the reference functions). They read the tables of
`sim.world.layout` by name; the step `dt` comes from the WORLD row alone."""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.kinematics.batch import INNER, exact_arc, half_angle, quantize_one
from sim.world.kernels.floor import in_hole
from sim.world.layout import Bodies, Floor


@numba.njit(cache=True)
def drive(commands: np.ndarray, robots: np.ndarray, state: np.ndarray, tallies: np.ndarray, pose: np.ndarray, world: np.ndarray) -> None:
    """Motor model, encoder ticks and the exact-arc motion of every robot for one step.

    Writes each robot's STATE wheel_speed (rad/s at the end of the step) and tick_carry, its
    TALLIES ticks, and the unobstructed world displacement `move` and heading change `alpha` of
    the arc. Random slip (STATE's slip, sqrt m, drawn per step) puts each wheel's arc s off by
    slip * sqrt(|s|): the variance grows with the distance rolled, whatever the step (Chong and
    Kleeman's model)."""
    dt = world[0].dt
    for i in range(commands.shape[0]):
        robot, now, ticks = robots[i], state[i], tallies[i].ticks
        wheel_speed, tick_carry = now.wheel_speed, now.tick_carry
        for w in range(2):
            c = min(max(commands[i, w], -robot.command_max), robot.command_max)
            target = c / robot.command_max * robot.max_speed
            current = wheel_speed[w]
            change = (target - current) * robot.lag
            change = min(max(change, -robot.max_change), robot.max_change)
            wheel_speed[w] = current + change
            whole, fraction = quantize_one(wheel_speed[w] * dt * robot.ticks_per_rad + tick_carry[w])
            ticks[w] = whole
            tick_carry[w] = fraction
        s_l = wheel_speed[0] * dt * robot.real_radius[0]
        s_r = wheel_speed[1] * dt * robot.real_radius[1]
        s_l += now.slip[0] * math.sqrt(abs(s_l))
        s_r += now.slip[1] * math.sqrt(abs(s_r))
        chord, a, _, _ = exact_arc(s_l, s_r, robot.track)
        mid = pose[i, 2] + 0.5 * a
        now.move[0] = chord * math.cos(mid)
        now.move[1] = chord * math.sin(mid)
        now.alpha = a


@numba.njit(cache=True, **INNER)
def first_bad(commands: np.ndarray) -> int:
    """Index of the first robot with a non-finite command (n, 2); -1 if none."""
    for i in range(commands.shape[0]):
        if not (math.isfinite(commands[i, 0]) and math.isfinite(commands[i, 1])):
            return i
    return -1


@numba.njit(cache=True)
def plan(commands: np.ndarray, robots: np.ndarray, state: np.ndarray, tallies: np.ndarray, pose: np.ndarray, world: np.ndarray) -> int:
    """`drive` when every command (n, 2) is finite; otherwise nothing changes and the first robot
    with a non-finite one is returned (-1: none)."""
    bad = first_bad(commands)
    if bad < 0:
        drive(commands, robots, state, tallies, pose, world)
    return bad


@numba.njit(cache=True)
def glide(pose: np.ndarray, robots: np.ndarray, bodies: Bodies, world: np.ndarray) -> np.ndarray:
    """The poses (n, 3) after a quiet step (`settle`): what pymunk's step and its position update
    give a body that enters the step at rest and meets nothing, the same operations in the same
    order (`cpBodyUpdateVelocity` with no gravity and no damping, then `cpBodyUpdatePosition`), so
    that they agree bit for bit."""
    dt = world[0].dt
    after = np.empty_like(pose)
    for i in range(pose.shape[0]):
        body = bodies.motion[bodies.rows[i]]
        m_inv, i_inv = 1.0 / robots[i].mass, 1.0 / robots[i].moment
        # velocity 0 times damping 1 plus (gravity 0 + force / mass) dt, and the position plus
        # (velocity + bias 0) dt: the zeros written out, as adding one can change the sign of a zero
        vx = 0.0 * 1.0 + (0.0 + body.force[0] * m_inv) * dt
        vy = 0.0 * 1.0 + (0.0 + body.force[1] * m_inv) * dt
        w = 0.0 * 1.0 + body.torque * i_inv * dt
        after[i, 0] = pose[i, 0] + (vx + 0.0) * dt
        after[i, 1] = pose[i, 1] + (vy + 0.0) * dt
        after[i, 2] = pose[i, 2] + (w + 0.0) * dt
    return after


@numba.njit(cache=True)
def measure(before: np.ndarray, after: np.ndarray, robots: np.ndarray, state: np.ndarray, tallies: np.ndarray, floor: Floor) -> None:
    """Mouse counts (TALLIES' counts) from each body's true motion `before` -> `after`, read as the
    constant twist between them; a mouse over a hole reads nothing.

    A robot's counts_per_metre is 0 without a mouse; max_step is the longest displacement per step
    (m) the sensor tracks; STATE's mouse_noise is counts per sqrt m of floor passed (drawn per
    step): the error's variance grows with the distance the sensor moved, whatever the step."""
    for i in range(before.shape[0]):
        c0, s0 = math.cos(before[i, 2]), math.sin(before[i, 2])
        c1, s1 = math.cos(after[i, 2]), math.sin(after[i, 2])
        robot = robots[i]
        if robot.counts_per_metre == 0.0:
            continue
        dx, dy = after[i, 0] - before[i, 0], after[i, 1] - before[i, 1]
        bx, by = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
        dth = after[i, 2] - before[i, 2]
        h = 0.5 * dth
        cos_h, sinc_h = half_angle(h)
        sin_h = sinc_h * h
        tx, ty = (cos_h * bx + sin_h * by) / sinc_h, (-sin_h * bx + cos_h * by) / sinc_h
        mount = robot.mount
        fx, fy = tx - dth * mount[1], ty + dth * mount[0]
        mx, my = mount[0], mount[1]
        lifted = in_hole(after[i, 0] + c1 * mx - s1 * my, after[i, 1] + s1 * mx + c1 * my, floor)
        if lifted or fx * fx + fy * fy > robot.max_step * robot.max_step:
            fx = fy = 0.0
        passed = math.sqrt(math.hypot(fx, fy))
        noise, carry, counts = state[i].mouse_noise, state[i].mouse_carry, tallies[i].counts
        for axis, metres in enumerate((fx, fy)):
            whole, fraction = quantize_one(metres * robot.counts_per_metre + noise[axis] * passed + carry[axis])
            counts[axis] = whole
            carry[axis] = fraction
