"""One step's sensor readings of one robot: the only view of the world a controller gets; and
every robot's readings of one step as the step's arrays (`SensorFrame`)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np


def _ints(n: int = 0) -> np.ndarray:
    return np.zeros(n, dtype=np.int64)


def _frozen(values: np.ndarray) -> np.ndarray:
    values.flags.writeable = False
    return values


def frozen_copy(array: np.ndarray) -> np.ndarray:
    """A copy of `array` over immutable bytes: no flag, view or `.base` of it can be made writeable
    (numpy refuses), so readings handed to a controller never reach the array they were copied
    from. (Cheaper than one bytes object for a step's three rows: memoryviews cost more than they save.)"""
    copy = np.frombuffer(array.tobytes(), array.dtype)
    return copy if array.ndim == 1 else copy.reshape(array.shape)


NO_STEERING = _frozen(np.zeros(0))
NO_MOUSE2 = _frozen(np.zeros(2, dtype=np.int64))
"""What a c't-Bot's readings hold for a chassis's steering angles and second mouse (shared, read-only)."""


@dataclass(slots=True)
class Readings:
    """Sensor values read at the start of a step, in the devices' own units.

    encoder_ticks: signed ticks counted during the previous step, (left, right).
    mouse_counts: signed counts during the previous step, (forward, left) in the sensor frame.
    ir_raw: raw IR sensor values (ADC units, as c't-Sim), one per IR sensor of the robot.
    ir_distance: distance the robot's firmware would infer from ir_raw (m); nan outside 0.1-0.8 m.
    line, border: CNY70 reflex sensors, 0 (white) .. 1023 (black or hole).
    light: light sensors, 0 (bright) .. 1023 (dark), c't-Sim's convention.

    (Slots: controllers read its fields often.)
    """

    time: float = 0.0
    encoder_ticks: np.ndarray = field(default_factory=lambda: _ints(2))
    mouse_counts: np.ndarray = field(default_factory=lambda: _ints(2))
    ir_raw: np.ndarray = field(default_factory=_ints)
    ir_distance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    line: np.ndarray = field(default_factory=_ints)
    border: np.ndarray = field(default_factory=_ints)
    light: np.ndarray = field(default_factory=_ints)
    steering: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mouse2_counts: np.ndarray = field(default_factory=lambda: _ints(2))
    failures: tuple = ()


ROWS_FROM = 16
"""Robots from which, all alike, readings are cut from a step's arrays by rows (one numpy call per
kind) rather than by a slice per robot and kind (cheaper for a few robots)."""


@dataclass(frozen=True)
class SensorLayout:
    """Where each robot's sensors lie in a step's arrays: robot after robot, the IR array holds its
    IR sensors, the floor array its line then its border sensors, the light array its light sensors."""

    slices: list[tuple[slice, slice, slice, slice]]
    """Per robot: its IR, line, border and light sensors."""
    counts: tuple[int, int, int, int] | None
    """IR, line, border and light sensors of every robot, when ROWS_FROM or more are all alike."""

    @classmethod
    def of(cls, counts: list[tuple[int, int, int, int]]) -> SensorLayout:
        """The layout of robots with these (IR, line, border, light) sensor counts, in order."""
        slices, ir, floor, light = [], 0, 0, 0
        for n_ir, n_line, n_border, n_light in counts:
            slices.append((slice(ir, ir + n_ir), slice(floor, floor + n_line), slice(floor + n_line, floor + n_line + n_border),
                           slice(light, light + n_light)))  # fmt: skip
            ir, floor, light = ir + n_ir, floor + n_line + n_border, light + n_light
        alike = len(counts) >= ROWS_FROM and all(c == counts[0] for c in counts)
        return cls(slices, counts[0] if alike else None)


class SensorFrame(Sequence[Readings]):
    """Every robot's readings of one step (what `World.read_all` gives): the step's own arrays of
    all robots, and robot i's `Readings` as `frame[i]`, views into them.

    The arrays are new each step, so readings kept stay as they were read. The per-robot
    `Readings` objects are built the first time any is asked for, all at once: code that works on
    the arrays (a benchmark, odometry of all robots from `tallies`) builds none; at a thousand
    robots they would cost as much as reading the sensors."""

    __slots__ = ("time", "tallies", "ir_raw", "ir_distance", "floor", "light", "_layout", "_robots")

    def __init__(self, time: float, tallies: np.ndarray, ir_raw: np.ndarray, ir_distance: np.ndarray, floor: np.ndarray,
                 light: np.ndarray, layout: SensorLayout):  # fmt: skip
        self.time = time
        """Simulated time of the reading (s)."""
        self.tallies = tallies
        """(n, 4) per robot: encoder ticks (left, right) then mouse counts (forward, left)."""
        self.ir_raw, self.ir_distance, self.floor, self.light = ir_raw, ir_distance, floor, light
        """Every robot's IR sensors (raw, believed distance m), floor sensors (its line then its
        border sensors) and light sensors, robot after robot (`SensorLayout`)."""
        self._layout = layout
        self._robots: list[Readings] | None = None

    def robots(self) -> list[Readings]:
        """Every robot's `Readings` (built on the first call, the same list after it)."""
        if self._robots is None:
            now, ir_raw, ir_distance, floor, light, layout = self.time, self.ir_raw, self.ir_distance, self.floor, self.light, self._layout
            ticks, mice = self.tallies[:, :2], self.tallies[:, 2:]
            if len(layout.slices) == 1:  # one robot: every IR and light array is its own
                _, line, border, _ = layout.slices[0]
                tally = self.tallies[0]
                self._robots = [Readings(now, tally[:2], tally[2:], ir_raw, ir_distance, floor[line], floor[border], light, NO_STEERING, NO_MOUSE2)]
            elif layout.counts is None:  # a slice per robot and kind
                self._robots = [
                    Readings(now, tick, mouse, ir_raw[r], ir_distance[r], floor[f], floor[b], light[li], NO_STEERING, NO_MOUSE2)
                    for (r, f, b, li), tick, mouse in zip(layout.slices, ticks, mice)
                ]
            else:  # rows of each kind's array, one numpy call per kind
                n = len(layout.slices)
                n_ir, n_line, n_border, n_light = layout.counts
                floors = floor.reshape(n, n_line + n_border)
                rows = zip(ticks, mice, ir_raw.reshape(n, n_ir), ir_distance.reshape(n, n_ir), floors[:, :n_line], floors[:, n_line:], light.reshape(n, n_light))
                self._robots = [Readings(now, *row, NO_STEERING, NO_MOUSE2) for row in rows]
        return self._robots

    def __len__(self) -> int:
        return len(self.tallies)

    def __getitem__(self, index: int | slice) -> Readings | list[Readings]:
        return self.robots()[index]

    def __iter__(self) -> Iterator[Readings]:
        return iter(self.robots())
