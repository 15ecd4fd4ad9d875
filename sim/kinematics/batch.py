"""Exact arc motion, encoders and mouse for a batch of robots in one compiled pass (numba).

The numpy functions of this package are the reference: clear, broadcasting, one job each. A
simulation of thousands of robots pays for every temporary array they create, so these kernels do
the same arithmetic in one pass per step (tests check them against the reference to rounding).

Layout: every per-robot quantity is a row of N values (structure of arrays: pose (3, N) holds the
rows x, y, θ), so the loop over robots loads and stores each quantity contiguously and the compiler
runs it four or eight robots at a time in SIMD lanes. The serial kernels take all robots in one
loop, the parallel ones one part per thread with the same code; every robot's arithmetic is the
same in a SIMD lane or alone (no fastmath, explicit fused multiply-adds), so they agree bit for bit.

No fastmath flag is set. The arc pass rounds each multiply-add once, by an explicit fused
multiply-add (`_fma`, LLVM's llvm.fma): a third more robot-steps per second, and a pose closer to
the exact one than two roundings give; llvm.fma has one result wherever and however the loop is
compiled. (fastmath "contract", which lets the compiler choose which pairs to fuse, is as fast, but
its choice depends on the context the loop was compiled in: a serial kernel compiled in one process
and a parallel one in another disagreed in the last bit.) Counting keeps the reference's operations
in the reference's order, so ticks and counts equal the reference's exactly.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from sim.kinematics.arc import _ADVANCE_SERIES_LIMIT, _COS, _SERIES_LIMIT, _SINC

INNER = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True}
"""numba's options for a kernel that only other kernels call (`@numba.njit(cache=True, **INNER)`):
no wrappers for callers in Python or C, which numba otherwise compiles and caches with every
kernel, a fixed part of each one's first compile (the main job's odometry and world kernels: about
a tenth of their CPU). Such a kernel called from Python is refused ("no cpython wrapper"); its
`py_func` is the plain function."""


class Drive(NamedTuple):
    """What the robots of a batch share (`step_batch`): the track (m), encoder ticks per metre of
    rim, the mouse's mount x, y in the body frame (m) and its counts per metre."""

    track: float
    ticks_per_metre: float
    mount_x: float
    mount_y: float
    counts_per_metre: float


class Counters(NamedTuple):
    """The robots' counting (`step_batch`), (2, N) each, in place: the encoders' carries (rows
    left, right) and this step's ticks (int64), the mouse's carries and this step's counts (int64;
    rows forward, left)."""

    tick_carry: np.ndarray
    ticks: np.ndarray
    mouse_carry: np.ndarray
    counts: np.ndarray


@intrinsic
def _fma(typingctx, a, b, c):
    """a·b + c rounded once: one instruction on x86-64 CPUs since 2013 and on ARM64, a correct but
    slow library call on older ones."""
    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        return builder.call(builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double] * 3)), args)

    return types.float64(types.float64, types.float64, types.float64), codegen


@numba.njit(cache=True, inline="always")
def _mul_add(a: float, b: float, c: float) -> float:
    """a·b + c rounded twice, in IEEE order: the world's arc, whose runs are stored bit for bit."""
    return a * b + c


@numba.njit(cache=True, inline="always")
def _series(h: float, mul_add) -> tuple[float, float]:
    """(cos h, sin h / h) by the series of `arc.half_angle_terms`, for |h| <= the series limit;
    `mul_add` is `_mul_add` (the world's arc) or `_fma` (the batch kernels)."""
    h2 = h * h
    sinc = _SINC[5]
    for k in range(4, -1, -1):
        sinc = mul_add(sinc, h2, _SINC[k])
    cos = _COS[6]
    for k in range(5, -1, -1):
        cos = mul_add(cos, h2, _COS[k])
    return cos, sinc


