"""The compiled parts of the Monte Carlo localiser against closed forms: the IR raw values'
distance intervals, the scan likelihood at the world's own pose, the motion, the low-variance
resampler and the particles' mean and covariance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bots.ctbot import CTBOT
from bots.ir_curve import gp2d12
from bots.odometry.particles import low_variance_resample, mean_and_covariance, move_particles
from sim.kinematics import wrap_angle
from sim.world import World, localising
from sim.world.files import load_world
from sim.world.localising import SHARED_FROM, MapScan, raw_intervals


@pytest.fixture(scope="module")
def maze_scan() -> MapScan:
    return MapScan(load_world("maze"), CTBOT)


@settings(max_examples=200, deadline=None)
@given(distance=st.floats(0.0, 0.95), side=st.sampled_from(("left", "right")))
def test_a_distance_lies_in_an_interval_of_the_raw_value_it_reads(distance: float, side: str) -> None:
    """Every distance (m) is inside one of the intervals `raw_intervals` lists for the raw value the
    curve gives it (to the grid's half step, 10 um: the intervals' edges lie between grid points)."""
    curve = gp2d12(side)
    low, table = raw_intervals(curve)
    rows = table[int(curve.lookup(np.array([distance]))[0]) - low]
    rows = rows[~np.isnan(rows[:, 0])]
    assert np.any((rows[:, 0] - 1e-5 <= distance) & (distance <= rows[:, 1] + 1e-5))


def test_each_raw_value_s_intervals_do_not_overlap_and_the_far_one_reaches_infinity() -> None:
    """The intervals of all raw values tile the distances: sorted, each ends where the next begins;
    the first starts at -inf (noise clipped at 0), the last, `beyond`'s, ends at +inf."""
    for side in ("left", "right"):
        curve = gp2d12(side)
        low, table = raw_intervals(curve)
        rows = table.reshape(-1, 2)
        rows = rows[~np.isnan(rows[:, 0])]
        rows = rows[np.argsort(rows[:, 0])]
        assert rows[0, 0] == -math.inf and rows[-1, 1] == math.inf
        np.testing.assert_array_equal(rows[1:, 0], rows[:-1, 1])
        beyond = table[int(np.floor(curve.beyond + 0.5)) - low]
        assert math.inf in beyond[:, 1]


def test_a_noise_free_scan_is_likeliest_at_the_robot_s_own_pose(maze_scan: MapScan) -> None:
    """Noise-free readings of the c't-Bot at its start in the maze (facing north along a corridor
    towards a wall across it): the particle at its pose is as likely as `best` says any pose could
    be to within a raw unit (at least 30 % of it); 3 cm nearer the wall or turned 10 degrees, far
    less likely; 3 cm sideways, along the wall ahead, exactly as likely (the scan cannot tell)."""
    world = World(load_world("maze"))
    world.add_robot(CTBOT)
    pose = world.poses()[0]
    assert pose[2] == pytest.approx(math.pi / 2)
    raw = world.read_all()[0].ir_raw
    poses = np.array([pose, pose + (0.0, 0.03, 0.0), pose + (0.0, 0.0, math.radians(10)), pose + (0.03, 0.0, 0.0)])
    out = np.empty(len(poses))
    maze_scan.likelihood(poses, raw, out)
    assert out[0] >= 0.3 * maze_scan.best(raw)
    assert np.all(out[1:3] < 1e-3 * out[0])
    assert out[3] == out[0]


def test_a_particle_in_a_wall_is_ruled_out(maze_scan: MapScan) -> None:
    """The maze's outer wall runs along x = 0: a robot centred 2 cm from it cannot be there."""
    out = np.empty(1)
    maze_scan.likelihood(np.array([[0.02, 0.36, 0.0]]), np.array([200, 200]), out)
    assert out[0] == 0.0


def test_free_poses_leave_the_robot_clear_of_every_wall(maze_scan: MapScan) -> None:
    """Every free pose is one where the world would accept the robot (no wall nearer than its radius)."""
    poses = maze_scan.free(np.random.default_rng(1), 300)
    assert len(poses) == 300
    out = np.empty(len(poses))
    maze_scan.likelihood(poses, np.array([200, 200]), out)
    assert np.all(out > 0.0)
    lo, hi = np.array(load_world("maze").bounds[:2]), np.array(load_world("maze").bounds[2:])
    assert np.all((poses[:, :2] > lo) & (poses[:, :2] < hi))


@pytest.mark.parametrize(("particles", "out", "raw"), [((5, 3), (1,), (2,)), ((5, 3), (5,), (1,)), ((5, 2), (5,), (2,)), ((5,), (5,), (2,))])
def test_a_likelihood_of_other_shapes_is_refused(maze_scan: MapScan, particles: tuple, out: tuple, raw: tuple) -> None:
    """A user's localiser may call the map with any arrays: a short `out` or too few raw values
    would have the kernel write or read past an array's end (a crash), so it is a ValueError."""
    with pytest.raises(ValueError, match="likelihood takes"):
        maze_scan.likelihood(np.zeros(particles), np.full(raw, 200), np.empty(out))


