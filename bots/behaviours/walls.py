"""Behaviours on the IR distance sensors: solve a maze by following a wall, wander about."""

from __future__ import annotations

import math
from collections.abc import Generator
from functools import cache

import numpy as np

from bots.behaviours.base import (
    BORDER_DANGEROUS,
    GROUND_GOAL,
    RUNNING,
    SPEED_NORMAL,
    Behaviour,
    Look,
    Plan,
)
from bots.behaviours.motion import DriveDistance, DriveTo, Turn
from bots.commands import Command, Twist
from bots.controller import Status, register
from bots.ir_curve import ir_curve_for
from bots.odometry.base import mouse_applies
from bots.readings import Readings
from sim.kinematics import (
    Pose,
    apply_increment,
    relative_increment,
    relative_pose,
    wrap_angle,
)

GOAL_TOLERANCE = 0x10
"""How far (raw units) the line sensors' mean may read from GROUND_GOAL on the goal floor."""
GOAL_SPREAD = 40.0
"""Largest standard deviation (raw units) of those readings: twice the harsh preset's line noise."""
GOAL_READINGS = 10
"""Steps in a row whose readings of one line sensor average to the goal colour before it counts
as the goal: one noisy reading near the goal colour is not the goal floor (under harsh noise, 20
raw units, a floor 40 units off the goal colour reads within the tolerance one time in nine; the
mean of 20 readings strays by 4.5)."""
_GOAL_SUM, _GOAL_SUM_TOLERANCE, _GOAL_SPREAD_SQUARED = GOAL_READINGS * GROUND_GOAL, GOAL_READINGS * GOAL_TOLERANCE, (GOAL_READINGS * GOAL_SPREAD) ** 2
"""The goal test's bounds on GOAL_READINGS readings' sum and its spread (`SolveMaze._on_goal`)."""
LOOK_STEPS = 8
"""Steps a look averages the IR distances over at least (all it needs when the readings are steady)."""
LOOK_MAX_STEPS = 32
"""Steps a look averages noisy IR distances over at most: realistic noise (5 mm) reaches LOOK_ERROR
in about 31, which squares up within 1 degree from the two sensors 72 mm apart; harsh noise (15 mm)
becomes 2.7 mm, a skew good to 3 degrees. More steps spend the main job's 300 s standing, fewer
square up too loosely: goals reached (harsh seeds 0-99, realistic 0-99) and their mean times,
with square-ups on closed walls: 90 and 100 in 272-277 s and 253 s at 64 steps, 90 and 100 in
261 s and 251 s at 32, 90 and 99 in 249-253 s and 248 s at 24 (harsh 0-19: 15 of 20 at 16)."""
LOOK_ERROR = 0.0009
"""A look goes on while a sensor's mean has a larger standard error than this (m)."""
SQUARE_BAND = (0.27, 0.7)
"""IR distances (m) trusted for squaring up on a wall: above the 0.1-0.26 m that a wall closer than
0.1 m folds back to, below the curve's flat end."""
MOUSE_LEARN_M = 0.1
"""Straight distance (m) after which the mouse's scale is taken from its counts against the encoders'."""
DRIFT_LEARN_M = 1.0
"""Straight distance (m) after which the encoders' drift per metre is taken from the mouse: by then
the mouse's random error (about 1.3 degrees per root metre) is below the 1.8 degrees a metre of a
0.3 % wheel diameter mismatch, and it shrinks as the root of the distance from there."""
MAX_VISITS = 4
"""Visits to one room after which its ways are looked at again (`_visit`)."""
HEADING_DRIFT = math.radians(2.0) ** 2
"""Variance (rad^2) the believed heading gains per metre driven and per radian turned: the
mouse-corrected encoders drift about a degree a root metre; twice that, because a belief that
trusts itself too much squares up too little (realistic noise, seed 7: a heading off by 1.55
degrees rms at the looks with one, 1.25 with two)."""
MAX_SKEW = math.radians(15)
"""Largest angle to a wall face (rad) a look squares up on; more means the two rays hit two faces."""
OPEN_FRACTION = 0.9
"""A way is open when both IR sensors see nothing nearer than this many cells: a room's neighbour
wall reads at most 0.2 m (0.065 m away, folded back), the wall beyond an open neighbour at least
0.3 m (cell 0.24 m)."""

