"""A run's samples: columns streamed to a temporary file as the run writes them, every robot's
log of truth, estimates and readings (`RobotLog`), and the finished run (`RunResult`)."""

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
from sim.world.physics import ReadingsPlan
from sim.world.spec import WorldSpec

_UPPER = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))
"""Where a (3, 3) covariance's COVARIANCE_FIELDS entries are."""
BLOCK = 65536
"""Samples per block when a finished run is read through (metrics, files)."""
CUT = 256
"""Rows whose views `_Columns.row` cuts at once."""
WINDOW = 8192
"""Samples of every column a running log holds in memory: the rows being written; each window
full goes to the run's file, so memory and address space stay the same however long the run."""


def row(shape: tuple[int, ...] = (), kind: type = np.float64) -> np.dtype:
    """The type of one sample's row of a column: `kind` values of `shape` (a numpy subarray dtype)."""
    return np.dtype((kind, shape)) if shape else np.dtype(kind)


class SamplesNotKept(OSError):
    """The run's file of samples cannot take more rows (a disk error): the run ends there, every
    sample before it kept."""


WHOLE = 32 << 20
"""Largest file of samples read, once its run has ended, through one mapping of all of it (a run
of up to about 75,000 samples of a c't-Bot; `_Store.settle`): its rows are views of that, and a
result kept holds that mapping's file descriptor alone. While a run runs, and after a longer run,
rows are mapped a range at a time."""