@numba.njit(cache=True, inline="always")
def half_angle(h: float) -> tuple[float, float]:
    """(cos h, sin h / h), the series below the limit as in `arc.half_angle_terms`."""
    if abs(h) > _SERIES_LIMIT:
        return math.cos(h), math.sin(h) / h
    return _series(h, _mul_add)


@numba.njit(cache=True, inline="always")
def exact_arc(s_left: float, s_right: float, track: float) -> tuple[float, float, float, float]:
    """(chord, α, cos α/2, sin α/2) of the exact arc from wheel arcs (seed 002, eqs 1.3–1.15),
    continuous through α → 0: the one compiled arc of the project (these kernels and the world's)."""
    alpha = (s_right - s_left) / track
    h = 0.5 * alpha
    cos_h, sinc_h = half_angle(h)
    return 0.5 * (s_left + s_right) * sinc_h, alpha, cos_h, sinc_h * h


@numba.njit(cache=True, inline="always")
def advance_one(x: float, y: float, theta: float, s: float, alpha: float, end_heading: bool) -> tuple[float, float, float]:
    """`arc.advance` for compiled code that steps odometry on the robot: the same operations in
    the same order and nothing fused, so its poses equal `advance`'s bit for bit."""
    return advance_chord(x, y, theta, chord_of(s, alpha), alpha, end_heading)


@numba.njit(cache=True, inline="always")
def chord_of(s: float, alpha: float) -> float:
    """`advance_one`'s chord of an arc of length s turning by alpha (its first half)."""
    h = 0.5 * alpha
    sinc = math.sin(h) / h if abs(h) > _ADVANCE_SERIES_LIMIT else 1.0 - h * h / 6.0
    return s * sinc


@numba.njit(cache=True, inline="always")
def advance_chord(x: float, y: float, theta: float, chord: float, alpha: float, end_heading: bool) -> tuple[float, float, float]:
    """`advance_one`'s second half: the `chord_of` an arc laid from the pose (for poses that share
    an arc, its chord worked out once)."""
    direction = theta + (alpha if end_heading else 0.5 * alpha)
    return x + chord * math.cos(direction), y + chord * math.sin(direction), theta + alpha


@numba.njit(cache=True, inline="always")
def quantize_one(total: float) -> tuple[float, float]:
    """(whole counts, carry in [0, 1)) of a running total, as `quantize.quantize`: a total just
    below an integer whose fraction rounds to 1.0 counts that whole event instead. np.floor stays a
    float (numba's math.floor makes an int64 and back: two conversions more per count)."""
    whole = np.floor(total)
    fraction = total - whole
    if fraction >= 1.0:
        return whole + 1.0, 0.0
    return whole, fraction


@numba.njit(cache=True, inline="always")
def _advance(moving: tuple[float, float, float, float, float], chord: float, alpha: float, cos_h: float, sin_h: float) -> tuple[float, float, float, float, float]:
    """Pose and heading direction `moving` = (x, y, θ, c, s), (c, s) = (cos θ, sin θ), after an arc:
    the chord runs along the mid heading θ + α/2, and the heading turns by α/2 twice. Carrying (c,
    s) saves the heading's trig; one Newton step back onto the unit circle keeps it from drifting
    in length. Multiply-adds are fused (`_fma`)."""
    x, y, theta, c, s = moving
    mid_c, mid_s = _fma(c, cos_h, -s * sin_h), _fma(s, cos_h, c * sin_h)
    c, s = _fma(mid_c, cos_h, -mid_s * sin_h), _fma(mid_s, cos_h, mid_c * sin_h)
    norm = 1.5 - 0.5 * _fma(c, c, s * s)
    return _fma(chord, mid_c, x), _fma(chord, mid_s, y), theta + alpha, c * norm, s * norm


