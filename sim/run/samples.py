"""A run's samples: file-backed columns allocated once for the whole run, every robot's log of
truth, estimates and readings (`RobotLog`), and the finished run (`RunResult`)."""

from __future__ import annotations

import math
import mmap
import os
import re
import tempfile
from collections.abc import Iterator, Sequence

import numpy as np

from bots.odometry.batch import COVARIANCES, ESTIMATES
from bots.readings import Readings, SensorFrame
from bots.spec import RobotSpec
from sim.run.ending import Ending, RunError
from sim.world import World
from sim.world.spec import WorldSpec

_UPPER = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))
"""Where a (3, 3) covariance's COVARIANCE_FIELDS entries are."""
BLOCK = 65536
"""Samples per block when a finished run is read through (metrics, files)."""
RESIDENT = 8192
"""Samples of a running log kept in resident memory: observers read the latest ones (the
recorder up to `sim.views.recording.recorder.CHUNK` back)."""


def row(shape: tuple[int, ...] = (), kind: type = np.float64) -> np.dtype:
    """The type of one sample's row of a column: `kind` values of `shape` (a numpy subarray dtype)."""
    return np.dtype((kind, shape)) if shape else np.dtype(kind)


class _Columns:
    """Preallocated arrays of a run's samples (name -> the type of one row, `row`), backed by an
    unlinked temporary file instead of anonymous memory. Pages are touched only when written, and
    rows already written or read can be handed back to the operating system (`release`): they stay
    readable (a read brings its page back from the file), so an hour-long run's resident memory
    does not grow with its length, while every column stays an ordinary numpy array."""

    def __init__(self, rows: dict[str, np.dtype], capacity: int):
        page = mmap.PAGESIZE
        sizes = {name: -(-max(capacity, 1) * kind.itemsize // page) * page for name, kind in rows.items()}
        total = max(sum(sizes.values()), page)  # (mmap refuses an empty map)
        _check_address_space(total)
        with tempfile.TemporaryFile() as handle:
            _reserve(handle.fileno(), total)
            self._map = mmap.mmap(handle.fileno(), total)
        self.arrays: dict[str, np.ndarray] = {}
        self._regions: list[tuple[int, int]] = []  # (byte offset, bytes per row) of each column
        offset = 0
        for name, kind in rows.items():
            count = capacity * math.prod(kind.shape)
            self.arrays[name] = np.frombuffer(self._map, kind.base, count, offset).reshape(capacity, *kind.shape)
            self._regions.append((offset, kind.itemsize))
            offset += sizes[name]
        self._released = 0

    def release(self, start: int, stop: int) -> None:
        """Take rows [start, stop) out of resident memory (whole pages inside that range)."""
        if not hasattr(mmap, "MADV_DONTNEED"):  # not on every platform: memory then just grows
            return
        page = mmap.PAGESIZE
        for offset, width in self._regions:
            first, last = -(-start * width // page) * page, stop * width // page * page
            if last > first:
                self._map.madvise(mmap.MADV_DONTNEED, offset + first, last - first)

    def release_written(self, count: int) -> None:
        """While a run writes: release what lies more than RESIDENT rows behind `count`, once per
        RESIDENT rows."""
        if count - self._released >= 2 * RESIDENT:
            self.release(self._released, count - RESIDENT)
            self._released = count - RESIDENT


HEADROOM = 2 << 30
"""Address space (bytes) a run takes beside its columns once it runs: the recording's threads and
buffers, the writers' blocks (a 100 s run of one c't-Bot grew by 1.8 GiB after its columns)."""


def _check_address_space(size: int) -> None:
    """Refuse (RunError, one line) columns of `size` bytes that would not fit, with HEADROOM, under
    the process's address-space limit (`ulimit -v`): past it an allocation inside the recorder
    aborts the process (SIGABRT) with nothing written. Linux only (it reads /proc/self/statm)."""
    try:
        import resource

        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        with open("/proc/self/statm", encoding="ascii") as statm:
            used = int(statm.read().split()[0]) * mmap.PAGESIZE
    except (ImportError, OSError, ValueError):
        return
    if limit != resource.RLIM_INFINITY and used + size + HEADROOM > limit:
        raise RunError(
            f"the run needs about {(used + size + HEADROOM) / 2**30:.1f} GiB of address space ({size / 2**30:.1f} GiB for its "
            f"samples), more than the limit of {limit / 2**30:.1f} GiB (ulimit -v); give a shorter --duration or fewer robots, or raise the limit"
        )


def _reserve(descriptor: int, size: int) -> None:
    """Give the columns' file its disk space now: a page first written into a sparse file on a
    full disk kills the process (SIGBUS), a reservation that does not fit is a RunError before
    the run starts, naming the folder (TMPDIR) and what is missing."""
    try:
        if hasattr(os, "posix_fallocate"):
            os.posix_fallocate(descriptor, 0, size)
        else:
            os.truncate(descriptor, size)
    except OSError as err:
        folder = tempfile.gettempdir()
        raise RunError(
            f"the run's trajectories need {size / 1e6:.1f} MB in the temporary folder {folder} and it has no room "
            f"({err.strerror}); free space there or point TMPDIR at a folder with room"
        ) from None


class Samples:
    """The run's own columns, one row per sample for all robots at once: the sample times, the
    arrays the world's sensors are read into (`World.sensor_rows`), and the true pose and default
    estimates of the robots whose odometry is stepped in one batch (`DefaultOdometry`, which writes
    them). `count` is the number of complete samples: a sample counts once every robot's part of
    it is written (a Ctrl-C half-way leaves the last row uncounted)."""

    def __init__(self, sensors: dict[str, np.dtype], batched: int, capacity: int):
        self.columns = _Columns({"time": row(), "poses": row((batched, 1 + ESTIMATES, 3)), "covariances": row((batched, ESTIMATES, COVARIANCES)), **sensors}, capacity)
        arrays = self.columns.arrays
        self.time, self.poses, self.covariances = arrays["time"], arrays["poses"], arrays["covariances"]
        self.values, self.believed, self.tallies = arrays["values"], arrays["believed"], arrays["tallies"]
        self.count = 0
        self.frame: SensorFrame | None = None
        """The readings of the current sample."""


class RobotLog:
    """Everything one robot did in a run, one row per sample (the start of every step, and the
    end of the run): ground truth and each estimate as (T, 3) arrays, each estimate's covariance
    where it has one as (T, 6) (`bots.uncertainty.COVARIANCE_FIELDS`), its readings as columns,
    and the current sample's readings. Rows live in file-backed arrays allocated once for the whole run
    (`_Columns`): the run's own (`Samples`) for a robot with the default estimators, else its own;
    so a long run costs bytes of disk per sample, not a Python object per step, and its resident
    memory stays flat."""

    def __init__(self, name: str, spec: RobotSpec, controller_name: str, params: dict[str, str],
                 estimators: list[str], samples: Samples, index: int, world: World, slot: int | None = None,
                 uncertain: Sequence[str] | None = None, extra: Sequence[str] = (), extra_uncertain: Sequence[str] = ()):  # fmt: skip
        """`index`: the robot's index in the world; `slot`: its row in the batched odometry (None:
        Python estimators, logged by `append`); `uncertain`: the estimates that have a covariance
        (None: all). `extra`: a batched robot's own Python estimators beside the batch's (logged
        by `append_extra`), `extra_uncertain` those of them with a covariance."""
        self.name, self.spec, self.controller_name, self.params = name, spec, controller_name, params
        self.index = index
        self.collisions = 0
        self.fell = False
        self.status: str | None = None
        """How its controller ended, where it says ('success', 'failure'; 'running'), else None."""
        self.goal_time: float | None = None
        self.notes: dict[str, list] = {}
        """What the run did other than asked (projected infeasible twists): kind -> [first message, count]."""
        self.estimators: list = []
        """The robot's estimators stepped in Python (none where the batch steps its defaults), for
        observers that draw what one holds beyond its pose (a localiser's particles)."""
        self._samples, self._world = samples, world
        uncertain = list(estimators if uncertain is None else uncertain)
        if slot is None:
            rows = {"poses": row((1 + len(estimators), 3)), "covariances": row((len(uncertain), COVARIANCES))}
            self._columns: _Columns | None = _Columns(rows, len(samples.time))
            self._poses, self._covariances = self._columns.arrays["poses"], self._columns.arrays["covariances"]
        else:
            self._columns = None
            self._poses = samples.poses[:, slot, : 1 + len(estimators)]
            self._covariances = samples.covariances[:, slot, : len(estimators)]
        """Per sample: the true pose, then each estimate (one row to write a sample, not one per
        pose); and the covariances of those in `uncertain`."""
        self._truth = self._poses[:, 0]
        self._estimates = {label: self._poses[:, 1 + k] for k, label in enumerate(estimators)}
        self._uncertain = {label: self._covariances[:, k] for k, label in enumerate(uncertain)}
        if extra:  # a batched robot's own estimators: in columns of its own, after the batch's
            rows = {"poses": row((len(extra), 3)), "covariances": row((len(extra_uncertain), COVARIANCES))}
            self._columns = _Columns(rows, len(samples.time))
            self._extra_poses, self._extra_covariances = self._columns.arrays["poses"], self._columns.arrays["covariances"]
            self._estimates |= {label: self._extra_poses[:, k] for k, label in enumerate(extra)}
            self._uncertain |= {label: self._extra_covariances[:, k] for k, label in enumerate(extra_uncertain)}

    def goal_outcome(self, duration: float) -> str:
        """Whether and when the robot reached its goal, in the words the table, report.html and
        the recording say it in: 'goal reached at 231.4 s' or 'goal not reached in 300 s'."""
        return f"goal reached at {self.goal_time:.1f} s" if self.goal_time is not None else f"goal not reached in {duration:g} s"

    @property
    def latest(self) -> Readings | None:
        """The readings of the current sample (what the controller gets this step)."""
        frame = self._samples.frame
        return None if frame is None else frame[self.index]

    def append(self, truth: np.ndarray, estimates: np.ndarray | Sequence[np.ndarray], covariances: Sequence[np.ndarray] = ()) -> None:
        """Log the current sample of a robot with Python estimators: the true pose (3,), the
        estimates, (k, 3) or k poses, and the (3, 3) covariances of those with one."""
        n = self._samples.count
        self._truth[n] = truth
        if len(estimates):
            self._poses[n, 1:] = estimates
        for k, cov in enumerate(covariances):
            self._covariances[n, k] = cov[_UPPER]
        self._columns.release_written(n + 1)

    def append_extra(self, estimates: Sequence[np.ndarray], covariances: Sequence[np.ndarray] = ()) -> None:
        """Log the current sample of a batched robot's own estimators (`extra`): their poses and
        the (3, 3) covariances of those with one (the batch logs the rest)."""
        n = self._samples.count
        row = self._extra_poses[n]
        for k, pose in enumerate(estimates):  # (pose by pose: numpy makes an array of a list of them first)
            row[k] = pose
        for k, cov in enumerate(covariances):
            self._extra_covariances[n, k] = cov[_UPPER]
        self._columns.release_written(n + 1)

    def release(self, rows: slice) -> None:
        """Take these rows out of resident memory (they stay readable)."""
        if self._columns is not None:
            self._columns.release(rows.start, rows.stop)

    def __len__(self) -> int:
        return self._samples.count

    def note(self, message: str) -> None:
        """Count a message; messages that differ only in their numbers are one kind (bounded memory)."""
        entry = self.notes.setdefault(re.sub(r"-?\d[\d.e+-]*", "#", message), [message, 0])
        entry[1] += 1

    def time_array(self) -> np.ndarray:
        """(T,) sample times (s), the run's (a view)."""
        return self._samples.time[: self._samples.count]

    def truth_array(self) -> np.ndarray:
        """(T, 3) ground-truth poses (a view, no copy)."""
        return self._truth[: self._samples.count]

    def estimate_arrays(self) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 3) estimated poses (views, no copies)."""
        count = self._samples.count
        return {label: poses[:count] for label, poses in self._estimates.items()}

    def covariance_arrays(self) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 6) covariance entries (COVARIANCE_FIELDS: m², m·rad, rad²) of the
        estimates that have one (views, no copies)."""
        count = self._samples.count
        return {label: values[:count] for label, values in self._uncertain.items()}

    def readings(self, rows: slice) -> dict[str, np.ndarray]:
        """This robot's readings of samples `rows` as columns: Readings' field name -> (n, width)
        array (views into the run's columns; not a general chassis's per-wheel fields)."""
        s = self._samples
        return self._world.readings_columns(self.index, s.values[rows], s.believed[rows], s.tallies[rows])


class RunResult:
    """A finished (or stopped) run. `reason` is how it ended (an `Ending`); `verdict` what `run`'s
    referee (`stop_when`) answered when it ended the run (reason JUDGED), else None; `error` holds
    the one-line message of a failure."""

    def __init__(self, world: WorldSpec, seed: int, dt: float, robots: list[RobotLog], samples: Samples):
        self.world, self.seed, self.dt, self.robots = world, seed, dt, robots
        self.reason: Ending = Ending.DURATION
        self.verdict: str | None = None
        self.error: str | None = None
        self.failed_estimator: tuple[int, str] | None = None
        """(robot index, estimator name) of the Python estimator whose failure ended the run, else None."""
        self.notes: list[str] = []
        """What the run's guards put back that a controller had changed (`sim.guards`), once each."""
        self._samples = samples

    @property
    def time(self) -> np.ndarray:
        """(T,) sample times (s), a view."""
        return self._samples.time[: self._samples.count]

    def __len__(self) -> int:
        return self._samples.count

    @property
    def duration(self) -> float:
        """Simulated seconds covered (0 before the first sample)."""
        count = self._samples.count
        return float(self._samples.time[count - 1]) if count else 0.0

    def blocks(self, size: int | None = None) -> Iterator[slice]:
        """Row ranges that cover every sample, `size` (default BLOCK) at a time, to read a long run
        through with bounded memory: once the next is asked for, the previous block's rows of the
        run's columns and of every robot's log leave resident memory again."""
        size = size or BLOCK
        for start in range(0, len(self), size):
            rows = slice(start, min(start + size, len(self)))
            yield rows
            self._samples.columns.release(rows.start, rows.stop)
            for log in self.robots:
                log.release(rows)
