"""Sensor transfer functions: what a device outputs for what it senses, in its own units.

Geometry (ray casts, floor sampling) lives in `sim.world`; here are the curves: IR distance ->
raw value (c't-Sim's measured characteristic files or a built-in fit), the firmware's way back,
floor colour -> CNY70 value, light distance -> LDR darkness (ctsim-reference.md §2).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

CNY70_MAX = 1023
LDR_MAX = 1023


class CurveFileError(ValueError):
    """A characteristic file that cannot be read; the message names the file and line."""


@dataclass(frozen=True)
class IRCurve:
    """A distance sensor's characteristic: raw value at tabulated distances (m), interpolated
    linearly and rounded like c't-Sim's `Characteristic.lookupPrecise`. Beyond the last
    distance (nothing seen) the sensor reads the last value."""

    distance: np.ndarray
    raw: np.ndarray
    name: str = "curve"

    def lookup(self, distance: np.ndarray) -> np.ndarray:
        """Raw values (int) for distances (m); inf or beyond the table reads the last value."""
        d = np.asarray(distance, dtype=np.float64)
        return np.rint(np.interp(d, self.distance, self.raw)).astype(np.int64)

    def distance_from_raw(self, raw: np.ndarray, min_range: float = 0.1, max_range: float = 0.8) -> np.ndarray:
        """The firmware's inverse (c't-Bot `sensor_dist_lookup`): distance (m) from a raw value on
        the curve's falling branch within [min_range, max_range]; nan outside it."""
        return self.inverse(min_range, max_range)(raw)

    def inverse(self, min_range: float = 0.1, max_range: float = 0.8):
        """`distance_from_raw` for one range as a function, its table prepared once."""
        keep = (self.distance >= min_range) & (self.distance <= max_range)
        d, v = self.distance[keep][::-1], self.raw[keep][::-1].astype(np.float64)  # raw rises as d falls
        low, high = v.min() - 0.5, v.max() + 0.5  # a raw value rounded from a distance in range is in range

        def distance(raw: np.ndarray) -> np.ndarray:
            r = np.asarray(raw, dtype=np.float64)
            return np.where((r > high) | (r < low), np.nan, np.interp(r, v, d))

        return distance


def load_ir_curve(path: str | Path) -> IRCurve:
    """Read a c't-Sim characteristic file (`distance cm; value;` per line after a two-line header)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="latin-1").splitlines()
    except OSError as err:
        raise CurveFileError(f"{path}: {err.strerror or err}") from None
    distance, raw = [], []
    for number, line in enumerate(lines, start=1):
        fields = [f.strip() for f in line.split(";") if f.strip()]
        if not fields or not fields[0].replace(".", "", 1).isdigit():
            continue  # header or blank line
        try:
            distance.append(float(fields[0]) / 100)
            raw.append(float(fields[1]))
        except (IndexError, ValueError):
            raise CurveFileError(f"{path}:{number}: expected 'distance_cm; value;', got {line.strip()!r}") from None
    if len(distance) < 2 or np.any(np.diff(distance) <= 0):
        raise CurveFileError(f"{path}: needs at least two rows with increasing distances")
    return IRCurve(np.array(distance), np.array(raw), name=path.stem)


@lru_cache(maxsize=None)
def builtin_gp2d12(side: str) -> IRCurve:
    """The project's own model of the c't-Bot's Sharp GP2D12 sensors: raw = a/(d + b) + c fitted
    (max error 11 and 8 raw units) to the measured left and right curves between 0.1 and 0.8 m,
    with the sensor's fold-back below 0.1 m drawn as a straight line to the value at 0 m."""
    a, b, c, at_zero = {"left": (53.82, 0.0086, 40.48, 167), "right": (61.45, 0.0185, 0.36, 173)}[side]
    d = np.concatenate(([0.0], np.linspace(0.1, 0.85, 76)))
    raw = a / (d + b) + c
    raw[0] = at_zero
    return IRCurve(d, raw, name=f"gp2d12-{side}-builtin")


def cny70_value(colour: np.ndarray) -> np.ndarray:
    """CNY70 reflex sensor value for floor colours (..., 3) in 0..1: absorption 1 - mean(RGB)
    scaled to 0 (white) .. 1023 (black) and truncated, in c't-Sim's float32 arithmetic
    (`World.sensGroundReflectionCross`: normal floor #606060 -> 637, goal #66FF00 -> 545)."""
    rgb = np.asarray(colour, dtype=np.float32)
    absorption = np.float32(1.0) - (rgb[..., 0] + rgb[..., 1] + rgb[..., 2]) / np.float32(3.0)
    return np.floor(absorption * np.float32(CNY70_MAX)).astype(np.int64)


def ldr_value(distance: np.ndarray, reach: float = 1.0) -> np.ndarray:
    """LDR darkness for the distance (m) to the nearest visible lamp surface: linear, truncated,
    1023 at `reach` or with no light (inf), as c't-Sim's `World.sensLight`."""
    d = np.asarray(distance, dtype=np.float64)
    return np.floor(np.minimum(d / reach, 1.0) * LDR_MAX).astype(np.int64)