@numba.njit(cache=True, inline="always")
def _arc_one(x: float, y: float, theta: float, c: float, s: float, s_left: float, s_right: float, alpha: float) -> tuple:
    """(x, y, θ, cos θ, sin θ, beyond) of a robot after its exact arc (`exact_arc`, `_advance`) by
    `half_angle`'s series with the multiply-adds fused, with no call and no branch, so that the
    loop around it runs in SIMD lanes: the half angle is clipped to the series' range, and a robot
    turning beyond it (beyond: a turn of more than 0.5 rad in one step) keeps its pose here, for
    `_arcs_beyond`. (Scalars in and out: array arguments of an inlined function would cost two
    reference counts each per robot.)"""
    h = 0.5 * alpha
    beyond = abs(h) > _SERIES_LIMIT
    h = min(max(h, -_SERIES_LIMIT), _SERIES_LIMIT)
    cos_h, sinc_h = _series(h, _fma)
    moved = _advance((x, y, theta, c, s), 0.5 * (s_left + s_right) * sinc_h, alpha, cos_h, sinc_h * h)
    if beyond:
        return x, y, theta, c, s, beyond
    return moved[0], moved[1], moved[2], moved[3], moved[4], beyond


@numba.njit(cache=True)
def _arcs_beyond(x: np.ndarray, y: np.ndarray, theta: np.ndarray, c: np.ndarray, s: np.ndarray, s_left: np.ndarray,
                 s_right: np.ndarray, track: float) -> None:
    """The robots `_arc_one` left (turning beyond the series' range) moved by `exact_arc`'s trig."""
    for i in range(x.shape[0]):
        chord, alpha, cos_h, sin_h = exact_arc(s_left[i], s_right[i], track)
        if abs(0.5 * alpha) > _SERIES_LIMIT:
            x[i], y[i], theta[i], c[i], s[i] = _advance((x[i], y[i], theta[i], c[i], s[i]), chord, alpha, cos_h, sin_h)


@numba.njit(cache=True, inline="always")
def _count_one(s_left: float, s_right: float, alpha: float, drive: Drive, carries: tuple[float, float, float, float]) -> tuple:
    """A robot's encoder ticks and carries (left, right), then mouse counts and carries (forward,
    left): `quantize_one` of each running total, carried from `carries` (left, right, forward,
    left). The mouse at (mount_x, mount_y) in the body frame moves by (s − α·mount_y, α·mount_x)."""
    ticks_per_metre, mount_x, mount_y, counts_per_metre = drive.ticks_per_metre, drive.mount_x, drive.mount_y, drive.counts_per_metre
    carry_left, carry_right, carry_forward, carry_lateral = carries
    ticks_left, carry_left = quantize_one(s_left * ticks_per_metre + carry_left)
    ticks_right, carry_right = quantize_one(s_right * ticks_per_metre + carry_right)
    forward, carry_forward = quantize_one((0.5 * (s_left + s_right) - alpha * mount_y) * counts_per_metre + carry_forward)
    lateral, carry_lateral = quantize_one(alpha * mount_x * counts_per_metre + carry_lateral)
    return ticks_left, carry_left, ticks_right, carry_right, forward, carry_forward, lateral, carry_lateral


@numba.njit(cache=True)
def _pose_rows(x: np.ndarray, y: np.ndarray, theta: np.ndarray, c: np.ndarray, s: np.ndarray, s_left: np.ndarray,
               s_right: np.ndarray, track: float) -> None:
    """Robots along their exact arcs, in place (the rows of one part)."""
    beyond = 0
    for i in range(x.shape[0]):
        alpha = (s_right[i] - s_left[i]) / track
        x[i], y[i], theta[i], c[i], s[i], far = _arc_one(x[i], y[i], theta[i], c[i], s[i], s_left[i], s_right[i], alpha)
        beyond += far
    if beyond:
        _arcs_beyond(x, y, theta, c, s, s_left, s_right, track)