RECHECK_M = 0.03
"""How far (m) a robot backs off to look again at a way it cannot tell open or closed: 6 cm more
in the sum of both sensors where it is open, less down the fold-back where a wall touches them."""
STALL_M = 0.02
"""Wheels' rolling (m) over which a drive compares the mouse's distance with theirs: 13 steps at
0.15 m/s, seven encoder ticks, 300 mouse counts."""
STALL_SHARE = 0.5
"""Share of the wheels' rolling below which the mouse's distance means the robot is stuck."""
FACE_TOLERANCE = 0.03
"""Largest distance (m) between where both IR sensors see one face and the believed tile edge for
a look to count it as the face beyond an open way: the believed pose is good to about 2 cm."""
FOLD_REACH = 0.42
"""IR distance (m) below which a reading may be a wall touching the sensor: the GP2D12 curves fold
back below 0.1 m, and at 0-1 cm read 0.41 m (left) and 0.33 m (right)."""

STEPS = ((1, 0), (0, 1), (-1, 0), (0, -1))
"""Grid step of each quarter turn, counter-clockwise from the start heading."""


def clear_ahead(distance: np.ndarray, beyond_m: float) -> bool:
    """Whether every IR distance is beyond `beyond_m` (nan: nothing within range).
    A wall closer than the sensors' 0.1 m reads as a false 0.1-0.26 m on the curve's fold-back, so
    anything below about 0.27 m may be a wall right in front."""
    return all(d > beyond_m or math.isnan(d) for d in distance.tolist())


def _in_view(distance: np.ndarray) -> tuple[float, float]:
    """The first two IR distances as floats, nan (nothing within range) as infinity: what
    `np.nan_to_num(distance[:2], nan=math.inf)` gives a look's means, without its 30-50 µs a call
    (a plan asks after every look)."""
    left, right = (math.inf if d != d else d for d in distance[:2].tolist())
    return left, right


def _receded(before: np.ndarray, after: np.ndarray) -> bool:
    """Whether IR distances seen from RECHECK_M further back than `before` read farther (nan:
    nothing within range): what lies ahead does; a wall touching the sensors reads nearer, down
    the GP2D12's fold-back (0.33-0.41 m at 1 cm, 0.1 m at 10 cm)."""
    return float(np.sum(np.nan_to_num(after[:2], nan=1.0) - np.nan_to_num(before[:2], nan=1.0))) > 0


NEAR_STEP = 0.001
"""Spacing (m) of the distances at which `_raw_likelihood` tabulates a closed wall's raw values."""
NEAR_REACH = 0.3
"""Farthest distance (m) it tabulates: past a room's own wall seen from anywhere in the room."""
NEAR_WINDOW = 0.08
"""How far (m) from where the belief puts a room's own closed wall a fold-back square-up looks for
it (`SolveMaze._square_up_near`): the wall may be 0-0.15 m from the sensors of a robot anywhere in
the room, and the same raw values read 0.06-0.07 m on the fold-back and 0.10-0.16 m beyond it."""
NEAR_PRIOR = 0.03
"""Spread (m) of the believed position a fold-back square-up weighs the readings against: what
tells a noise-free 0.065 m from the 0.125 m that reads the same raw value."""
NEAR_ERROR = 0.01
"""Largest standard deviation (m) of a sensor's distance to a closed wall for a square-up on it:
more means its readings fit both sides of the fold-back."""
NEAR_ROWS = 16
"""Distances `_raw_likelihood` weighs at once: its table for a sensor with a metre of noise (a robot
file may give it) then takes some 30 MB at a time, not 700."""
NEAR_MIN_STD = 0.001
"""Least IR noise (m) the fold-back model assumes (a noise-free sensor reads one value, which
then fits the distances within a millimetre of it)."""
NEAR_DISTANCES = np.arange(0.0, NEAR_REACH + NEAR_STEP / 2, NEAR_STEP)
"""The distances (m) of `_raw_likelihood`'s columns: 0, NEAR_STEP, ... NEAR_REACH."""


