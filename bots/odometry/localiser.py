"""Monte Carlo localisation (Thrun, Burgard and Fox, Probabilistic Robotics, ch. 8): odometry
held to the map by the IR sensors, as a particle filter.

Each particle is a pose the robot may be at. Motion: the robot's own fused odometry (encoders and
mouse, `bots.odometry.fused.FusedOdometry`; the encoders alone without a mouse) gives the increment
since the last update, and every particle takes it with noise of the estimators' belief
(`bots.uncertainty.Belief`: slip per metre rolled, mouse noise per metre passed, the calibration
still unknown per metre and per radian), INFLATE times wider, and roughening; while the robot is
found, each particle takes its turn either from that odometry or, switching now and then
(SWITCH), from the encoders alone, so that a slide the mouse reads as turning leaves particles on
the robot. Measurement: every EVERY steps in which the robot moved, the map (`MapModel`, handed
over by the run loop: a prior the robot carries, never its true pose) weighs each particle by the
likelihood of the IR sensors' raw values there; the set is resampled (low variance) when its
effective size falls below half. The estimate is the particles' weighted mean; its covariance is
carried from scan to scan as a linear filter's whose gain is what each scan did to the set's
spread (`MonteCarloLocaliser._carry`): the belief's own motion noise where the scans say little,
the set's spread, not a fourth of it, where they pin the pose down.

Lost and found (after augmented MCL, Probabilistic Robotics table 8.3, on a score that does not
depend on the scene): `score` is the scan's likelihood averaged over the particles, over the most
any pose could give that scan, in [0, 1]. When its fast average falls below LOST_BELOW of its slow
one, the search begins (`searching`; `lost` with it): the set grows to `recovery` particles, the old ones and the rest spread around
the estimate (a robot moved by hand), each scan draws INJECT of them anew from free floor where the
scan fits (sensor resetting, Lenser and Veloso 2000), and they move with SEARCH times the
roughening. The search ends once the fast score is back to FOUND_AT of the slow one before the
loss and the particles' spread is under FOUND_SPREAD; the set shrinks back. `lost` is cleared only
once the robot has rolled CONFIRM metres without the search beginning again and the place passes
a recall: the set, taken back along the odometry, must fit the scans since the robot was lost
too (RECALL metres of them at least, driven in VIEWS directions; RECALL_NEAR for a robot nudged),
and no other place may fit them as well (`_rivals`: a set drawn anew over the whole map where the
scan fits, taken back the same way, must end on the place), or the search begins again. The
search weighs the last scans; the recall makes a place explain all of them, and the rivals that
it alone does. A place the scans since the loss rule out, at the end of a search (the recall
then, as a veto, over whatever history there is) or at the confirmation, is dropped: the search
begins again with the whole set drawn anew from the free floor where the scan fits, not around it.

Among thousands of look-alike places in the maze the few particles the search draws on the robot
share each scan's weight with hundreds elsewhere, and the search mostly ends on a wrong place.
So once the history holds RECALL metres, and every GLOBAL_EVERY metres after, the search goes
over the whole map with all of them (`_global`): a set drawn anew, taken back through the history,
ends on one place or on none, and the set is put where it points. A place is recalled only after
AGREE such searches in a row ended on it by their fresh draws alone (besides the recall and the
rivals' check, a draw of its own). Measured at 75f03d9, before the global search ran every
GLOBAL_EVERY metres as it now does (docs/odometry.md, `python -m sim.experiments.kidnap`, the
robot kept driving solve_maze): a robot carried far across the maze
is found again, `lost` cleared on it, within RECOVERY_TIME (120 s) in 57 of 70 kidnappings (55
within 90 s, none sooner than 47 s: RECALL metres of scans at the maze's pace), said lost within
1.4 s in 69 of them (6.3 s in one), and never said found while off.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from bots.odometry.base import mouse_applies
from bots.odometry.encoder import EncoderOdometry
from bots.odometry.fused import FusedOdometry
from bots.odometry.particles import MapModel, low_variance_resample, mean_and_covariance, move_particles
from bots.readings import Readings
from bots.spec import RobotSpec
from bots.uncertainty import Belief
from sim.kinematics import relative_pose

PARTICLES = 500
"""Default particle count: 1,000 ray casts an update (two IR sensors), some 0.6 ms on a 2-core VM."""
EVERY = 5
"""Steps between measurement updates (50 ms at c't-Sim's 10 ms step; the GP2D12 gives a new
reading every 38 ms): the ray casts of one update spread over five world steps."""
INFLATE = 2.0
"""Factor on the believed motion noise's standard deviations: the particles must spread over
what the odometry cannot know between two scans (quantisation, a wheel slipping at a wall); with
the belief's own noise, a robot nudged by hand as in tests/test_localiser.py was not found again
with seeds 0 and 2 of 0-3."""
ROUGHEN = np.array((0.001, 0.001, 0.004))
"""Standard deviations (forward m, lateral m, turn rad) every particle moves by at least in an
update: roughening (Probabilistic Robotics §4.3.4), so that a set resampled onto a few poses
spreads again before the next scan and covers what the belief leaves out (a wheel slipping at a
wall: roughening only after a resampling, 1 of 5 wandering runs in the empty world, seeds 20-24,
lost the robot after a bump)."""
SEARCH = 4.0
"""While lost, roughening this many times wider: each hypothesis searches the poses around it."""
TURN_FLOOR = 0.01
"""Relative error of a turn (rad per rad turned) the motion noise never goes below."""
FAST, SLOW = 0.3, 0.02
"""Per update: how quickly the fast and the slow average of the scan score follow it."""
LOST_BELOW, FOUND_AT = 0.01, 0.5
"""Lost when the fast score falls below LOST_BELOW of the slow one (in the maze its ratio stays
above 0.25 while the filter is on the robot, and falls below 0.01 within a second of a
kidnapping); found again when it is back above FOUND_AT of the slow score before the loss."""
FOUND_SPREAD = 0.1
"""...and only once the particles' position spread (root of the covariance's trace, m) is this small."""
CONFIRM = 0.75
"""Metres the robot must roll with the search ended and not begun again before the place is
recalled (RECALL): in a world of look-alike places a wrong place fits the scans for a while, and
most are found out within this (six robots carried 2.3 m across the maze, seeds 0-5: 13 of 14
wrong places within 0.62 m). Alone it did not make a wrong "found" rare: in 30 kidnappings in
the maze (five places, seeds 0-5, 60 s after) the flag cleared on a wrong place 1.3-2.6 m off in
11, for up to 36 s; with the recall (2 m, up to 3 m) in 2, for 3.3 and 4.5 s; with RECALL and
RECALL_MOST (2.5 m, up to 4 m) in none (docs/odometry.md)."""
RECALL, RECALL_NEAR, RECALL_MOST = 3.5, 1.0, 4.0
"""Metres of scans since the robot was lost that must fit a place found again, taken back along
the odometry (`MonteCarloLocaliser._recall`), before `lost` is cleared: at least RECALL, all of
them up to RECALL_MOST (older ones are dropped: the recall's cost stays bounded, and a robot
carried by hand for a while, its wheels turning in the air, is found again once it has driven on). RECALL_NEAR where the place, taken back along the odometry, is within NEARBY
of the estimate when the robot was lost: a robot nudged is far likelier than one carried to one
look-alike place among many, so the prior needs less of the scans. In the maze a wrong place
passed a recall of 1.1 m (1.45 m off); a robot nudged was said found after 13.5-19.4 s with 1 m,
after some 21 s with 1.5 m. With 2 m, up to 3 m, a place 2 m off fitted the 2 m of scans since
the loss and one 1.4 m off the last 3 m (of 30 kidnappings in the maze); 2.5 m, up to 4 m, failed
both, and places on the robot were said found some 6 s later (docs/odometry.md). With the
global search (`MonteCarloLocaliser._global`) 2.5 m let a place 2.5 m off be found, which fitted
the scans since the loss better than the robot's own (recalls of 0.074 and 0.062); 3.5 m found
the robot there, and none of 80 kidnappings said found while off."""
NEARBY = 0.3
"""Within this distance (m) of the estimate when the robot was lost, a place is the one it was
nudged to: in the maze the next corridor is 0.48 m away."""
VIEW, VIEWS = 0.2, 3
"""A place found far from where the robot was lost is recalled only once the history holds VIEW
metres or more of travel in each of VIEWS of the map's four directions (east, north, west, south,
each within 45 degrees, the odometry's turned as the place turns it): in the maze a robot
carried 2.5 m and driven only east and west since fitted a wrong place over all 2 m of its scans."""
RECALL_BELOW = 0.02
"""The scans taken back fit where their fast score average stays above this share of the slow
one: twice LOST_BELOW. In the 66 kidnappings of docs/odometry.md (the maze and worlds/rooms.xml)
39 of 42 recalls on the robot read 0.042-0.32 (three under, in one run, said found at its fourth);
14 of 16 on a place 0.18-2.2 m off failed, two passed (0.053 and 0.098: maze look-alikes)."""
RECOVERY = 5000
"""Particles while lost: the scan picks where a kidnapped robot may be among the whole map's free
floor, which takes ten times the particles that follow a robot already found."""
NEAR = np.array((0.05, 0.05, 0.35))
"""Standard deviations (x, y m; heading rad) of the half of the set that searches around the last
estimate when the robot is lost: a robot nudged, turned or carried a cell away by hand."""
INJECT = 0.02
"""The share of the particles drawn anew in each update while lost: the others keep adding up the
evidence of the scans since."""
CANDIDATES = 10
"""Free poses drawn per particle drawn anew, of which the scan picks (sensor resetting)."""
WIDE = 50
"""Free poses drawn per particle of the sets that search the whole map for a place fitting all the
scans since the loss (`MonteCarloLocaliser._drawn_back`): the robot's pose is among the few a set
taken back through metres of scans keeps only if one was drawn within a centimetre or two and a
few degrees of it, which CANDIDATES times as many left to chance in the maze (a set of 5,000 drawn
among 50,000 missed the robot twice in a row, so a place 2.5 m off was found)."""
SWITCH = 0.02
"""Per scan, the chance that a particle changes which sensor it takes its turn from (the fused
odometry's, the mouse's in effect, or the encoders' alone): a robot sliding along a wall moves its
mouse sideways, which the fused odometry may read as turning (0.4 rad/s in the maze's bottom
corridor, seeds 4 and 35 of the main job, under its slide detector's band) while the wheels turn
alike; the particles that follow the encoders then fit the scans and the resampling keeps them.
Where the mouse is right they fall behind by the encoders' quantisation and die out, and this
share comes back each scan (a particle keeps its sensor for some 50 scans, 2.5 s)."""
SCAN_SHARE = 0.5
"""The share of a scan's noise under the likelihood's model (`MonteCarloLocaliser._carry`) the
estimate takes: the sensors' own noise is 0.61 of the model's variance in the realistic preset
(5 mm of sqrt(5² + 4²) = 6.4 mm, `sim.world.localising.MODEL_STD`), an upper bound here, for the
negative parts of each scan's difference of two sampled spreads are cut off. Chosen on the main
job's seeds 0-59 among 0.3, 0.5, 0.61, 0.8 and 1, and checked on seeds 100-119 (docs/odometry.md)."""
RIVALS = 0.2
"""The most weight other places may hold in `MonteCarloLocaliser._rivals` for a place to be found.
In docs/odometry.md's kidnappings it read 0 or 1, the set taken back ending on one place: 1 on the
two wrong places 1.6 and 2.4 m off that had passed the recall, 0 on 20 of 24 places on the robot
(1 on four: another place fitted too, or the set taken back missed the robot's), so any cut
between works. Also for a robot nudged: without it a place 0.97 m off, taken back within NEARBY
of where the robot was lost, passed the 1 m recall (maze, (0.84, 0.84) with seed 9)."""
GLOBAL_EVERY = 0.5
"""Metres rolled between two global searches (`MonteCarloLocaliser._global`) while the robot is
lost and the history holds RECALL metres of scans or more."""
STRIDE, STRIDE_TURN = 0.012, 0.1
"""Metres rolled or radians turned between two of the history's scans that the searches over the
whole map (`MonteCarloLocaliser._drawn_back`) weigh: every third scan or so of a robot driving
at the maze's pace, a third of the stall in `ctsim play`."""
AGREE = 2
"""Global searches in a row that must end on the place before it is recalled (and the rivals'
check draws a set of its own after them): each is a draw of its own, and one may miss the robot's
pose, so that a look-alike place holds the weight."""
PLACES = 32
"""The poses drawn that `MonteCarloLocaliser._global` tries as the centre of a place: those whose
descendants hold the most weight."""
RECOVERY_TIME = 120.0
"""The stated time (s) within which a robot carried far across the maze is found again, `lost`
cleared on it, in most kidnappings (the module says how many; docs/odometry.md)."""
TEMPER = 1.0
"""While lost, a scan weighs the particles by its likelihood to this power (annealing): among
thousands of hypotheses, one near the robot but a few millimetres or degrees off must survive
the scans until the motion noise brings it closer."""


class MonteCarloLocaliser:
    """A particle filter of the pose against the map (the module says how). Before `reset`, the
    run loop hands it the map and a generator (`use_map`). After each update: `pose` and
    `covariance` (the particles' weighted mean and spread), `lost`, `score` (of the last scan),
    `particles` (n, 3) and their `weights`, and `updated` (the time of the last scan, s)."""

    name = "localiser"

    def __init__(self, particles: int = PARTICLES, every: int = EVERY, recovery: int = RECOVERY):
        if not 2 <= particles <= recovery or every < 1:
            raise ValueError(f"a localiser needs 2 or more particles, at most `recovery` ({recovery}), and 1 or more steps between scans, got {particles} and {every}")
        self.count, self.every, self.recovery = particles, every, recovery
        self.map: MapModel | None = None

    def use_map(self, scan: MapModel, rng: np.random.Generator) -> None:
        """The map of the world the robot carries and the generator of its random draws."""
        self.map, self.rng = scan, rng

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        if self.map is None:
            raise ValueError("a localiser needs the world's map: run it through the run loop (ctsim run --estimator localiser)")
        self.odometry = FusedOdometry() if mouse_applies(robot) else EncoderOdometry()
        self.odometry.reset(robot, pose)
        p = self.odometry.params
        self._tick_turn = (p["tick_left"] / p["track"], p["tick_right"] / p["track"]) if mouse_applies(robot) else None
        """Radians a tick of the left and the right wheel turns the robot by (the believed geometry);
        None where the odometry is the encoders' already."""
        self.mouse_lever = abs(robot.mouse.mount[0]) if mouse_applies(robot) else 0.0
        self.track = p["track"]
        self.belief = Belief.of(robot)
        start = np.asarray(pose, dtype=np.float64)
        self.particles = np.tile(start, (self.count, 1))
        self.weights = np.full(self.count, 1.0 / self.count)
        self.by_encoders = np.zeros(self.count, dtype=np.bool_)
        """Per particle: whether it takes its turn from the encoders (SWITCH)."""
        self.likelihood = np.ones(self.count)
        self._mean, self._cov = start.copy(), np.zeros((3, 3))
        self._prior_mean, self._prior = start.copy(), np.zeros((3, 3))  # the set's mean and spread before a scan's weighing
        self._carried = np.zeros((3, 3))
        """The estimate's covariance at the last scan (`_carry`)."""
        self._anchor = start.copy()  # the odometry's pose at the last update
        self._encoder_turn = 0.0  # what the encoders turned since the last update
        self.pose = start.copy()
        self._steps, self._rolled, self._turned = 0, 0.0, 0.0
        self.score = self.fast = self.slow = math.nan  # (the first scan sets the averages)
        self.searching = False
        """Whether the set searches for the robot (grown, drawing anew, roughening wider)."""
        self._held = 0.0  # metres rolled since the search ended
        self.confirmed = True  # (the start pose is known)
        """Whether the place the set follows, since the robot was last lost, has been checked
        against the scans since (`_recall`)."""
        self._history: deque[tuple[np.ndarray, np.ndarray, float, float, float]] = deque()
        """While not confirmed, per scan since the robot was lost, of the last RECALL_MOST metres:
        the odometry's pose, the raw IR values, the metres rolled and radians turned since the scan
        before, and the radians the encoders alone turned (nan without a mouse)."""
        self._recorded = 0.0  # metres the history spans
        self._travelled = 0.0
        """Metres rolled since the robot was lost: what schedules the global searches (`_recorded`
        stops at RECALL_MOST, and a schedule on it stopped them after the second)."""
        self._next_global = 0.0  # metres travelled at which the next global search runs
        self._agreed = 0
        """How many global searches (`_global`) in a row ended on one place with the particles drawn
        anew alone: the set is then there, and only after AGREE of them is a place recalled whose
        history holds RECALL metres."""
        self._lost_at = (start[:2].copy(), start.copy())
        """Where the estimate (x, y) and the odometry's pose were when the robot was lost."""
        self.updated = 0.0

    @property
    def lost(self) -> bool:
        """Whether the localiser does not know where the robot is: searching, or following a place
        not yet confirmed (held for CONFIRM metres and fitting the scans since the robot was lost)."""
        return self.searching or not self.confirmed

    def update(self, readings: Readings) -> None:
        before = self.odometry.pose
        self.odometry.update(readings)
        step = relative_pose(before, self.odometry.pose)
        self._rolled += math.hypot(step[0], step[1])
        self._turned += abs(step[2])
        self._steps += 1
        if self._tick_turn is not None:
            left, right = readings.encoder_ticks.tolist()
            self._encoder_turn += right * self._tick_turn[1] - left * self._tick_turn[0]
        if self._steps >= self.every and (self._rolled > 0.0 or self._turned > 0.0):
            self._scan(readings)
        dx, dy, dtheta = relative_pose(self._anchor, self.odometry.pose)
        x, y, theta = self._mean.tolist()
        c, s = math.cos(theta), math.sin(theta)
        self.pose = np.array((x + c * dx - s * dy, y + s * dx + c * dy, theta + dtheta))

    def _scan(self, readings: Readings) -> None:
        """Move the particles by the odometry since the last scan, weigh them by this one, take
        their weighted mean and spread, judge whether the robot is lost, and resample (growing the
        set while lost, drawing some anew)."""
        n = len(self.particles)
        increment = relative_pose(self._anchor, self.odometry.pose)
        turns = np.full(n, np.nan)
        if self._tick_turn is not None and not self.searching:  # (searching, every particle follows the odometry)
            self.by_encoders ^= self.rng.random(n) < SWITCH
            turns[self.by_encoders] = self._encoder_turn
        encoder_turn, self._encoder_turn = self._encoder_turn, 0.0
        move_particles(self.particles, *increment, self._motion_std(True, self._rolled, self._turned), self.rng.standard_normal((n, 3)), turns)
        mean_and_covariance(self.particles, self.weights, float(self._mean[2]), self._prior_mean, self._prior)
        self._anchor = self.odometry.pose.copy()
        rolled, turned = self._rolled, self._turned
        self._steps, self._rolled, self._turned = 0, 0.0, 0.0
        raw = readings.ir_raw
        self.likelihood = np.empty(n)
        self.map.likelihood(self.particles, raw, self.likelihood)
        weighted = self.weights * self.likelihood
        total = float(weighted.sum())
        self.score = total / self.map.best(raw)
        if self.searching:
            weighted = self.weights * self.likelihood**TEMPER
            total = float(weighted.sum())
        if math.isnan(self.fast):
            self.fast = self.slow = self.score
        self.fast += FAST * (self.score - self.fast)
        self.weights = weighted / total if total > 0.0 else np.full(n, 1.0 / n)
        mean_and_covariance(self.particles, self.weights, float(self._mean[2]), self._mean, self._cov)
        was_searching = self.searching
        if not was_searching:  # (searching, the slow average keeps what finding the robot again must reach)
            self.slow += SLOW * (self.score - self.slow)
            self.searching = self.fast < LOST_BELOW * self.slow
        else:
            self.searching = self.fast < FOUND_AT * self.slow or math.sqrt(self._cov[0, 0] + self._cov[1, 1]) > FOUND_SPREAD
        if self.searching and self.confirmed:
            self.confirmed, self._recorded, self._travelled, self._lost_at, self._next_global, self._agreed = False, 0.0, 0.0, (self._mean[:2].copy(), self._anchor), 0.0, 0
            self._history.clear()
        if not self.confirmed:
            self._record(raw, rolled, turned, encoder_turn)
        refuted = False  # (a place the scans since the loss rule out: search the whole map again)
        if was_searching and not self.searching and not self.confirmed and len(self._history) > 1:
            refuted = self.searching = self._recall() < RECALL_BELOW
        self._held = 0.0 if self.searching else self._held + rolled
        if not self.searching and not self.confirmed and self._held >= CONFIRM and (self._agreed >= AGREE or self._recorded < RECALL) and self._enough():
            self.confirmed = self._recall() >= RECALL_BELOW and self._rivals(raw) < RIVALS
            refuted = self.searching = not self.confirmed
            self._held = 0.0 if self.searching else self._held
        placed = None
        if refuted:  # (the global search waits for the next scan: one stall at a time in `ctsim play`)
            self._next_global = min(self._next_global, self._travelled)
        elif not self.confirmed and self._recorded >= RECALL and self._travelled >= self._next_global:
            self._next_global = self._travelled + GLOBAL_EVERY
            placed, agreed = self._global(raw)
            self._agreed = self._agreed + 1 if agreed else 0
            if placed is not None and math.dist(placed[0].mean(axis=0)[:2], self._mean[:2]) < NEARBY:
                placed = None  # (the set is on the place the scans since the loss point to)
            elif placed is not None:
                refuted = self.searching = True
        self._carry(rolled, turned)
        size = self.recovery if self.searching else self.count
        if self.searching:
            self.by_encoders[:] = False
        picked = placed if placed is not None else self._picked(size, raw) if refuted else (np.empty((0, 3)), np.empty(0))
        if len(picked[0]):  # all of the set drawn anew from free floor where the scan fits
            self.particles, self.likelihood = picked
            self.by_encoders = np.zeros(len(self.particles), dtype=np.bool_)
            self.weights = np.full(len(self.particles), 1.0 / len(self.particles))
        elif self.searching and not was_searching:  # the set as it was, and the rest around the estimate
            near = self._mean + self.rng.normal(0.0, 1.0, (size - n, 3)) * NEAR
            self._resample(n, [(near, np.zeros(len(near)))])
        elif self.searching or size != n or 1.0 / float(np.dot(self.weights, self.weights)) < 0.5 * n:
            fresh = self.rng.binomial(size, INJECT) if self.searching else 0
            self._resample(size - fresh, [self._picked(fresh, raw)] if fresh else [])
        self.updated = readings.time

    def _record(self, raw: np.ndarray, rolled: float, turned: float, encoder_turn: float) -> None:
        """Add this scan to the history, and drop the scans RECALL_MOST metres before it."""
        self._history.append((self._anchor, raw.copy(), rolled, turned, encoder_turn if self._tick_turn is not None else math.nan))
        self._recorded += rolled
        self._travelled += rolled
        while self._recorded - self._history[0][2] >= RECALL_MOST:
            self._recorded -= self._history.popleft()[2]

    def _enough(self) -> bool:
        """Whether the history holds the scans a place found again must fit before it is recalled:
        RECALL_NEAR metres where the robot, taken back from there along the odometry, was within
        NEARBY of the estimate when it was lost (a robot nudged: the prior favours it); anywhere
        else RECALL metres, with VIEW metres or more of them in each of VIEWS of the map's four
        directions (as the place turns the odometry's)."""
        if self._nudged():
            return self._recorded >= RECALL_NEAR
        if self._recorded < RECALL:
            return False
        poses = np.array([pose for pose, *_ in self._history])
        steps = np.diff(poses[:, :2], axis=0)
        direction = np.arctan2(steps[:, 1], steps[:, 0]) + self._mean[2] - self._anchor[2]
        quarter = np.round(direction / (0.5 * math.pi)).astype(np.int64) % 4
        return int(np.count_nonzero(np.bincount(quarter, np.hypot(steps[:, 0], steps[:, 1]), 4) >= VIEW)) >= VIEWS

    def _nudged(self) -> bool:
        """Whether the place, taken back along the odometry to when the robot was lost, lies within
        NEARBY of the estimate then: a robot nudged, for which RECALL_NEAR metres of scans do."""
        estimate, odometry = self._lost_at
        return math.dist(self._taken_back(odometry), estimate) < NEARBY

    def _taken_back(self, odometry: np.ndarray) -> tuple[float, float]:
        """Where the set's place was when the odometry read `odometry`: the estimate taken back
        along the odometry's move since then."""
        dx, dy, _ = relative_pose(self._anchor, odometry)
        c, s = math.cos(self._mean[2]), math.sin(self._mean[2])
        return self._mean[0] + c * dx - s * dy, self._mean[1] + s * dx + c * dy

    def _recall(self) -> float:
        """How well the history's scans fit the place the set follows: the least the fast score
        average of the set taken back through them (`_back`, every scan) reached over the slow one,
        stopping below RECALL_BELOW (a forward run loses the robot below LOST_BELOW)."""
        particles, weights, by_encoders = self.particles.copy(), self.weights.copy(), self.by_encoders.copy()
        if len(particles) > self.count:  # (a search just ended: as many as the set will keep)
            drawn = low_variance_resample(weights, self.count, self.rng.random() / self.count)
            particles, weights, by_encoders = particles[drawn], np.full(self.count, 1.0 / self.count), by_encoders[drawn]
        back = self._back(particles, weights, by_encoders, False, RECALL_BELOW)
        return 0.0 if back is None else back[3]

    def _drawn_back(self, raw: np.ndarray, kept: int = 0, stride: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """A set drawn anew from the whole map's free floor where the scan `raw` fits (`_picked`,
        `recovery` particles of WIDE times as many; `kept` of the set's own beside them, drawn by
        their weight), taken back through the history's scans (`_back`: STRIDE apart, or every one
        without `stride`): the poses drawn, their likelihood, the set at the history's first scan,
        and per particle its weight and the index of the pose drawn it descends from (None where
        no pose fits the scan or the scans rule out every one)."""
        drawn, likelihood_now = self._picked(self.recovery, raw, WIDE)
        if len(drawn) == 0:
            return None
        if kept:
            own = low_variance_resample(self.weights, kept, self.rng.random() / kept)
            drawn, likelihood_now = np.concatenate([drawn, self.particles[own]]), np.concatenate([likelihood_now, self.likelihood[own]])
        n = len(drawn)
        back = self._back(drawn.copy(), np.full(n, 1.0 / n), np.zeros(n, dtype=np.bool_), stride, 0.0)
        return None if back is None else (drawn, likelihood_now, *back[:3])

    def _back(self, particles: np.ndarray, weights: np.ndarray, by_encoders: np.ndarray, stride: bool, stop: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float] | None:
        """A weighted set taken back along the odometry through the history's scans, from the last
        to the first (every scan, or with `stride` STRIDE apart), with the motion noise (and the
        encoders' turn where `by_encoders`, SWITCH), weighed and resampled by each earlier scan as
        it was forward: the set at the first scan, its weights, per particle the index of the one
        it descends from, and the least its fast score average reached over the slow one,
        stopping once that is below `stop` (None where a scan rules out every particle)."""
        n, fast, worst = len(particles), self.fast, math.inf
        ancestors, likelihood = np.arange(n), np.empty(n)
        for pose, earlier, raw, rolled, turned, encoder_turn in self._strides(STRIDE if stride else 0.0, STRIDE_TURN if stride else 0.0):
            turns = np.full(n, np.nan)
            if not math.isnan(encoder_turn):
                by_encoders ^= self.rng.random(n) < SWITCH
                turns[by_encoders] = -encoder_turn
            move_particles(particles, *relative_pose(pose, earlier), self._motion_std(True, rolled, turned), self.rng.standard_normal((n, 3)), turns)
            self.map.likelihood(particles, raw, likelihood)
            weighted = weights * likelihood
            total = float(weighted.sum())
            if total <= 0.0:
                return None
            fast += FAST * (total / self.map.best(raw) - fast)
            worst = min(worst, fast / self.slow)
            if worst < stop:
                break
            weights = weighted / total
            if 1.0 / float(np.dot(weights, weights)) < 0.5 * n:
                chosen = low_variance_resample(weights, n, self.rng.random() / n)
                particles, ancestors, by_encoders = particles[chosen], ancestors[chosen], by_encoders[chosen]
                weights = np.full(n, 1.0 / n)
        return particles, weights, ancestors, worst

    def _strides(self, metres: float, radians: float) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, float, float, float]]:
        """The history's steps back from its last scan to its first, over scans `metres` or
        `radians` apart (0: every scan): (the odometry's pose at one, at the one before, the raw
        values there, the metres rolled, the radians turned and the encoders' turn between)."""
        steps = []
        later, rolled, turned, encoder_turn = self._history[-1][0], 0.0, 0.0, 0.0
        for k in range(len(self._history) - 1, 0, -1):
            rolled, turned, encoder_turn = rolled + self._history[k][2], turned + self._history[k][3], encoder_turn + self._history[k][4]
            if rolled >= metres or turned >= radians or k == 1:
                earlier, raw = self._history[k - 1][:2]
                steps.append((later, earlier, raw, rolled, turned, encoder_turn))
                later, rolled, turned, encoder_turn = earlier, 0.0, 0.0, 0.0
        return steps

    def _rivals(self, raw: np.ndarray) -> float:
        """The share of the weight on other places (NEARBY or more from the estimate) of a set drawn
        anew over the whole map and taken back through the history (`_drawn_back`): a place is
        found only if no other place fits the scans since the loss too."""
        back = self._drawn_back(raw, stride=False)
        if back is None:
            return 0.0
        _, _, particles, weights, _ = back
        taken = np.array(self._taken_back(self._history[0][0]))
        return float(weights[np.hypot(*(particles[:, :2] - taken).T) >= NEARBY].sum())

    def _global(self, raw: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray] | None, bool]:
        """Where the scans since the loss put the robot now, searched over the whole map. A set
        drawn anew (`_drawn_back`), with `count` of the set's own beside it (its place competes
        too), taken back through the history: the place is the pose drawn with the most of the
        weight of the particles that descend from it or from one NEARBY (the set taken back ends
        there). If that is 1 - RIVALS of it or more: `recovery` poses drawn there by that weight,
        and their likelihood of this scan, else None; and whether the particles drawn anew alone
        hold 1 - RIVALS of theirs there (a rivals' check of their own: a place the set's own
        particles carry alone is not recalled). The search weighs the last scans only, and among
        thousands of look-alike places the few particles on the robot's lose the weight; all the
        scans since the loss tell them apart."""
        back = self._drawn_back(raw, self.count)
        if back is None:
            return None, False
        drawn, likelihood, _, weights, ancestors = back
        held = np.bincount(ancestors, weights, len(drawn))
        top = np.argsort(held)[-PLACES:]
        near = np.hypot(drawn[top, None, 0] - drawn[None, :, 0], drawn[top, None, 1] - drawn[None, :, 1]) < NEARBY
        shares = near @ held
        best = int(np.argmax(shares))
        if shares[best] < 1.0 - RIVALS:
            return None, False
        fresh = len(drawn) - self.count
        agreed = float(held[:fresh] @ near[best, :fresh]) >= (1.0 - RIVALS) * float(held[:fresh].sum())
        chosen = self.rng.choice(len(drawn), size=self.recovery, p=held * near[best] / shares[best])
        return (drawn[chosen], likelihood[chosen]), agreed

    def _carry(self, rolled: float, turned: float) -> None:
        """The estimate's covariance at this scan, carried from the last one: the error of the
        set's mean as a linear filter's whose gain is what the scan did to the set (Joseph form).
        The scan took the set's spread from prior P0 to P1, a gain of A = P1 P0^-1 (I - KH); the
        estimate's error before it, the last one's plus the belief's own motion noise Q (not
        INFLATE times it: the odometry's real error), is carried through A, and the scan's noise
        K R K^T (P1 - A P0 A^T under the likelihood's model) added at the sensors' share of it
        (SCAN_SHARE).
        Where a scan says nothing (A = 1) the covariance grows by the belief alone; where it pins
        the pose down, it is the set's spread, not a fourth of it (docs/odometry.md). While
        searching: the set's spread over INFLATE squared, the robot may be anywhere in it."""
        if self.searching or np.linalg.eigvalsh(self._prior)[0] <= 1e-12 * np.trace(self._prior):  # (or a set of a few particles, flat)
            self._carried = self._cov / INFLATE**2
            return
        gain = np.linalg.solve(self._prior, self._cov).T
        noise = self._cov - gain @ self._prior @ gain.T
        values, vectors = np.linalg.eigh(0.5 * (noise + noise.T))
        noise = (vectors * np.maximum(values, 0.0)) @ vectors.T  # (a sampled set's difference may read negative)
        self._carried = gain @ (self._carried + self._belief_noise(rolled, turned, float(self._mean[2]))) @ gain.T + SCAN_SHARE * noise

    def _belief_noise(self, rolled: float, turned: float, heading: float) -> np.ndarray:
        """(3, 3) the believed motion noise (world frame, at `heading`) of `rolled` m and `turned` rad."""
        forward, lateral, turn = (self._motion_std(False, rolled, turned) / INFLATE).tolist()
        c, s = math.cos(heading), math.sin(heading)
        cov = np.zeros((3, 3))
        cov[0, 0] = c * c * forward**2 + s * s * lateral**2
        cov[0, 1] = cov[1, 0] = c * s * (forward**2 - lateral**2)
        cov[1, 1] = s * s * forward**2 + c * c * lateral**2
        cov[2, 2] = turn**2
        return cov

    @property
    def covariance(self) -> np.ndarray:
        """(3, 3) the estimate's covariance at the last scan (`_carry`) plus the believed motion
        noise of the odometry since (so that it never reads zero, at the start either)."""
        return self._carried + self._belief_noise(self._rolled, self._turned, float(self.pose[2]))

    def _resample(self, count: int, added: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """`count` of the particles drawn by their weights, then the `added` ones (poses and, for
        the recording, the last scan's likelihood there), all of equal weight."""
        drawn = low_variance_resample(self.weights, count, self.rng.random() / count)
        self.particles = np.concatenate([self.particles[drawn], *(poses for poses, _ in added)])
        self.likelihood = np.concatenate([self.likelihood[drawn], *(likelihood for _, likelihood in added)])
        self.by_encoders = np.concatenate([self.by_encoders[drawn], np.zeros(len(self.particles) - count, dtype=np.bool_)])
        self.weights = np.full(len(self.particles), 1.0 / len(self.particles))

    def _picked(self, count: int, raw: np.ndarray, per: int = CANDIDATES) -> tuple[np.ndarray, np.ndarray]:
        """(count, 3) free poses drawn in proportion to the likelihood of the scan `raw` among
        `per` times as many drawn uniformly (sensor resetting), headings within pi of the
        estimate's, and that likelihood (none where no candidate fits the scan)."""
        candidates = self.map.free(self.rng, per * count)
        likelihood = np.empty(len(candidates))
        self.map.likelihood(candidates, raw, likelihood)
        total = likelihood.sum()
        if total <= 0.0:
            return np.empty((0, 3)), np.empty(0)
        chosen = self.rng.choice(len(candidates), size=count, p=likelihood / total)
        poses = candidates[chosen]
        poses[:, 2] = self._mean[2] + (poses[:, 2] - self._mean[2] + math.pi) % math.tau - math.pi
        return poses, likelihood[chosen]

    def _motion_std(self, roughen: bool, rolled: float, turned: float) -> np.ndarray:
        """(forward m, lateral m, turn rad) standard deviations of an increment of `rolled` m and
        `turned` rad: the believed random noise over the distance rolled and the calibration still
        unknown over the distance and the turn, INFLATE times wider, and (if `roughen`) at least
        ROUGHEN (SEARCH times that while searching)."""
        b = self.belief
        forward = 0.5 * b.slip_var * rolled + (b.wheel_scale_std * rolled) ** 2
        if self.mouse_lever:
            turn = b.mouse_var / self.mouse_lever**2 * rolled + (max(b.mouse_scale_std, TURN_FLOOR) * turned) ** 2
        else:
            turn = 2.0 * b.slip_var / self.track**2 * rolled + (max(b.track_std, TURN_FLOOR) * turned) ** 2
        lateral = turn * rolled * rolled / 4.0 + b.mouse_var * rolled
        return np.hypot(INFLATE * np.sqrt(np.array((forward, lateral, turn))), ROUGHEN * (SEARCH if self.searching else 1.0) * roughen)