@numba.njit(cache=True)
def _batch_rows(motion: tuple, wheels: tuple[np.ndarray, np.ndarray], drive: Drive, counting: tuple) -> None:
    """Robots along their exact arcs and their ticks and counts, in place, in one loop (the rows of
    one part): each wheel arc is loaded, and each turn divided out, once. `motion`: the rows x, y,
    θ, cos θ, sin θ; `wheels`: the wheel arcs' rows (left, right); `counting`: the rows of the
    encoders' carries and ticks (left, right), then the mouse's (forward, left), as `Counters`.
    (Rows, not 2-D blocks: the loop runs in SIMD lanes over contiguous rows.)"""
    x, y, theta, c, s = motion
    s_left, s_right = wheels
    track = drive.track
    carry_left, carry_right, ticks_left, ticks_right, carry_forward, carry_lateral, counts_forward, counts_lateral = counting
    beyond = 0
    for i in range(x.shape[0]):
        alpha = (s_right[i] - s_left[i]) / track
        x[i], y[i], theta[i], c[i], s[i], far = _arc_one(x[i], y[i], theta[i], c[i], s[i], s_left[i], s_right[i], alpha)
        beyond += far
        (ticks_left[i], carry_left[i], ticks_right[i], carry_right[i], counts_forward[i], carry_forward[i], counts_lateral[i],
         carry_lateral[i]) = _count_one(s_left[i], s_right[i], alpha, drive, (carry_left[i], carry_right[i], carry_forward[i], carry_lateral[i]))
    if beyond:
        _arcs_beyond(x, y, theta, c, s, s_left, s_right, track)


@numba.njit(cache=True)
def _check_rows(array: np.ndarray, rows: int, robots: int) -> None:
    """A kernel reads past the end of a short row without a word: refuse the wrong shape instead."""
    if array.shape[0] != rows or array.shape[1] != robots:
        raise ValueError("step_batch/step_poses: pose must be (3, N) and every other per-robot array (2, N), one column per robot")


@numba.njit(cache=True)
def _check_poses(pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray) -> int:
    robots = pose.shape[1]
    _check_rows(pose, 3, robots)
    _check_rows(heading_dir, 2, robots)
    _check_rows(wheel_arcs, 2, robots)
    return robots


@numba.njit(cache=True)
def _check_counts(robots: int, counters: Counters) -> None:
    _check_rows(counters.tick_carry, 2, robots)
    _check_rows(counters.ticks, 2, robots)
    _check_rows(counters.mouse_carry, 2, robots)
    _check_rows(counters.counts, 2, robots)


@numba.njit(cache=True)
def _part(k: int, parts: int, robots: int) -> tuple[int, int]:
    """Robots lo:hi of part k of `parts` (as even as can be)."""
    return robots * k // parts, robots * (k + 1) // parts


@numba.njit(cache=True)
def _poses_part(lo: int, hi: int, pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, track: float) -> None:
    _pose_rows(pose[0, lo:hi], pose[1, lo:hi], pose[2, lo:hi], heading_dir[0, lo:hi], heading_dir[1, lo:hi],
               wheel_arcs[0, lo:hi], wheel_arcs[1, lo:hi], track)  # fmt: skip


@numba.njit(cache=True)
def _batch_part(lo: int, hi: int, pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, drive: Drive, counters: Counters) -> None:
    tick_carry, ticks, mouse_carry, counts = counters
    _batch_rows((pose[0, lo:hi], pose[1, lo:hi], pose[2, lo:hi], heading_dir[0, lo:hi], heading_dir[1, lo:hi]), (wheel_arcs[0, lo:hi], wheel_arcs[1, lo:hi]), drive,
                (tick_carry[0, lo:hi], tick_carry[1, lo:hi], ticks[0, lo:hi], ticks[1, lo:hi],
                 mouse_carry[0, lo:hi], mouse_carry[1, lo:hi], counts[0, lo:hi], counts[1, lo:hi]))  # fmt: skip


