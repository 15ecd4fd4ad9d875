"""One step's sensor readings of one robot: the only view of the world a controller gets; and
every robot's readings of one step as the step's arrays (`SensorFrame`)."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, make_dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from bots.sensor_kinds import FRAMED, FRAMES, KINDS, SensorKind


def _frozen(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values


def frozen_copy(array: np.ndarray) -> np.ndarray:
    """A flat copy of `array` over immutable bytes: no flag, view or `.base` of it can be made
    writeable (numpy refuses), so readings handed to a controller never reach the array they were
    copied from. (Cheaper than one bytes object for a step's three rows: memoryviews cost more than
    they save.)"""
    return np.frombuffer(array.tobytes(), array.dtype)


def _empty(kind: SensorKind) -> Callable[[], np.ndarray]:
    """A kind's value where none was read: zeros of its fixed channels (none for a list of sensors)."""
    return lambda: np.zeros(len(kind.channels), kind.dtype)


def _readings_class() -> type:
    """`Readings`, one array field per row of the sensor registry, in its order (between `time`
    and `failures`), so that a new kind is a row there and nothing here."""
    arrays = [(kind.field, np.ndarray, field(default_factory=_empty(kind))) for kind in KINDS]
    made = make_dataclass("Readings", [("time", float, field(default=0.0)), *arrays, ("failures", tuple, field(default=()))], slots=True)
    made.__module__ = __name__  # (so that it pickles, for the sandbox's processes, as `bots.readings.Readings`)
    made.__doc__ = "\n".join([
        "Sensor values read at the start of a step, in the devices' own units: one array per kind of",
        "the sensor registry (`bots.sensor_kinds.KINDS`, its `meaning`), named after it.",
        "",
        "time: simulated time of the reading (s).",
        *(f"{kind.field}: {kind.meaning}." for kind in KINDS),
        "failures: the wheel faults a general chassis's fault observer reports (`bots.chassis_commands`).",
        "",
        "(Slots: controllers read its fields often.) For sums on a few values, unpack `.tolist()`: the",
        "arrays' items are numpy scalars, and numpy 2 multiplies an int64 one by a Python float in about",
        "2 µs, a Python int in 40 ns (`left, right = readings.encoder_ticks.tolist()`).",
    ])  # fmt: skip
    return made


if TYPE_CHECKING:  # (what a type checker knows of the class made from the registry)

    class Readings:
        time: float
        failures: tuple

        def __init__(self, time: float = 0.0, *arrays: np.ndarray, failures: tuple = (), **named: np.ndarray) -> None: ...
        def __getattr__(self, field: str) -> np.ndarray: ...
else:
    Readings = _readings_class()


ARRAYS = tuple(kind.field for kind in KINDS)
"""Readings' arrays, in its fields' order (the registry's kinds)."""
CHASSIS_ONLY = {kind.field: _frozen(np.zeros(len(kind.channels), kind.dtype)) for kind in KINDS if kind.frame is None}
"""What a c't-Bot's readings hold for a general chassis's own kinds (steering angles, second mouse; shared, read-only)."""
ROWS_FROM = 16
"""Robots from which, all alike, readings are cut from a step's arrays by rows (one numpy call per
kind) rather than by a slice per robot and kind (cheaper for a few robots)."""