@cache
def _raw_likelihood(curve: str | None, side: str, noise_std: float) -> tuple[int, np.ndarray]:
    """(lowest raw value, log-probability of each raw value from there at each distance of
    NEAR_DISTANCES: a row per raw value) of an IR sensor facing a wall: its distance plus normal noise of
    `noise_std` (not below 0, as the sensors read) through its characteristic, rounded. On the
    GP2D12's fold-back a raw value is two distances (one below 0.09 m, one above): the scatter of
    noisy readings tells them apart, as their mean cannot. Tabulated once per curve and noise."""
    ir = ir_curve_for(curve, side)
    std = max(noise_std, NEAR_MIN_STD)
    step = 0.00005  # (the fold-back's steepest 12 raw units a millimetre: every raw value has its distances)
    true = np.arange(0.0, NEAR_REACH + 6 * std, step)
    raw = ir.lookup(true)
    low, high = ir.raw_range()
    order = np.argsort(raw, kind="stable")
    values, starts = np.unique(raw[order], return_index=True)
    grid = NEAR_DISTANCES
    chances = np.zeros((len(grid), high - low + 1))
    ordered = true[order]
    for first in range(0, len(grid), NEAR_ROWS):  # (a few rows at a time: a robot file may give the sensor up to 1 m of noise)
        rows = slice(first, first + NEAR_ROWS)
        weights = np.exp(-0.5 * ((ordered[None, :] - grid[rows, None]) / std) ** 2) * (step / (std * math.sqrt(2 * math.pi)))
        chances[rows, values - low] = np.add.reduceat(weights, starts, axis=1)
    below = 0.5 * np.array([math.erfc(d / (std * math.sqrt(2))) for d in grid.tolist()])  # noise below 0 m reads as 0
    chances[:, raw[0] - low] += below
    # (a floor: one stray reading does not rule a distance out; a row per raw value, so that a look's
    # values read their rows' band of distances, not a scattered column of every distance's row)
    return low, np.ascontiguousarray(np.log(chances + 1e-6).T)


class DriveToRoom(DriveTo):
    """DriveTo that stops dead and fails where a border sensor sees an abyss (a hole or the edge of
    the map: the border sensors sit 38 mm ahead of the wheels, which fall), or once `stalled` (set
    by a plan whose mouse sees the robot stand while its wheels turn: a wall ahead)."""

    abyss = False
    stalled = False

    def act(self, t: float, readings: Readings) -> Command:
        for value in readings.border.tolist():  # (a loop: max(..., default=0) was a quarter of this step)
            if value > BORDER_DANGEROUS:
                self.abyss = True
        if self.abyss or self.stalled:
            return self.finish(Status.FAILURE)
        return DriveTo.act(self, t, readings)  # (not super(): a super object a step)