@numba.njit(cache=True)
def step_poses(pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, track: float) -> None:
    """Advance N robots along their exact arcs by one step, in place: poses only, for many
    idealised robots at once (rollouts of candidate wheel commands, sweeps, vector environments).

    pose (3, N): rows x, y (m) and θ (rad, continuous); heading_dir (2, N) = (cos θ, sin θ), carried
    so that no trig of the heading is needed (renormalised every step); wheel_arcs (2, N) = rows
    s_l, s_r (m) of this step; track (m)."""
    _poses_part(0, _check_poses(pose, heading_dir, wheel_arcs), pose, heading_dir, wheel_arcs, track)


def step_poses_parallel(pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, track: float) -> None:
    """`step_poses` (same arguments) with the robots shared out over the cores (numba threads), one
    part each: bit-identical to it, since each part runs the same code on its own columns."""
    _poses_parallel(numba.get_num_threads(), pose, heading_dir, wheel_arcs, track)


@numba.njit(cache=True, parallel=True)
def _poses_parallel(parts: int, pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, track: float) -> None:
    """`step_poses` in `parts` parts over the threads (the thread count is an argument: a compiled
    function that asks for it cannot be cached)."""
    robots = _check_poses(pose, heading_dir, wheel_arcs)
    for k in numba.prange(parts):
        lo, hi = _part(k, parts, robots)
        _poses_part(lo, hi, pose, heading_dir, wheel_arcs, track)


def step_batch(pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, drive: Drive, counters: Counters) -> None:
    """Advance N robots by one step, in place: `step_poses` (on `drive.track`), then each robot's
    encoder ticks and mouse counts of the step into `counters`. (`drive` and `counters` reach the
    compiled kernel as plain tuples: numba's dispatch types a named tuple in Python, some 0.5 µs
    each on every call, a plain one in C.)"""
    _step_batch(pose, heading_dir, wheel_arcs, tuple(drive), tuple(counters))


@numba.njit(cache=True)
def _step_batch(pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, drive: tuple, counting: tuple) -> None:
    """`step_batch` with the values of a `Drive` and the arrays of `Counters` as plain tuples."""
    counters = Counters(*counting)
    robots = _check_poses(pose, heading_dir, wheel_arcs)
    _check_counts(robots, counters)
    _batch_part(0, robots, pose, heading_dir, wheel_arcs, Drive(*drive), counters)


def step_batch_parallel(pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, drive: Drive, counters: Counters) -> None:
    """`step_batch` (same arguments) with the robots shared out over the cores (numba threads), one
    part each: bit-identical to it, since each part runs the same code on its own columns. Between calls
    OpenMP's threads spin a while before they sleep (its default): called step after step, they are
    awake for the next call. Threads that sleep at once (OMP_WAIT_POLICY=passive) cost a wake-up of
    some 70 µs per call on a 2-core VM, more than a whole 10,000-robot step. Even awake, starting
    them costs 2-6 µs a call there, and the second thread's part often ends 3-5 µs after the same
    part on the calling thread: up to a third of a serial 10,000-robot step. It pays from thousands
    of robots, fully from tens of thousands, and only on cores that other work leaves free."""
    _batch_parallel(numba.get_num_threads(), pose, heading_dir, wheel_arcs, tuple(drive), tuple(counters))


@numba.njit(cache=True, parallel=True)
def _batch_parallel(parts: int, pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, values: tuple, counting: tuple) -> None:
    """`step_batch` in `parts` parts over the threads (see `_poses_parallel`), `drive` and
    `counters` as plain tuples (as `_step_batch`)."""
    drive, counters = Drive(*values), Counters(*counting)
    robots = _check_poses(pose, heading_dir, wheel_arcs)
    _check_counts(robots, counters)
    for k in numba.prange(parts):
        lo, hi = _part(k, parts, robots)
        _batch_part(lo, hi, pose, heading_dir, wheel_arcs, drive, counters)