class _Store:
    """The unlinked temporary file (in TMPDIR) that holds a run's columns, and the regions handed
    out of it, each given its disk space when handed out (`_reserve`). Unlinked, it has no name in
    any folder a link, a pipe or another process could take."""

    def __init__(self) -> None:
        self._file = tempfile.TemporaryFile()
        self.descriptor = self._file.fileno()
        self.size = 0
        self._whole: mmap.mmap | bytes | None = None

    def __getstate__(self) -> dict:
        """Pickled as the bytes its file holds (a result sent to another process: multiprocessing,
        joblib): the copy reads its rows from those (`whole`), with no file of its own."""
        if self._whole is not None:
            return {"size": self.size, "data": bytes(self._whole)}
        chunks, at = [], 0
        while at < self.size:
            chunk = os.pread(self.descriptor, min(self.size - at, 1 << 26), at)
            if not chunk:
                break
            chunks.append(chunk)
            at += len(chunk)
        return {"size": self.size, "data": b"".join(chunks)}

    def __setstate__(self, state: dict) -> None:
        self._file, self.descriptor, self.size, self._whole = None, -1, state["size"], state["data"]  # (-1: a write fails as on a disk error)

    @property
    def whole(self) -> bool:
        """Whether the file is read through one mapping of all of it (`settle`)."""
        return self._whole is not None

    def mapped(self, offset: int, length: int) -> tuple[mmap.mmap, int]:
        """A read-only mapping that holds the file's bytes [offset, offset + length), and where in
        it they start: the whole file's (`settle`), else one of just that range."""
        if self._whole is not None:
            return self._whole, offset
        aligned = offset - offset % mmap.ALLOCATIONGRANULARITY
        return mmap.mmap(self.descriptor, offset - aligned + length, access=mmap.ACCESS_READ, offset=aligned), offset - aligned

    def settle(self) -> None:
        """Once every row is in the file: a file of WHOLE bytes at most is read through one
        mapping from then on, and its own descriptor closed (a result kept holds the mapping's)."""
        if self.size <= WHOLE and self._whole is None:
            try:
                self._whole = mmap.mmap(self.descriptor, self.size, access=mmap.ACCESS_READ)
            except OSError:  # (no address space left for it: read by range, as a longer run)
                return
            self._file.close()

    def regions(self, sizes: list[int]) -> list[int]:
        """The offsets of new regions of `sizes` bytes (each from a page boundary, as mappings
        start), reserved at once."""
        offsets, start = [], self.size
        for size in sizes:
            offsets.append(self.size)
            self.size += -(-size // mmap.PAGESIZE) * mmap.PAGESIZE
        if self.size > start:
            _reserve(self.descriptor, start, self.size - start)
        return offsets


class _Columns:
    """Columns of a run's samples (name -> the type of one row, `row`) of up to `capacity` rows in
    a run's file (`_Store`). Writers fill `arrays`, WINDOW rows each, at `local(n)`; a full window
    goes to the file and the arrays take the next rows. Readers get rows mapped from the file (the
    page cache; rows still in the window are written there first), read-only and without a copy:
    a run's memory and address space do not grow with its length, and one robot's part of a row
    is a view of it. In a file mapped a range at a time (`_Store.mapped`), the last rows read of
    each column (a block at most) stay mapped, so that every robot's part of a block is read from
    one mapping."""

    def __init__(self, store: _Store, rows: dict[str, np.dtype], capacity: int):
        self.window = max(1, min(WINDOW, capacity))
        _check_address_space(sum(kind.itemsize for kind in rows.values()) * self.window)
        self._store, self._kinds = store, rows
        self._offsets = dict(zip(rows, store.regions([capacity * kind.itemsize for kind in rows.values()])))
        self.arrays = {name: np.zeros((self.window, *kind.shape), kind.base) for name, kind in rows.items()}
        self.base = 0
        """The run's row of the arrays' first row: rows before it are in the file."""
        self._kept = dict.fromkeys(rows, 0)
        """Per column, the rows [0, kept) in the file."""
        self.last: dict[str, tuple[int, int, np.ndarray]] = {}
        """Per column, the rows last mapped (start, stop, rows), while rows are mapped by range."""
        self._cut: tuple[int, tuple[str, ...], list[tuple[np.ndarray, ...]]] = (-1, (), [])
        """The rows last cut by `row` (their first row, the columns, the views)."""

    def __getstate__(self) -> dict:
        """Pickled without the rows last mapped (views of the file's mappings)."""
        return {**self.__dict__, "last": {}}

    def local(self, n: int) -> int:
        """Where the arrays take the run's row `n` (rows are written in order): a full window is
        written to the file first (SamplesNotKept where it cannot be)."""
        at = n - self.base
        if at < self.window:
            return at
        self.keep(self.base + self.window)
        self.base = n
        return 0

    def row(self, at: int, names: tuple[str, ...]) -> tuple[np.ndarray, ...]:
        """Row `at` of the arrays (`local`'s) of the columns `names` (rows of more than one value),
        as views: cut CUT rows at a time by iteration, so that a run's step costs a list index, not
        an indexing per column (a tenth of its loop's own work)."""
        start, cut, views = self._cut
        if not (start <= at < start + CUT and cut == names):
            start = at - at % CUT
            views = list(zip(*(self.arrays[name][start : start + CUT] for name in names)))
            self._cut = (start, names, views)
        return views[at - start]

    def keep(self, stop: int) -> None:
        """Write every column's window rows below `stop` to the file."""
        for name in self._kinds:
            self._keep(name, stop)

    def _keep(self, name: str, stop: int) -> None:
        """Write the window's rows of column `name` below `stop` to the file (rows written whole)."""
        start, width = self._kept[name], self._kinds[name].itemsize
        if stop <= start or not width:  # (a column of no values: the batch's poses in a run without it)
            return
        data = memoryview(self.arrays[name][start - self.base : stop - self.base]).cast("B")
        offset, done = self._offsets[name] + start * width, 0
        try:
            while done < len(data):
                done += os.pwrite(self._store.descriptor, data[done:], offset + done)
        except OSError as err:
            raise SamplesNotKept(err.errno, f"the run's samples from sample {start} on could not be written to the temporary folder {tempfile.gettempdir()} "
                                            f"({err.strerror or err}); the run ends there") from None  # fmt: skip
        self._kept[name] = stop

    def view(self, name: str, start: int, stop: int) -> np.ndarray:
        """Rows [start, stop) of column `name` (rows written whole: below the run's count),
        mapped read-only from the file; where the window's rows cannot be written there (a disk
        error ended the run), they are copied from the window."""
        kind = self._kinds[name]
        if stop <= start or not kind.itemsize:
            return np.empty((max(stop - start, 0), *kind.shape), kind.base)
        try:
            self._keep(name, stop)
        except SamplesNotKept:
            kept = min(max(start, self.base), stop)
            rows = np.concatenate((self._mapped(name, start, kept), self.arrays[name][kept - self.base : stop - self.base]))
            rows.flags.writeable = False
            return rows
        last = self.last.get(name)
        if last is not None and last[0] <= start and stop <= last[1]:
            return last[2][start - last[0] : stop - last[0]]
        rows = self._mapped(name, start, stop)
        if not self._store.whole and stop - start <= BLOCK:  # (ranges mapped apart; a long run read whole is not kept mapped)
            self.last[name] = (start, stop, rows)
        return rows

    def _mapped(self, name: str, start: int, stop: int) -> np.ndarray:
        """Rows [start, stop) of column `name` in the file, mapped read-only (unmapped when the
        array goes)."""
        kind = self._kinds[name]
        if stop <= start:
            return np.empty((0, *kind.shape), kind.base)
        mapped, at = self._store.mapped(self._offsets[name] + start * kind.itemsize, (stop - start) * kind.itemsize)
        return np.frombuffer(mapped, kind.base, (stop - start) * math.prod(kind.shape), at).reshape(stop - start, *kind.shape)


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
            f"the run needs about {(used + size + HEADROOM) / 2**30:.1f} GiB of address space, more than the limit of {limit / 2**30:.1f} GiB "
            f"(ulimit -v); a run's length does not change it (its samples go to a file as it runs): raise the limit"
        )