@register("solve_maze")
class SolveMaze(Plan):
    """Left- or right-hand wall follower for c't-Sim mazes: rooms (c't-Sim's 0.24 m tiles) on a grid
    aligned with the start pose, walls whole tiles. First it drives ahead until a wall is beside or
    in front of it; then in each room it takes the first open way of: the preferred side, ahead, the
    other side, back (the c't-Bot's IR sensors only look forward, so it turns to face each way it has
    not seen yet), and drives to that room's centre by its own odometry. An abyss (hole, map edge)
    counts as a wall: the border sensors stop the drive at its edge, and the robot backs off.

    Every look that sees one wall face at a trustworthy distance squares the robot's belief up on it:
    the two sensors' difference gives the angle to the face, their mean the distance, and faces lie
    on the tile grid, so heading and position along that axis are corrected (what keeps wheel slip
    and a wrong track width from leading it into a wall); a look at a room's own closed wall, which
    reads on the IR curve's fold-back, squares up from the likelihood of its raw values
    (`_square_up_near`). Looks average noisy readings for longer, a
    way whose two sensors disagree within reach of the curve's fold-back counts as closed (it may be
    a wall touching them), and where the encoders' turn drifts the mouse's is taken
    (`_correct_odometry`). Ways seen are remembered, so rooms visited again cost one look only, at
    the way out before driving it (a square-up where something lies ahead in reach). Succeeds
    on the goal floor (a line sensor's mean over GOAL_READINGS steps reads GROUND_GOAL, which no
    single noisy reading fakes), after driving a quarter room onto it."""

    def __init__(self, hand: str = "right", cell_m: float = 0.24, speed_m_s: float = SPEED_NORMAL, max_rooms: int = 1000):
        if hand not in ("left", "right"):
            raise ValueError(f"hand must be 'left' or 'right', got {hand!r}")
        if cell_m <= 0 or speed_m_s <= 0:
            raise ValueError("need a positive cell size and speed")
        self.first = 1 if hand == "left" else -1  # quarter turns, counter-clockwise positive
        self.cell = cell_m
        self.speed = speed_m_s
        self.max_rooms = max_rooms

    def start(self) -> None:
        self.need("ir", 2)
        self.need("line", 1)
        self.entering: Behaviour | None = None
        self.known: dict[tuple[int, int, int], bool] = {}  # (room x, room y, quarter) -> open
        self.looked: tuple[tuple[int, int], int] | None = None  # the way the last look faced
        self.visits: dict[tuple[int, int], int] = {}  # room -> visits since its ways were last seen
        lines = len(self.robot.line)
        self.floor_seen = [[0] * lines for _ in range(GOAL_READINGS)]  # the last steps' line readings, a ring
        self.floor_steps = 0  # steps seen
        self.floor_sums = [0] * lines  # per line sensor: the sum of the readings in the ring
        self.frame = self.pose  # the grid's origin in this behaviour's odometry frame
        left, right = self.robot.ir[0].position, self.robot.ir[1].position
        self.ir_ahead = 0.5 * (left[0] + right[0])  # sensors ahead of the axle (m)
        self.ir_baseline = left[1] - right[1]  # left sensor to right sensor (m)
        mouse = self.robot.mouse
        sees_turns = mouse_applies(self.robot)  # (a mouse on the axle line reads no rotation: not used)
        self.mouse_turn = 0.0254 / mouse.dpi / mouse.mount[0] if sees_turns else None  # rad per lateral count
        self.mouse_metre = 0.0254 / mouse.dpi if sees_turns else None  # m per count at the nominal dpi
        self.tick_turn = self.odometry.metres_per_tick / self.odometry.track  # rad per tick of one wheel
        self.half_track = self.odometry.track / 2
        self.drive: DriveToRoom | None = None  # the last drive to a room
        self.wheels_driven = self.mouse_driven = 0.0  # in the drive's current STALL_M: by the encoders and by the mouse (m)
        self.spin_gap = 0.0  # turning on the spot: the mouse's turn less the encoders' since the robot last stood (rad)
        self.last_pose: Pose | None = None  # the odometry's pose after the last step
        self.raw_likelihood = [_raw_likelihood(s.curve, s.side, s.noise_std) for s in self.robot.ir[:2]]
        self.heading_var = 0.0  # the believed heading's variance (rad^2): the start pose is aligned
        self.disagreement = 0.0  # driving straight: encoders' turn less the mouse's (rad)
        self.mouse_straight = 0.0  # driving straight: the mouse's distance at its nominal dpi (m)
        self.encoders_straight = 0.0  # and the encoders' (m)
        super().start()

    def act(self, t: float, readings: Readings) -> Command:
        self._correct_odometry(readings)
        if self._on_goal(readings.line.tolist()) and self.entering is None:
            self.entering = self.run(DriveToRoom(self.cell / 4, 0.0, self.speed))
        if self.entering is None:
            return Plan.act(self, t, readings)  # (not super(): a super object a step)
        command = self.entering.step(t, readings)
        return command if self.entering.status is RUNNING else self.finish(self.entering.status)

    def _on_goal(self, line: list[int]) -> bool:
        """Take this step's line readings; whether a line sensor's last GOAL_READINGS readings
        average to the goal floor's colour and scatter no more than noise does (each sensor by
        itself, and a steady floor: readings crossing from white to black pass through the goal
        colour on the way). A running sum over a ring of the last readings: an addition a step, the
        squares summed only where the mean reads the goal's colour."""
        seen, steps, sums = self.floor_seen, self.floor_steps, self.floor_sums
        slot = steps % GOAL_READINGS
        gone, seen[slot] = seen[slot], line
        self.floor_steps = steps = steps + 1
        found = False
        for k, value in enumerate(line):
            total = sums[k] = sums[k] + value - gone[k]
            if not found and abs(total - _GOAL_SUM) <= _GOAL_SUM_TOLERANCE:  # (the mean, times GOAL_READINGS)
                squares = sum(readings[k] * readings[k] for readings in seen)  # (whole numbers: exact)
                found = GOAL_READINGS * squares - total * total <= _GOAL_SPREAD_SQUARED  # (the variance, times its square)
        return found and steps >= GOAL_READINGS

    def _correct_odometry(self, readings: Readings) -> None:
        """Correct this step's turn of the shared odometry, which the children steer by.

        The encoders' turn drifts: a spurious tick turns the belief by 1.75 degrees at once, a
        wheel diameter off by 0.3 % by 1.8 degrees a metre, a track width off by 1 % by 1 degree
        a quarter turn; each would lead the robot off its line for good. The mouse, 15 mm behind
        the axle, sees the body's turn as lateral counts (0.24 degrees each) without bias but
        with more random error (its noise over 15 mm of lever arm: about 1.3 degrees per root
        metre, the encoders' slip 0.3), and reads 3.75 % off on the real c't-Bot; its scale is
        learnt from its distance against the encoders' while driving straight. So:
        - in a step where the two turns differ by more than half a tick's, the mouse's is taken
          (a spurious tick or a wheel slipping at a wall; noise moves the mouse's a tenth of that);
        - driving straight, the encoders' turn is corrected by their drift per metre against the
          mouse, learnt over all straight driving so far (the mouse's random error averages
          out as the root of the distance, the wheels' bias does not);
        - turning on the spot, the mouse's turn is taken once the robot stands again (its counts
          add up without loss, about 0.2 degrees of noise a quarter turn; the encoders' stop up
          to a tick off, 1.75 degrees; taken step by step, the mouse's counts would end a turn
          hunting for its last fraction of a count).
        Without a mouse only the square-ups correct the heading."""
        odometry, last = self.odometry, self.last_pose
        pose = odometry.pose
        forward, lateral = readings.mouse_counts.tolist()
        if pose == last and not (forward or lateral):  # standing still
            if self.spin_gap:  # after a turn
                odometry.turn_by(self.spin_gap)
                self.spin_gap = 0.0
                self.last_pose = odometry.pose
            return
        self.last_pose = pose
        if last is None:
            return
        x, y, heading = pose
        last_x, last_y, last_heading = last
        turned = heading - last_heading
        self.heading_var += HEADING_DRIFT * (math.hypot(x - last_x, y - last_y) + abs(turned))
        if self.mouse_turn is None:
            return
        driven = (x - last_x) * math.cos(heading) + (y - last_y) * math.sin(heading)
        scale = self.mouse_straight / self.encoders_straight if self.encoders_straight > MOUSE_LEARN_M else 1.0
        mouse = lateral * self.mouse_turn / scale
        if self.drive is not None and self.drive.status is RUNNING:
            self._watch_stall(driven, forward * self.mouse_metre / scale)
        tick_turn = self.tick_turn
        larger = abs(mouse) if abs(mouse) > abs(turned) else abs(turned)  # (max of the two turns' sizes)
        if abs(turned - mouse) > tick_turn / 2:
            odometry.turn_by(mouse - turned)
        elif driven and larger < tick_turn / 4:  # straight: scale errors are nil
            self.mouse_straight += forward * self.mouse_metre * math.copysign(1.0, driven)
            self.encoders_straight += abs(driven)
            self.disagreement += turned - mouse
            if self.encoders_straight > DRIFT_LEARN_M:
                odometry.turn_by(-self.disagreement / self.encoders_straight * abs(driven))
        elif abs(driven) < self.half_track * larger:  # turning on the spot
            self.spin_gap += mouse - turned
        elif not (turned or mouse or driven) and self.spin_gap:  # standing still after a turn
            odometry.turn_by(self.spin_gap)
            self.spin_gap = 0.0
        self.last_pose = odometry.pose

    def _watch_stall(self, wheels: float, mouse: float) -> None:
        """Stop the drive under way where, over STALL_M of the wheels' rolling, the mouse saw the
        robot move less than STALL_SHARE of it (wheels spinning against a wall ahead), and move
        the believed position back to where the mouse says the robot is."""
        self.wheels_driven += wheels
        self.mouse_driven += mouse
        if self.wheels_driven < STALL_M:
            return
        if self.mouse_driven < STALL_SHARE * self.wheels_driven:
            self.odometry.move_by(self.mouse_driven - self.wheels_driven)
            self.drive.stalled = True
        self.wheels_driven = self.mouse_driven = 0.0

    @property
    def grid_pose(self) -> Pose:
        """Believed pose on the grid: room (i, j) has its centre at (i, j) * cell."""
        return relative_pose(self.frame, self.pose)

    def _face(self, quarter: int) -> Turn:
        return Turn(math.degrees(float(wrap_angle(quarter * math.pi / 2 - self.grid_pose[2]))), self.speed)

    def _learn(self, room: tuple[int, int], quarter: int, is_open: bool) -> None:
        """Remember the way between `room` and its neighbour `quarter`, seen from both sides."""
        q = quarter % 4
        i, j = room[0] + STEPS[q][0], room[1] + STEPS[q][1]
        self.known[(*room, q)] = self.known[(i, j, (q + 2) % 4)] = is_open

    def _is_open(self, room: tuple[int, int], quarter: int) -> Generator[Behaviour, Status, bool]:
        """Whether the way `quarter` out of `room` is open: remembered, or seen by facing it. A look
        that cannot tell a way open at a slant from a wall touching the sensors (`_open`) is
        checked again from RECHECK_M further back (`_receded`); an open way squares the robot up
        on what lies beyond it."""
        key = (*room, quarter % 4)
        if key not in self.known:
            yield self._face(quarter)
            look = yield from self._look()
            is_open = self._open(look.ir_distance, room, quarter)
            backed = is_open is None
            if backed:
                yield DriveDistance(-RECHECK_M, self.speed)
                again = yield from self._look()
                is_open = _receded(look.ir_distance, again.ir_distance)
                look = again
            if is_open:
                self._square_up(look.ir_distance, look.ir_error, room, quarter)
            else:
                self._square_up_near(look, room, quarter)
                if backed:
                    yield DriveDistance(RECHECK_M, self.speed)
            self.looked = (room, quarter % 4)
            self._learn(room, quarter, is_open)
        return self.known[key]

    def _look(self) -> Generator[Behaviour, Status, Look]:
        """Stand and look ahead, for longer at distances a square-up would measure by."""
        look = Look(LOOK_STEPS, LOOK_MAX_STEPS, LOOK_ERROR, SQUARE_BAND)
        yield look
        return look

    def _along(self, room: tuple[int, int], quarter: int) -> float:
        """Believed distance (m) of the robot from `room`'s centre along the way `quarter`."""
        step = STEPS[quarter % 4]
        x, y, _ = self.grid_pose
        return (x - room[0] * self.cell) * step[0] + (y - room[1] * self.cell) * step[1]

    def _open(self, distance: np.ndarray, room: tuple[int, int], quarter: int) -> bool | None:
        """Whether a look along `quarter` from `room` sees the way open (True), closed (False) or
        cannot tell (None). Closed: both sensors see something nearer than OPEN_FRACTION cells.
        Open: neither does, and a sensor sees nothing within FOLD_REACH (no wall touches the
        sensors: the other's nearer reading is the side of the way, seen at a slant by a robot
        off its line), or both
        see one face (their difference within MAX_SKEW) where a tile edge beyond the way lies
        (within FACE_TOLERANCE of the believed pose). Else a wall touching the sensors and a way
        seen at a slant look alike: a wall touching them reads up to 0.41 m on one sensor and
        0.33 m on the other, and one a few centimetres off reads anything from there to 0.1 m."""
        left, right = _in_view(distance)
        near = OPEN_FRACTION * self.cell
        if max(left, right) < near:
            return False
        if min(left, right) >= near and max(left, right) >= FOLD_REACH:
            return True
        if abs(left - right) > self.ir_baseline * math.tan(MAX_SKEW):
            return None
        beyond = (0.5 * (left + right) + self.ir_ahead + self._along(room, quarter)) / self.cell - 0.5  # rooms to the face
        return True if round(beyond) >= 1 and abs(beyond - round(beyond)) * self.cell <= FACE_TOLERANCE else None

    def _square_up_near(self, look: Look, room: tuple[int, int], quarter: int) -> None:
        """Square up on `room`'s own closed wall facing `quarter`, 0.065 m ahead of the sensors
        from its centre, where their curve folds back: each sensor's distance is the mean of its
        likelihood (`_raw_likelihood`) over the look's raw values within NEAR_WINDOW of the
        believed wall, weighed by the belief (NEAR_PRIOR); a sensor whose readings fit both sides
        of the fold-back (spread past NEAR_ERROR) leaves the belief as it is. What corrects a
        robot's position across a corridor with closed walls, which no face beyond an open way
        shows (harsh noise: robots 6 cm off the line hit a corner at its end)."""
        expected = self.cell / 2 - self._along(room, quarter) - self.ir_ahead  # believed sensors to the wall (m)
        within = np.flatnonzero(np.abs(NEAR_DISTANCES - expected) < NEAR_WINDOW)
        if not within.size:
            return
        distances = NEAR_DISTANCES[within]
        window = slice(within[0], within[-1] + 1)  # (the distances are sorted: one band of a table's columns)
        prior = -0.5 * ((distances - expected) / NEAR_PRIOR) ** 2
        means, errors = [], []
        for (low, table), raws, sensor in zip(self.raw_likelihood, look.raws, self.robot.ir):
            last = len(table) - 1  # (noise-free readings repeat one value: it says no more than once)
            rows = [min(max(value - low, 0), last) for value in (raws if sensor.noise_std else raws[:1])]
            fit = table[rows, window].sum(axis=0) + prior
            chance = np.exp(fit - fit.max())
            chance /= chance.sum()
            mean = float(chance @ distances)
            means.append(mean)
            errors.append(math.sqrt(float(chance @ (distances - mean) ** 2)))
        if max(errors) <= NEAR_ERROR:
            self._square_on(means[0], means[1], np.array(errors), room, quarter)

    def _square_up(self, distance: np.ndarray, error: np.ndarray, room: tuple[int, int], quarter: int) -> None:
        """Square up on a face beyond an open way facing `quarter`, where both IR sensors' means
        `distance` lie in SQUARE_BAND (`_square_on`)."""
        left, right = distance[0], distance[1]
        low, high = SQUARE_BAND
        if not (low < left < high and low < right < high):
            return
        self._square_on(left, right, error, room, quarter)

    def _square_on(self, left: float, right: float, error: np.ndarray, room: tuple[int, int], quarter: int) -> None:
        """Correct the grid pose from one wall face seen by both IR sensors facing `quarter`, at
        `left` and `right` (m), their standard errors `error` (m): the position along that axis is
        taken as seen, the heading weighed against the belief's own uncertainty (a look's skew of
        5 mm noise averaged 32 times is good to 1 degree, about what the belief drifts in a
        metre), as a Kalman filter of the heading would; noise-free readings are taken as seen."""
        skew = math.atan((left - right) / self.ir_baseline)
        if abs(skew) > MAX_SKEW:
            return
        pose = self.grid_pose
        axis = np.array(STEPS[quarter % 4], dtype=float)
        along = self._along(room, quarter)
        wall = (0.5 * (left + right) + self.ir_ahead) * math.cos(skew)  # robot centre to the face
        face = (round((along + wall) / self.cell - 0.5) + 0.5) * self.cell  # the nearest tile edge
        corrected = np.array(pose)
        corrected[:2] += (face - wall - along) * axis
        noise = float(np.sum(np.square(error[:2]))) / self.ir_baseline**2  # the skew's variance (rad^2)
        gain = self.heading_var / (self.heading_var + noise) if noise > 0 else 1.0
        corrected[2] += gain * float(wrap_angle(quarter * math.pi / 2 + skew - pose[2]))
        self.heading_var *= 1.0 - gain
        self.frame = apply_increment(self.pose, relative_increment(corrected, np.zeros(3)))

    def _visit(self, room: tuple[int, int]) -> None:
        """Count a visit to `room`; past MAX_VISITS forget its ways, to be seen afresh: a wall
        follower enters a room at most once through each of its four ways, so more means a way
        was misread and the plan goes round a loop that is not there."""
        self.visits[room] = self.visits.get(room, 0) + 1
        if self.visits[room] > MAX_VISITS:
            self.visits[room] = 0
            for q in range(4):
                i, j = room[0] + STEPS[q][0], room[1] + STEPS[q][1]
                self.known.pop((*room, q), None)
                self.known.pop((i, j, (q + 2) % 4), None)

    def _drive(self, room: tuple[int, int], quarter: int) -> Generator[Behaviour, Status, bool]:
        """Face `quarter` and drive to the next room's centre; on an abyss back off to this room's
        centre and remember that way as closed. Whether the robot got there."""
        yield self._face(quarter)
        if self.looked != (room, quarter % 4):  # a way known from before: square up on what lies ahead
            look = yield from self._look()
            self._square_up(look.ir_distance, look.ir_error, room, quarter)
        step = STEPS[quarter % 4]
        target = np.array([(room[0] + step[0]) * self.cell, (room[1] + step[1]) * self.cell, 0.0])
        local = relative_increment(self.pose, apply_increment(self.frame, target))
        drive = self.drive = DriveToRoom(local[0], local[1], self.speed)
        self.wheels_driven = self.mouse_driven = 0.0
        status = yield drive
        out = float(np.dot(self.grid_pose[:2] - np.asarray(room) * self.cell, step))
        if status is Status.SUCCESS or (not drive.abyss and out > self.cell / 2):
            self._learn(room, quarter, True)  # there, or passed the centre (slip on the last millimetres)
            return True
        if not (drive.abyss or drive.stalled):
            return False  # passed a target less than half a room out by its own odometry: try the next way from here
        self._learn(room, quarter, False)
        yield DriveDistance(-out, self.speed)
        return False

    def plan(self) -> Generator[Behaviour, Status, Status | None]:
        heading, room, following = 0, (0, 0), False
        for _ in range(self.max_rooms):
            if not following:  # find a wall: ahead until one is at the preferred side or in front
                if not (yield from self._is_open(room, heading + self.first)):
                    following = True
                elif not (yield from self._is_open(room, heading)):
                    heading -= self.first  # as if arrived going the other way: the wall is at hand
                    following = True
            ways = (heading + self.first, heading, heading - self.first, heading + 2) if following else (heading,)
            for way in ways:
                if (yield from self._is_open(room, way)) and (yield from self._drive(room, way)):
                    heading, room = way, (room[0] + STEPS[way % 4][0], room[1] + STEPS[way % 4][1])
                    self._visit(room)
                    break
            else:
                if following:
                    return Status.FAILURE  # walled in
        return Status.FAILURE