@dataclass(frozen=True)
class SensorLayout:
    """Where each robot's readings lie in a step's arrays (the registry's `FRAMES`) and those in
    the World's rows: in each array, robot after robot, the kinds packed there (`FRAMED`) in the
    registry's order; in each row, its arrays in `FRAMES`' order."""

    cuts: tuple[tuple[str, str, slice], ...]
    """Each frame array: (its name, its row, its slice of the row)."""
    plans: list[tuple[tuple[str | None, Any], ...]]
    """Per robot, for each of `ARRAYS`: (its row, its slice of the row flattened), or (None, its
    constant) for a general chassis's own kinds."""
    columns: tuple[tuple[str | None, Any], ...] | None
    """Robots all alike: for each of `ARRAYS`, (its frame array, its columns in a robot's row of
    it) or (None, its constant); None otherwise."""

    @classmethod
    def of(cls, widths: list[dict[str, int]]) -> SensorLayout:
        """The layout of robots whose framed kinds have these widths (field -> `SensorKind.width`), in order."""
        sizes = {frame.name: sum(robot[kind.field] for robot in widths for kind in FRAMED if kind.frame == frame.name) for frame in FRAMES}
        cuts, ends = [], dict.fromkeys((frame.row for frame in FRAMES), 0)
        for frame in FRAMES:
            start = ends[frame.row]
            ends[frame.row] = start + sizes[frame.name]
            cuts.append((frame.name, frame.row, slice(start, ends[frame.row])))
        row_of = {name: (row, cut.start) for name, row, cut in cuts}
        filled = {frame.name: 0 for frame in FRAMES}
        plans, columns = [], None
        for robot in widths:
            own, relative = {}, {}
            for kind in FRAMED:
                row, offset = row_of[kind.frame]
                start = filled[kind.frame]
                filled[kind.frame] = start + robot[kind.field]
                own[kind.field] = (row, slice(offset + start, offset + filled[kind.frame]))
                relative[kind.field] = (kind.frame, slice(start, filled[kind.frame]))
            plans.append(tuple(own.get(name, (None, CHASSIS_ONLY.get(name))) for name in ARRAYS))
            if columns is None:
                columns = tuple(relative.get(name, (None, CHASSIS_ONLY.get(name))) for name in ARRAYS)
        return cls(tuple(cuts), plans, columns if all(w == widths[0] for w in widths) else None)


class SensorFrame(Sequence[Readings]):
    """Every robot's readings of one step (what `World.read_all` gives): the step's own arrays of
    all robots, and robot i's `Readings` as `frame[i]`, views into them.

    The arrays are new each step, so readings kept stay as they were read. The per-robot
    `Readings` objects are built the first time any is asked for, all at once: code that works on
    the arrays (a benchmark, odometry of all robots from `tallies`) builds none; at a thousand
    robots they would cost as much as reading the sensors."""

    __slots__ = ("time", "_rows", "_layout", "_arrays", "_robots")

    def __init__(self, time: float, rows: dict[str, np.ndarray], layout: SensorLayout):
        """`rows`: the World's rows the frame's arrays are cut from (`sim.world.physics.World.sensor_rows`), each flat."""
        self.time = time
        """Simulated time of the reading (s)."""
        self._rows = rows
        self._layout = layout
        self._arrays: dict[str, np.ndarray] | None = None
        self._robots: list[Readings] | None = None

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """Each of the registry's `FRAMES` arrays, flat, robot after robot (`SensorLayout`)."""
        if self._arrays is None:
            self._arrays = {name: self._rows[row][cut] for name, row, cut in self._layout.cuts}
        return self._arrays

    @property
    def tallies(self) -> np.ndarray:
        """(n, 4) per robot: encoder ticks (left, right) then mouse counts (forward, left), what odometry takes."""
        return self.arrays["tallies"].reshape(len(self), -1)

    def robots(self) -> list[Readings]:
        """Every robot's `Readings` (built on the first call, the same list after it)."""
        if self._robots is None:
            now, layout, rows = self.time, self._layout, self._rows
            if layout.columns is None or len(self) < ROWS_FROM:  # a slice per robot and kind
                self._robots = [Readings(now, *[rows[row][cut] if row is not None else cut for row, cut in plan]) for plan in layout.plans]
            else:  # rows of each kind's array, one numpy call per kind
                n, arrays = len(self), self.arrays
                columns = [arrays[frame].reshape(n, -1)[:, cut] if frame is not None else [cut] * n for frame, cut in layout.columns]
                self._robots = [Readings(now, *row) for row in zip(*columns)]
        return self._robots

    def rows(self, field: str) -> np.ndarray:
        """Every robot's values of one framed kind (a `Readings` field) as rows (n, width), a view;
        for robots all alike (the copies of a Gymnasium environment)."""
        frame, cut = self._layout.columns[ARRAYS.index(field)] if self._layout.columns is not None else (None, None)
        if frame is None:
            raise ValueError(f"rows of {field!r} need robots all alike, each with it in a step's arrays")
        return self.arrays[frame].reshape(len(self), -1)[:, cut]

    def __len__(self) -> int:
        return len(self._layout.plans)

    def __getitem__(self, index: int | slice) -> Readings | list[Readings]:
        return self.robots()[index]

    def __iter__(self) -> Iterator[Readings]:
        return iter(self.robots())