def _reserve(descriptor: int, offset: int, size: int) -> None:
    """Give the columns' file its disk space now: a window written into a sparse file on a full
    disk would fail mid-run, a reservation that does not fit is a RunError before the run starts,
    naming the folder (TMPDIR) and what is missing."""
    try:
        if hasattr(os, "posix_fallocate"):
            os.posix_fallocate(descriptor, offset, size)
        else:
            os.truncate(descriptor, offset + size)
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
    them), in the run's file beside the robots' own (`new_columns`). `count` is the number of complete
    samples: a sample counts once every robot's part of it is written (a Ctrl-C half-way leaves the
    last row uncounted)."""

    def __init__(self, sensors: dict[str, np.dtype], batched: int, capacity: int):
        self._store, self._every = _Store(), []
        self.capacity = capacity
        self.columns = self.new_columns({"time": row(), "poses": row((batched, 1 + ESTIMATES, 3)), "covariances": row((batched, ESTIMATES, COVARIANCES)), **sensors})
        self.count = 0
        self.frame: SensorFrame | None = None
        """The readings of the current sample."""

    def new_columns(self, rows: dict[str, np.dtype]) -> _Columns:
        """Columns of the run's length in its file (the run's own, or a robot's)."""
        columns = _Columns(self._store, rows, self.capacity)
        self._every.append(columns)
        return columns

    def settle(self) -> None:
        """At the run's end: every complete row written to the file (`_Store.settle`); a disk
        error leaves the rows not written in their windows, where they are read."""
        try:
            for columns in self._every:
                columns.keep(self.count)
        except SamplesNotKept:
            return
        self._store.settle()

    def forget(self) -> None:
        """Let go of the rows last mapped of every column (`_Columns.view`)."""
        for columns in self._every:
            columns.last.clear()

    def rows(self, rows: slice | None) -> tuple[int, int]:
        """(start, stop) of `rows` (None: all) among the complete samples (a slice of step 1)."""
        span = range(self.count)[rows if rows is not None else slice(None)]
        if span.step != 1:
            raise ValueError(f"rows of a run are read as a slice of step 1, not {rows}")
        return span.start, span.stop