@register("follow_wall")
class FollowWall(SolveMaze):
    """solve_maze keeping the wall on its left: the other way through a maze (solve_maze's default
    is the right hand), as the firmware's wall follower offers both."""

    def __init__(self, hand: str = "left", cell_m: float = 0.24, speed_m_s: float = SPEED_NORMAL, max_rooms: int = 1000):
        super().__init__(hand, cell_m, speed_m_s, max_rooms)


@register("wander")
class Wander(Behaviour):
    """Explores: drives ahead and, when an IR sensor sees something within `clearance_m`, turns away
    (towards the side that sees less), by 90 degrees or more until the way is clear. While the way
    stays blocked it keeps turning the same way: choosing afresh at each quarter turn swings back
    and forth between two blocked headings in a corner."""

    def __init__(self, speed_m_s: float = SPEED_NORMAL, clearance_m: float = 0.25):
        self.speed = speed_m_s
        self.clearance = clearance_m

    def start(self) -> None:
        self.need("ir", 2)
        self.turning: Behaviour | None = None
        self.angle = 90.0  # of the quarter turns while the way is blocked (deg, + left)

    def act(self, t: float, readings: Readings) -> Command:
        if self.turning is not None and self.turning.status is Status.RUNNING:
            return self.turning.step(t, readings)
        if clear_ahead(readings.ir_distance, self.clearance):
            self.turning = None
            return Twist(self.speed, 0.0)
        if self.turning is None:  # newly blocked: away from the nearer side (nan: nothing within range)
            left, right = _in_view(readings.ir_distance)
            self.angle = 90.0 if left >= right else -90.0
        self.turning = self.run(Turn(self.angle, self.speed))
        return self.turning.step(t, readings)
