"""IR distance sensors' characteristics: the raw value a sensor reads for a distance (c't-Sim's
measured tables, the c't-Bot's shipped in `curves/`) and the firmware's way back. A robot's own
description, so that both the world's sensors (`sim.world.sensors`) and a controller that reasons
about its raw values (`bots.behaviours.walls`) read the same curve.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np

from bots.schema import FileError, read_bytes
from sim.errors import UserError


class CurveFileError(UserError):
    """A characteristic file that cannot be read; the message names the file and line."""


@dataclass(frozen=True, eq=False)
class IRCurve:
    """A distance sensor's characteristic, read as c't-Sim's `Characteristic` reads it: the rows
    (distance m, raw value) fill a table per whole centimetre (linear in between, float32, rows at
    a fractional centimetre count at the centimetre below); a distance is looked up between its
    two neighbouring centimetres and rounded half up. Closer than the first row or farther than
    the last (nothing seen) the sensor reads `beyond`."""

    distance: np.ndarray
    raw: np.ndarray
    beyond: float
    name: str = "curve"
    per_cm: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "per_cm", _per_centimetre(self.distance, self.raw, self.beyond))

    def lookup(self, distance: np.ndarray) -> np.ndarray:
        """Raw values (int) for distances (m); inf, nan or outside the table read `beyond`."""
        cm = np.asarray(distance, dtype=np.float64) * 100
        table, beyond = self.per_cm, np.float32(self.beyond)
        last = len(table) - 1
        inside = (cm >= 0) & (cm <= last)
        cm = np.where(inside, cm, 0.0)
        index = np.floor(cm).astype(np.int64)
        data = table[index].astype(np.float64)
        slope = (table[np.minimum(index + 1, last)] - table[index]).astype(np.float64)  # a float32 difference, as in Java
        between = inside & (table[index] != beyond) & (index < last)
        data = np.where(between, data + (cm - index) * slope, data)
        return np.floor(np.where(inside, data, float(beyond)) + 0.5).astype(np.int64)

    def distance_from_raw(self, raw: np.ndarray, min_range: float = 0.1, max_range: float = 0.8) -> np.ndarray:
        """The firmware's inverse (c't-Bot `sensor_dist_lookup`): distance (m) from a raw value on
        the curve's branch within [min_range, max_range], falling (the GP2D12s: raw rises as the
        wall comes nearer) or rising (the VL53L0X: raw in mm); past the branch's near end (closer,
        or a GP2D12's fold-back peak below min_range) min_range, as the firmware assumes; past its
        far end nan (nothing in view), and nan for the value that nothing in view reads (`beyond`:
        c't-Sim's right GP2D12 reads 80 for nothing, which its table also reaches at 75-76 cm)."""
        return self.inverse(min_range, max_range)(raw)

    def inverse(self, min_range: float = 0.1, max_range: float = 0.8):
        """`distance_from_raw` for one range as a function, its table prepared once (CurveFileError
        where fewer than two rows lie in the range). Where the
        curve turns within the range (a GP2D12's fold-back peaks at 9 cm, its right table turns
        up past 80 cm) a raw value is two distances: the branch read is the longest stretch over
        which the raw values keep one direction (`_branch`)."""
        keep = (self.distance >= min_range) & (self.distance <= max_range)
        if keep.sum() < 2:
            raise CurveFileError(f"IR curve {self.name!r} has fewer than two rows between min_range {min_range:g} m and max_range {max_range:g} m: "
                                 "no distance can be read back from its raw values there")  # fmt: skip
        d, v = _branch(self.distance[keep], self.raw[keep].astype(np.float64))
        rising = bool(v[-1] > v[0])
        if not rising:
            d, v = d[::-1], v[::-1]  # (np.interp reads rising raw values)
        low, high = v.min() - 0.5, v.max() + 0.5  # a raw value rounded from a distance in range is in range
        nothing = np.floor(self.beyond + 0.5)

        def distance(raw: np.ndarray) -> np.ndarray:
            r = np.asarray(raw, dtype=np.float64)
            near, far = (r < low, r > high) if rising else (r > high, r < low)
            seen = np.where(far | (r == nothing), np.nan, np.interp(r, v, d))
            return np.where(near, min_range, seen)

        return distance

    def raw_range(self) -> tuple[int, int]:
        """The lowest and highest raw value `lookup` can give (it rounds between table values)."""
        values = np.append(self.per_cm, np.float32(self.beyond)).astype(np.float64)
        return int(np.floor(values.min() + 0.5)), int(np.floor(values.max() + 0.5))

    def inverse_table(self, min_range: float = 0.1, max_range: float = 0.8) -> np.ndarray:
        """`inverse(min_range, max_range)` of every raw value in `raw_range()`, lowest first: what a
        compiled lookup reads (`kernels.sensing.ir_values`) instead of interpolating each step."""
        low, high = self.raw_range()
        return self.inverse(min_range, max_range)(np.arange(low, high + 1))


def _branch(distance: np.ndarray, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the longest stretch of distance over which `raw` (two rows or more) only rises or
    only falls (the first of equal ones; a stretch has two rows or more)."""
    turns = np.flatnonzero(np.diff(np.sign(np.diff(raw)))) + 1  # the rows where the direction changes
    starts, ends = np.concatenate(([0], turns)), np.concatenate((turns, [len(raw) - 1]))
    k = int(np.argmax(distance[ends] - distance[starts]))
    return distance[starts[k] : ends[k] + 1], raw[starts[k] : ends[k] + 1]