class RobotLog:
    """Everything one robot did in a run, one row per sample (the start of every step, and the
    end of the run): ground truth and each estimate as (T, 3) arrays, each estimate's covariance
    where it has one as (T, 6) (`bots.uncertainty.COVARIANCE_FIELDS`), its readings as columns,
    and the current sample's readings. Rows live in the run's streamed columns (`_Columns`): the
    run's own (`Samples`) for a robot with the default estimators, else its own; so a long run
    costs bytes of disk per sample, not a Python object per step, and its memory stays flat. Rows
    are read by range (`truth_array(rows)`, ...), read-only."""

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
        self.puts: list[int] = []
        """The samples, in order, at which it stood where it was put down (`World.put_robot`,
        `reset_robot`: a kidnapping, a click in `ctsim play`), not where its motion took it from
        the sample before: its true path breaks before each (a put before the first sample, none)."""
        self.notes: dict[str, list] = {}
        """What the run did other than asked (projected infeasible twists): kind -> [first message, count]."""
        self.estimators: list = []
        """The robot's estimators stepped in Python (none where the batch steps its defaults), for
        observers that draw what one holds beyond its pose (a localiser's particles)."""
        self._samples, self._world = samples, world
        self._plan: ReadingsPlan | None = None
        """Where its readings lie in the run's rows, once its world is let go (`__getstate__`)."""
        uncertain = list(estimators if uncertain is None else uncertain)
        self._columns: _Columns | None = None
        """The robot's own columns: all its poses (slot None), or its `extra` estimators'."""
        if slot is None:
            self._columns = own = samples.new_columns({"poses": row((1 + len(estimators), 3)), "covariances": row((len(uncertain), COVARIANCES))})
            place: tuple[_Columns, tuple] = (own, ())
        else:
            place = (samples.columns, (slot,))
        # where each of its columns lies: (columns, column name, index within a row)
        self._truth = (place[0], "poses", (*place[1], 0))
        self._estimates = {label: (place[0], "poses", (*place[1], 1 + k)) for k, label in enumerate(estimators)}
        self._uncertain = {label: (place[0], "covariances", (*place[1], k)) for k, label in enumerate(uncertain)}
        if extra:  # a batched robot's own estimators: in columns of its own, after the batch's
            self._columns = own = samples.new_columns({"poses": row((len(extra), 3)), "covariances": row((len(extra_uncertain), COVARIANCES))})
            self._estimates |= {label: (own, "poses", (k,)) for k, label in enumerate(extra)}
            self._uncertain |= {label: (own, "covariances", (k,)) for k, label in enumerate(extra_uncertain)}
        self._own = (self._columns.arrays["poses"], self._columns.arrays["covariances"]) if self._columns is not None else None
        """The rows in memory (`_Columns.arrays`, the same arrays all run) that `append` or `append_extra` write."""

    def __getstate__(self) -> dict:
        """Pickled (with its run's result: a result sent to another process) without its world and
        its estimators (live objects: the simulation, the user's code), where its readings lie
        in the rows kept instead (`readings`)."""
        plan = self._plan or self._world.readings_plan(self.index)
        return {**self.__dict__, "_world": None, "_plan": plan, "estimators": []}

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
        at = self._columns.local(self._samples.count)
        poses, entries = self._own
        poses[at, 0] = truth
        if len(estimates):
            poses[at, 1:] = estimates
        for k, cov in enumerate(covariances):
            entries[at, k] = cov[_UPPER]

    def append_extra(self, estimates: Sequence[np.ndarray], covariances: Sequence[np.ndarray] = ()) -> None:
        """Log the current sample of a batched robot's own estimators (`extra`): their poses and
        the (3, 3) covariances of those with one (the batch logs the rest)."""
        at = self._columns.local(self._samples.count)
        poses, entries = self._own
        for k, pose in enumerate(estimates):  # (pose by pose: numpy makes an array of a list of them first)
            poses[at, k] = pose
        for k, cov in enumerate(covariances):
            entries[at, k] = cov[_UPPER]

    def __len__(self) -> int:
        return self._samples.count

    def note(self, message: str) -> None:
        """Count a message; messages that differ only in their numbers are one kind (bounded memory)."""
        entry = self.notes.setdefault(re.sub(r"-?\d[\d.e+-]*", "#", message), [message, 0])
        entry[1] += 1

    def _read(self, place: tuple[_Columns, str, tuple], rows: slice | None) -> np.ndarray:
        columns, name, within = place
        return columns.view(name, *self._samples.rows(rows))[(slice(None), *within)]

    @property
    def estimate_names(self) -> list[str]:
        """The estimators whose poses the log holds, in order."""
        return list(self._estimates)

    @property
    def uncertain_names(self) -> list[str]:
        """Those of them with a covariance."""
        return list(self._uncertain)

    def time_array(self, rows: slice | None = None) -> np.ndarray:
        """(T,) sample times (s) of `rows` (None: all), the run's."""
        return self._samples.columns.view("time", *self._samples.rows(rows))

    def truth_array(self, rows: slice | None = None) -> np.ndarray:
        """(T, 3) ground-truth poses of `rows` (None: all)."""
        return self._read(self._truth, rows)

    def estimate_arrays(self, rows: slice | None = None) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 3) estimated poses of `rows` (None: all)."""
        return {label: self._read(place, rows) for label, place in self._estimates.items()}

    def poses_of(self, label: str, rows: slice | None = None) -> np.ndarray:
        """(T, 3) poses of `rows` (None: all) of the truth (label 'truth', a name no estimator may
        take) or of one estimate."""
        return self._read(self._truth if label == "truth" else self._estimates[label], rows)

    def covariance_arrays(self, rows: slice | None = None) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 6) covariance entries (COVARIANCE_FIELDS: m², m·rad, rad²) of `rows`
        (None: all) of the estimates that have one."""
        return {label: self._read(place, rows) for label, place in self._uncertain.items()}

    def readings(self, rows: slice) -> dict[str, np.ndarray]:
        """This robot's readings of samples `rows` as columns: Readings' field name -> (n, width)
        array (not a general chassis's per-wheel fields)."""
        columns, span = self._samples.columns, self._samples.rows(rows)
        plan = self._plan or self._world.readings_plan(self.index)
        return plan.columns(columns.view("values", *span), columns.view("believed", *span), columns.view("tallies", *span))


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
        """(T,) sample times (s), read-only."""
        return self.time_array()

    def time_array(self, rows: slice | None = None) -> np.ndarray:
        """(T,) sample times (s) of `rows` (None: all), read-only."""
        return self._samples.columns.view("time", *self._samples.rows(rows))

    def __len__(self) -> int:
        return self._samples.count

    @property
    def duration(self) -> float:
        """Simulated seconds covered (0 before the first sample)."""
        last = self.time_array(slice(-1, None))
        return float(last[0]) if len(last) else 0.0

    def blocks(self, size: int | None = None) -> Iterator[slice]:
        """Row ranges that cover every sample, `size` (default BLOCK) at a time, to read a long run
        through with bounded memory (each block's rows are mapped while they are read, the last
        block's no longer once all are read)."""
        size = size or BLOCK
        for start in range(0, len(self), size):
            yield slice(start, min(start + size, len(self)))
        self._samples.forget()
