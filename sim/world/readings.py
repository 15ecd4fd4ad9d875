"""One step's sensor readings of one robot: the only view of the world a controller gets."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def _ints(n: int = 0) -> np.ndarray:
    return np.zeros(n, dtype=np.int64)


@dataclass(slots=True)
class Readings:
    """Sensor values read at the start of a step, in the devices' own units.

    encoder_ticks: signed ticks counted during the previous step, (left, right).
    mouse_counts: signed counts during the previous step, (forward, left) in the sensor frame.
    ir_raw: raw IR sensor values (ADC units, as c't-Sim), one per IR sensor of the robot.
    ir_distance: distance the robot's firmware would infer from ir_raw (m); nan outside 0.1-0.8 m.
    line, border: CNY70 reflex sensors, 0 (white) .. 1023 (black or hole).
    light: light sensors, 0 (bright) .. 1023 (dark), c't-Sim's convention.

    (Slots: the world builds one per robot and step, and controllers read its fields often.)
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