def test_a_likelihood_takes_particles_of_any_number_type_and_refuses_an_out_it_cannot_write(maze_scan: MapScan) -> None:
    """Integer particles are read as floats (no second compile of the kernel); an `out` of ints, a
    list or a read-only array is a ValueError, not a silent copy or a thread's traceback."""
    poses = maze_scan.free(np.random.default_rng(3), 5)
    floats, ints = np.empty(5), np.empty(5)
    maze_scan.likelihood(poses, np.array([250, 180]), floats)
    maze_scan.likelihood(np.round(poses).astype(int), np.array([250, 180]), ints)
    maze_scan.likelihood(np.round(poses), np.array([250, 180]), floats)
    assert np.array_equal(floats, ints)
    frozen = np.empty(5)
    frozen.flags.writeable = False
    for out in (np.empty(5, dtype=int), [0.0] * 5, frozen):
        with pytest.raises(ValueError, match="likelihood writes into"):
            maze_scan.likelihood(poses, np.array([250, 180]), out)


def test_a_scan_shared_among_threads_is_the_same_to_the_bit(maze_scan: MapScan, monkeypatch: pytest.MonkeyPatch) -> None:
    """A search's set (SHARED_FROM particles and more) is cut into slices, one thread each (four
    here, whatever the machine has): every particle's likelihood is the one a single call gives,
    since each is computed alone."""
    import numba

    poses = maze_scan.free(np.random.default_rng(2), 2 * SHARED_FROM + 7)
    raw = np.array([310, 150])
    alone, shared = np.empty(len(poses)), np.empty(len(poses))
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 1)
    maze_scan.likelihood(poses, raw, alone)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 4)
    monkeypatch.setattr(localising.os, "getloadavg", lambda: (1.0, 1.0, 1.0))  # (four free cores)
    assert localising._free_cores() == 4
    maze_scan.likelihood(poses, raw, shared)
    assert np.any(alone > 0.0) and np.array_equal(alone, shared)


def test_a_scan_is_shared_only_among_free_cores(monkeypatch: pytest.MonkeyPatch) -> None:
    """Numba's four threads, the load average 1 (this process), 2.6 and 9: four, two and one
    threads (a sweep's processes already on every core get none more)."""
    import numba

    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 4)
    for load, threads in ((1.0, 4), (2.6, 2), (9.0, 1)):
        monkeypatch.setattr(localising.os, "getloadavg", lambda load=load: (load, load, load))
        assert localising._free_cores() == threads


@given(dx=st.floats(-0.05, 0.05), dy=st.floats(-0.01, 0.01), turn=st.floats(-0.5, 0.5), own=st.floats(-0.5, 0.5), heading=st.floats(-4.0, 4.0))
def test_noise_free_motion_composes_the_increment_at_the_mid_heading(dx: float, dy: float, turn: float, own: float, heading: float) -> None:
    """With no noise a particle moves by the body-frame increment turned by its heading plus half
    the turn (the chord of an arc along its mid-angle), and turns by the turn; a particle given a
    turn of its own (one following the encoders) does the same with that turn."""
    particles = np.array([[1.0, 2.0, heading], [1.0, 2.0, heading]])
    move_particles(particles, dx, dy, turn, np.zeros(3), np.zeros((2, 3)), np.array([np.nan, own]))
    for row, taken in zip(particles, (turn, own)):
        mid = heading + 0.5 * taken
        expected = (1.0 + math.cos(mid) * dx - math.sin(mid) * dy, 2.0 + math.sin(mid) * dx + math.cos(mid) * dy, heading + taken)
        np.testing.assert_allclose(row, expected, rtol=0, atol=1e-12)


@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40), st.floats(0.0, 0.999999), st.integers(1, 60))
def test_the_low_variance_resampler_draws_each_particle_floor_or_ceil_of_its_share(raw: list[float], tooth: float, count: int) -> None:
    """A particle of weight w among `count` draws appears floor(count w) or ceil(count w) times
    (one comb of equal teeth; 1e-9 of rounding in the running sum)."""
    weights = np.array(raw) + 1e-3
    weights /= weights.sum()
    particles = np.arange(len(weights), dtype=np.float64)[:, None].repeat(3, axis=1)
    drawn = particles[low_variance_resample(weights, count, tooth / count)]
    times = np.bincount(drawn[:, 0].astype(int), minlength=len(weights))
    assert times.sum() == count
    assert np.all(times >= np.floor(count * weights - 1e-9)) and np.all(times <= np.ceil(count * weights + 1e-9))


def test_mean_and_covariance_are_numpy_s_with_headings_wrapped() -> None:
    """Against numpy's weighted mean and covariance of particles whose headings straddle +-pi, taken
    around the reference: the mean heading lies within pi of it, and the particles are folded there."""
    rng = np.random.default_rng(3)
    particles = np.column_stack((rng.normal(1.0, 0.02, 400), rng.normal(-2.0, 0.01, 400), rng.normal(math.pi, 0.05, 400)))
    particles[::2, 2] -= 2 * math.pi  # the same headings, half of them a turn lower
    weights = rng.random(400)
    weights /= weights.sum()
    mean, cov = np.empty(3), np.empty((3, 3))
    mean_and_covariance(particles, weights, 3.0, mean, cov)
    folded = particles.copy()
    folded[:, 2] = 3.0 + wrap_angle(folded[:, 2] - 3.0)
    np.testing.assert_allclose(particles, folded, atol=1e-12)
    centre = weights @ folded
    np.testing.assert_allclose(mean[:2], centre[:2], atol=1e-12)
    assert abs(wrap_angle(mean[2] - math.pi)) < 0.01 and abs(mean[2] - 3.0) <= math.pi
    np.testing.assert_allclose(cov, np.cov(folded.T, aweights=weights, bias=True), atol=1e-6)