def _per_centimetre(distance: np.ndarray, raw: np.ndarray, beyond: float) -> np.ndarray:
    """c't-Sim's lookup table: one float32 value per whole centimetre from 0 to the last row,
    `beyond` before the first row, each row's value at its centimetre and steps of
    (next - this) / gap centimetres up to the next row, summed in float32."""
    cm = np.floor(np.asarray(distance, dtype=np.float64) * 100 + 1e-9).astype(np.int64)  # rows are given in cm
    values = np.asarray(raw, dtype=np.float32)
    table = np.full(cm[-1] + 1, np.float32(beyond), dtype=np.float32)
    for k in range(len(cm)):
        table[cm[k]] = values[k]
        if k + 1 < len(cm):
            gap = cm[k + 1] - cm[k]
            delta = (values[k + 1] - values[k]) / np.float32(gap)
            steps = np.arange(1, gap, dtype=np.float32)
            table[cm[k] + 1 : cm[k + 1]] = values[k] + steps * delta
    return table


CTSIM_BEYOND = {"gp2d12Left": 100.0, "gp2d12Right": 80.0, "gp2y0a60Left": 100.0, "gp2y0a60Right": 100.0, "vl53l0xLeft": 2000.0, "vl53l0xRight": 2000.0}
"""What c't-Sim reads from each of its characteristic files when nothing is in the table
(the INF that `MasterSimulator.buisitDistanceSim` gives each file)."""


MAX_CURVE_CM = 1000.0
"""Farthest row of a characteristic file (cm): an IR sensor's range is at most 10 m (`IRSensorSpec.max_range`)."""
MAX_RAW = 1e6
"""Largest raw value of a characteristic file (c't-Sim's files: ADC counts up to 1023, millimetres up to 2000)."""


def load_ir_curve(path: str | Path, beyond: float | None = None) -> IRCurve:
    """Read a c't-Sim characteristic file (`distance cm; value;` per line after a two-line header).
    Nothing in view reads `beyond`: by default c't-Sim's value for its own files (`CTSIM_BEYOND`),
    the last row's value for any other file."""
    path = Path(path)
    try:
        lines = read_bytes(path).decode("latin-1").splitlines()
    except FileError as err:
        raise CurveFileError(str(err)) from None
    distance, raw = [], []
    for number, line in enumerate(lines, start=1):
        fields = [f.strip() for f in line.split(";") if f.strip()]
        if not fields or not fields[0].replace(".", "", 1).isdigit():
            continue  # header or blank line
        try:
            centimetres, value = float(fields[0]), float(fields[1])
        except (IndexError, ValueError):
            raise CurveFileError(f"{path}:{number}: expected 'distance_cm; value;', got {line.strip()[:80]!r}") from None
        if centimetres > MAX_CURVE_CM or not 0 <= value <= MAX_RAW:  # (a table per centimetre: 1e9 cm would be gigabytes)
            raise CurveFileError(f"{path}:{number}: a row needs a distance of at most {MAX_CURVE_CM:g} cm and a raw value from 0 to {MAX_RAW:g}, "
                                 f"got {line.strip()[:80]!r}")  # fmt: skip
        distance.append(centimetres / 100)
        raw.append(value)
    if len(distance) < 2 or np.any(np.diff(np.floor(np.array(distance) * 100 + 1e-9)) <= 0):
        raise CurveFileError(f"{path}: needs at least two rows with increasing whole-centimetre distances")
    if beyond is None:
        beyond = CTSIM_BEYOND.get(path.stem, raw[-1])
    return IRCurve(np.array(distance), np.array(raw), beyond, name=path.stem)


CURVES = Path(__file__).with_name("curves")
"""The project's shipped characteristic tables (`gp2d12.toml`: the c't-Bot's GP2D12 pair)."""


@cache
def gp2d12(side: str) -> IRCurve:
    """The c't-Bot's default IR characteristic for `side` ("left" or "right"): c't-Sim's measured
    GP2D12 tables, shipped with ctsim as `bots/curves/gp2d12.toml` (origin noted there)."""
    with (CURVES / "gp2d12.toml").open("rb") as file:
        entry = tomllib.load(file)[side]
    table = np.array(entry["table"], dtype=np.float64)
    return IRCurve(table[:, 0] / 100, table[:, 1], float(entry["beyond"]), name=f"gp2d12-{side}")


def shared_folder() -> Path:
    """Where c't-Sim's own data files are looked for: the folder `CTSIM_SHARED` names, else
    `../shared` beside the repository (its `ctsim/characteristics` and `ctsim/parcours`)."""
    named = os.environ.get("CTSIM_SHARED")
    return Path(named) if named else Path(__file__).resolve().parents[2] / "shared"


def find_shared_curves() -> Path | None:
    """c't-Sim's characteristics folder (`shared_folder()/ctsim/characteristics`), if it is there."""
    here = shared_folder() / "ctsim" / "characteristics"
    return here if here.is_dir() else None


def ir_curve_for(name: str | None, side: str) -> IRCurve:
    """The characteristic a sensor names: a file path, a file name in the shared c't-Sim folder,
    or (None) the c't-Bot's GP2D12 table for its side (`gp2d12`, shipped with ctsim)."""
    if name is None:
        return gp2d12(side)
    path = Path(name)
    if not path.is_file():
        shared = find_shared_curves()
        if shared is not None and (shared / name).is_file():
            path = shared / name
    return load_ir_curve(path)
