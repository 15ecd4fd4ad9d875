"""One fused step of arc motion, encoders and mouse for a batch of robots, compiled with numba.

The numpy functions of this package are the reference: clear, broadcasting, one job each. A
simulation of thousands of robots pays for every temporary array they create, so this kernel does
the same arithmetic in one pass per robot (tests check it against the reference to rounding).
"""

from __future__ import annotations

import math
import os

# The parallel kernel is called once per step between serial work; OpenMP's default of spinning
# idle threads for a while after each call takes the cores from that work (and from anyone else on
# a shared machine). Threads that sleep cost a wake-up per call instead. A user's own setting wins;
# it must be in place before numba loads its OpenMP pool (the first parallel call).
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numba  # noqa: E402
import numpy as np  # noqa: E402

from sim.kinematics.arc import _COS, _SERIES_LIMIT, _SINC  # noqa: E402


@numba.njit(cache=True, inline="always")
def half_angle(h: float) -> tuple[float, float]:
    """(cos h, sin h / h), the series below the limit as in `arc.half_angle_terms`."""
    if abs(h) > _SERIES_LIMIT:
        return math.cos(h), math.sin(h) / h
    h2 = h * h
    sinc = _SINC[5]
    for k in range(4, -1, -1):
        sinc = sinc * h2 + _SINC[k]
    cos = _COS[6]
    for k in range(5, -1, -1):
        cos = cos * h2 + _COS[k]
    return cos, sinc


@numba.njit(cache=True, inline="always")
def exact_arc(s_left: float, s_right: float, track: float) -> tuple[float, float, float, float]:
    """(chord, α, cos α/2, sin α/2) of the exact arc from wheel arcs (seed 002, eqs 1.3–1.15),
    continuous through α → 0: the one compiled arc of the project (this kernel and the world's)."""
    alpha = (s_right - s_left) / track
    h = 0.5 * alpha
    cos_h, sinc_h = half_angle(h)
    return 0.5 * (s_left + s_right) * sinc_h, alpha, cos_h, sinc_h * h


@numba.njit(cache=True, inline="always")
def quantize_one(total: float) -> tuple[float, float]:
    """(whole counts, carry in [0, 1)) of a running total, as `quantize.quantize`: a total just
    below an integer whose fraction rounds to 1.0 counts that whole event instead."""
    whole = math.floor(total)
    fraction = total - whole
    if fraction >= 1.0:
        return whole + 1.0, 0.0
    return whole, fraction


@numba.njit(cache=True, inline="always")
def _step_one(
    i: int, pose: np.ndarray, heading_dir: np.ndarray, wheel_arcs: np.ndarray, track: float, ticks_per_metre: float,
    tick_carry: np.ndarray, ticks: np.ndarray, mount: np.ndarray, counts_per_metre: float, mouse_carry: np.ndarray,
    counts: np.ndarray,
) -> None:
    """Robot i of `step_batch`: it touches row i of every array only, so robots may run in any order
    or on any core with the same result."""
    s_l, s_r = wheel_arcs[i, 0], wheel_arcs[i, 1]
    s = 0.5 * (s_l + s_r)
    chord, alpha, cos_h, sin_h = exact_arc(s_l, s_r, track)
    c, sn = heading_dir[i, 0], heading_dir[i, 1]
    mid_c, mid_s = c * cos_h - sn * sin_h, sn * cos_h + c * sin_h
    pose[i, 0] += chord * mid_c
    pose[i, 1] += chord * mid_s
    pose[i, 2] += alpha
    c, sn = mid_c * cos_h - mid_s * sin_h, mid_s * cos_h + mid_c * sin_h
    norm = 1.5 - 0.5 * (c * c + sn * sn)  # one Newton step back onto the unit circle
    heading_dir[i, 0], heading_dir[i, 1] = c * norm, sn * norm
    for w in range(2):
        ticks[i, w], tick_carry[i, w] = quantize_one(wheel_arcs[i, w] * ticks_per_metre + tick_carry[i, w])
    for axis, metres in enumerate((s - alpha * mount[1], alpha * mount[0])):
        counts[i, axis], mouse_carry[i, axis] = quantize_one(metres * counts_per_metre + mouse_carry[i, axis])


@numba.njit(cache=True)
def step_batch(
    pose: np.ndarray,
    heading_dir: np.ndarray,
    wheel_arcs: np.ndarray,
    track: float,
    ticks_per_metre: float,
    tick_carry: np.ndarray,
    ticks: np.ndarray,
    mount: np.ndarray,
    counts_per_metre: float,
    mouse_carry: np.ndarray,
    counts: np.ndarray,
) -> None:
    """Advance N robots by one step, in place.

    pose (N, 3) world poses; heading_dir (N, 2) = (cos, sin) of the heading, carried so that no
    trig of the heading is needed (renormalised every step); wheel_arcs (N, 2) = (s_l, s_r) in m;
    tick_carry/ticks (N, 2) encoder carries and this step's ticks; mount (2,) mouse position in the
    body frame; mouse_carry/counts (N, 2) the mouse's carries and counts (forward, left)."""
    for i in range(pose.shape[0]):
        _step_one(i, pose, heading_dir, wheel_arcs, track, ticks_per_metre, tick_carry, ticks, mount, counts_per_metre, mouse_carry, counts)


@numba.njit(cache=True, parallel=True)
def step_batch_parallel(
    pose: np.ndarray,
    heading_dir: np.ndarray,
    wheel_arcs: np.ndarray,
    track: float,
    ticks_per_metre: float,
    tick_carry: np.ndarray,
    ticks: np.ndarray,
    mount: np.ndarray,
    counts_per_metre: float,
    mouse_carry: np.ndarray,
    counts: np.ndarray,
) -> None:
    """`step_batch` (same arguments) with the robots shared out over the cores (numba threads):
    bit-identical to it, since each robot's arithmetic is the same and touches its own rows only.
    Worth it from some thousands of robots; below, waking the threads costs more than it saves."""
    for i in numba.prange(pose.shape[0]):
        _step_one(i, pose, heading_dir, wheel_arcs, track, ticks_per_metre, tick_carry, ticks, mount, counts_per_metre, mouse_carry, counts)
