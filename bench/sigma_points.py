"""What the sigma points and the slide hypotheses cost (#49): the default estimators' compiled step
of one robot (`bots.odometry.batch.DefaultOdometry`, called once a step as a run calls it) with
them, against the same step less their work (the same compiled calls on the same readings, in
one compiled loop), on the readings of a maze run.
"""

from __future__ import annotations

import time

import numba
import numpy as np

from bots.odometry.batch import COVARIANCES, DefaultOdometry
from bots.odometry.encoder import sigma_encoders_both
from bots.odometry.layout import ESTIMATE, ESTIMATES, HYPOTHESIS_WEIGHT, SIGMAS
from bots.odometry.mouse import MOUSE_SIGMAS, mouse_arc, sigma_mouse
from bots.odometry.propagation import add_offset, add_point_noise, add_spread, lay


@numba.njit(cache=True)
def _sigma_work(params: np.ndarray, state: np.ndarray, poses: np.ndarray, errors: np.ndarray, tallies: np.ndarray, cov_out: np.ndarray,
                noise: np.ndarray) -> None:  # fmt: skip
    """Every step's sigma-point and hypothesis work of `batch_step` for one robot: the points laid
    with their random parts (`noise`: a step's, (2, 2)), their spread and random parts and the
    hypotheses' offsets added to the covariances."""
    p, st = params[0], state[0]
    for n in range(tallies.shape[0]):
        left, right, forward, lateral = float(tallies[n, 0]), float(tallies[n, 1]), float(tallies[n, 2]), float(tallies[n, 3])
        sigma_encoders_both(p, st, left, right, noise)
        sigma_mouse(p, st.sigmas[ESTIMATE.mouse], st.sigma_noises[ESTIMATE.mouse], forward, lateral, noise, st.turns[ESTIMATE.mouse])
        s, alpha = mouse_arc(p, forward, lateral)
        lay(st.mouse_watch.hypothesis, s, alpha, False)
        lay(st.fused_watch.hypothesis, s, alpha, False)
        add_spread(st.sigmas[ESTIMATE.encoders], SIGMAS, poses[0, ESTIMATE.encoders], cov_out[0, ESTIMATE.encoders])
        add_spread(st.sigmas[ESTIMATE.firmware], SIGMAS, poses[0, ESTIMATE.firmware], cov_out[0, ESTIMATE.firmware])
        add_point_noise(st.sigma_noises[ESTIMATE.encoders], SIGMAS, errors[0, ESTIMATE.encoders], cov_out[0, ESTIMATE.encoders])
        add_point_noise(st.sigma_noises[ESTIMATE.firmware], SIGMAS, errors[0, ESTIMATE.firmware], cov_out[0, ESTIMATE.firmware])
        add_spread(st.sigmas[ESTIMATE.mouse], MOUSE_SIGMAS, poses[0, ESTIMATE.mouse], cov_out[0, ESTIMATE.mouse])
        add_point_noise(st.sigma_noises[ESTIMATE.mouse], MOUSE_SIGMAS, errors[0, ESTIMATE.mouse], cov_out[0, ESTIMATE.mouse])
        add_offset(st.mouse_watch.hypothesis[:], poses[0, ESTIMATE.mouse], HYPOTHESIS_WEIGHT, cov_out[0, ESTIMATE.mouse])
        add_offset(st.fused_watch.hypothesis[:], poses[0, ESTIMATE.fused], HYPOTHESIS_WEIGHT, cov_out[0, ESTIMATE.fused])


def _readings(duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (T,), true poses (T, 3) and tallies (T, 4) of the main job's first `duration` s."""
    from sim.experiments.consistency import Scenario, drive

    track = drive(0, Scenario(duration=duration))
    return track.time, track.truth, np.ascontiguousarray(track.tallies, dtype=np.int64)


def sigma_point_cost(duration: float = 60.0, rounds: int = 5) -> dict[str, float]:
    """µs per step of the default estimators' step with the sigma points and hypotheses
    (`with_us`), of their share of it (`sigma_us`), and with over without (`ratio`); best of
    `rounds` (the others met a busy machine)."""
    from bots.ctbot import CTBOT
    from bots.noise import with_noise

    times, truth, tallies = _readings(duration)
    robot = with_noise(CTBOT, "realistic")
    best_with = best_sigma = float("inf")
    for _ in range(rounds + 1):  # (the first compiles or loads the kernels)
        odometry = DefaultOdometry([robot], truth[:1], [0])
        out, cov_out = np.zeros((1, 1 + ESTIMATES, 3)), np.zeros((1, ESTIMATES, COVARIANCES))
        started = time.perf_counter()
        for n, at in enumerate(times.tolist()):
            odometry.update_into(tallies[n : n + 1], at, truth[n : n + 1], out, cov_out)
        best_with = min(best_with, time.perf_counter() - started)
        fresh = DefaultOdometry([robot], truth[:1], [0])
        started = time.perf_counter()
        _sigma_work(fresh.params, fresh.state, fresh.poses, fresh.errors, tallies, cov_out, np.full((2, 2), 1e-9))
        best_sigma = min(best_sigma, time.perf_counter() - started)
    steps = len(times)
    return {"with_us": 1e6 * best_with / steps, "sigma_us": 1e6 * best_sigma / steps, "ratio": best_with / (best_with - best_sigma)}


def figures(scale: float):
    """(name, unit, thunk) of the sigma points' cost."""
    cost = {}

    def measured() -> dict[str, float]:
        if not cost:
            cost.update(sigma_point_cost(max(60.0 * scale, 10.0)))
        return cost

    yield "odometry_step_us", "µs per robot-step (the default estimators' compiled step, as a run calls it)", lambda: measured()["with_us"]
    yield "sigma_points_us", "µs per robot-step (the sigma points' and slide hypotheses' share of it)", lambda: measured()["sigma_us"]
    yield "sigma_points_ratio", "(the step with them / without them)", lambda: measured()["ratio"]
