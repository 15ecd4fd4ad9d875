"""Declared schemas of the files a user gives ctsim, and a TOML reader that cannot be made to hang.

Each file kind declares each of its keys once, as a `Field`: its type, its unit and the range it
must lie in. Robot descriptions declare theirs on their dataclasses (`declared`, `bots/spec.py`),
world files and sweep specs in tables of Fields beside their readers. A value that breaks its
Field is a `Problem`; a reader turns it into a `FileError`, one line `file:line: key: problem`,
the line found by `Locator`. `read_toml` bounds a file's size and nesting depth.
"""

from __future__ import annotations

import math
import os
import re
import stat
import sys
import tomllib
from dataclasses import dataclass, fields
from dataclasses import field as dataclass_field
from pathlib import Path
from typing import Any, BinaryIO

from sim.errors import UserError

MAX_BYTES = 4 * 2**20
"""Largest file ctsim reads (bytes, 4 MiB): the largest c't-Sim parcours is 4 KB, a hand-written
world or robot a few KB, a 500 x 500 grid 260 KB. TOML is read in pure Python at about 1 MB/s:
16 MiB of 600,000 walls took 15 s to parse, 4 MiB takes a few."""
MAX_DEPTH = 16
"""Deepest nesting of tables and lists in a file: ctsim's deepest is 4 (a robot's chassis wheels)."""
WORLD_EXTENT = 1e4
"""Largest coordinate (m) anywhere in a world or on a robot: ±10 km."""
MIN_LENGTH = 1e-3
"""Smallest size (m) of a body, wheel, wall, line or grid cell: 1 mm. The contact solver's slop is
0.5 mm, and ever smaller bodies end in NaN poses (a robot of 1e-307 kg did)."""
MIN_MASS = 1e-3
"""Smallest mass (kg) of a robot or a movable object: 1 g (a c't-Bot is 0.5 kg, c't-Sim's can 50 g)."""
MAX_DIGITS = 40
"""Most digits a whole number written in a file or an option may have: ctsim's largest are seeds
(20 digits); Python would refuse 4,300 and more with advice meant for programmers."""
TINY = sys.float_info.min
"""Smallest magnitude of a non-zero number (2.2e-308): below it floats are subnormal, lose their
precision and turn to 0 in the first product, so a value there is refused."""


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
"""The default of a Field that must be given."""
KINDS = ("number", "integer", "boolean", "text", "pair", "box", "points", "colour", "table", "tables", "texts")


class FileError(UserError):
    """A user mistake in a file; `str()` reads `file:line: problem` (the problem starts with the key)."""

    def __init__(self, path: str | Path | None, line: int | None, problem: str):
        self.path = str(path) if path is not None else "<file>"
        self.line = line
        self.problem = problem
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")


class Problem(ValueError):
    """A value that breaks its Field: `key` (dotted, '' for the value itself) and what is wrong."""

    def __init__(self, key: str, message: str):
        self.key, self.message = key, message
        super().__init__(f"{key}: {message}" if key else message)

    def within(self, key: str) -> Problem:
        """The same problem one level up (`motor` + `max_wheel_speed`)."""
        return Problem(f"{key}.{self.key}" if self.key else key, self.message)


@dataclass(frozen=True)
class Field:
    """One key of a file: its kind (`KINDS`), unit, range [low, high] (low excluded with `above`,
    infinity allowed as "no limit" with `infinite`), allowed `choices`, whether None is allowed
    (`optional`), the fewest `points`, and its default (REQUIRED: must be given). A range applies
    to each number of a pair, box or point list."""

    kind: str
    unit: str = ""
    low: float = -math.inf
    high: float = math.inf
    above: bool = False
    infinite: bool = False
    choices: tuple = ()
    optional: bool = False
    minimum: int = 0
    default: Any = REQUIRED

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise TypeError(f"unknown field kind {self.kind!r}")

    def describe(self) -> str:
        """What a value must be, in words: `a number (m) greater than 0 and at most 2`."""
        what = {"number": "a number", "integer": "a whole number", "boolean": "true or false", "text": "a string",
                "pair": "a list of 2 numbers", "box": "[xmin, ymin, xmax, ymax]", "colour": 'a colour like "#a0b0c0"',
                "points": f"a list of at least {self.minimum} [x, y] points", "table": "a table",
                "tables": "a list of tables", "texts": "a list of strings"}[self.kind]
        if self.choices:
            return f"one of {', '.join(map(repr, self.choices))}" if self.kind != "texts" else f"a list of {', '.join(map(repr, self.choices))}"
        bounds = []
        if self.low > -math.inf:
            bounds.append(f"{'greater than' if self.above else 'at least'} {_figure(self.low)}")
        if self.high < math.inf:
            bounds.append(f"at most {_figure(self.high)}")
        unit = f" ({self.unit})" if self.unit and self.kind in ("number", "integer", "pair", "box", "points") else ""
        return what + unit + (f" {' and '.join(bounds)}" if bounds else "") + (" (inf: no limit)" if self.infinite else "")

    def check(self, value: Any) -> Any:
        """The value as ctsim keeps it (ints as floats, lists as tuples), or Problem('', why)."""
        if value is None and self.optional:
            return None
        kind = self.kind
        if kind == "number":
            return self._number(value)
        if kind == "integer":
            if isinstance(value, bool) or not isinstance(value, int) or not self._in_range(value):
                self._fail(value)
            return value
        if kind == "boolean":
            if not isinstance(value, bool):
                self._fail(value)
            return value
        if kind == "text":
            if not isinstance(value, str) or (self.choices and value not in self.choices):
                self._fail(value)
            return value
        if kind in ("pair", "box"):
            count = 2 if kind == "pair" else 4
            if not isinstance(value, (list, tuple)) or len(value) != count:
                self._fail(value)
            try:
                return tuple(self._number(v) for v in value)
            except Problem as inner:
                self._fail(value, _why(inner))  # (naming the whole list)
        if kind == "points":
            if not isinstance(value, (list, tuple)) or len(value) < self.minimum or not all(isinstance(p, (list, tuple)) and len(p) == 2 for p in value):
                self._fail(value)
            try:
                return tuple((self._number(p[0]), self._number(p[1])) for p in value)
            except Problem as inner:
                self._fail(value, _why(inner))
        if kind == "colour":
            parsed = parse_colour(value) if isinstance(value, str) else None
            if parsed is None:
                self._fail(value)
            return parsed
        if kind == "table":
            if not isinstance(value, dict):
                self._fail(value)
            return value
        if kind == "tables":
            if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
                self._fail(value)
            return value
        if not isinstance(value, list) or not all(isinstance(v, str) and (not self.choices or v in self.choices) for v in value):
            self._fail(value)  # texts
        return tuple(value)

    def _number(self, value: Any) -> float:
        """A finite (or, with `infinite`, +inf) float in range; ints of any size are compared
        exactly before they become floats, -0.0 becomes 0.0, and subnormals are refused."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (isinstance(value, float) and math.isnan(value)):
            self._fail(value)
        if isinstance(value, float) and math.isinf(value) and not (self.infinite and value > 0):
            self._fail(value)
        if not self._in_range(value):
            self._fail(value)
        if value != 0 and abs(value) < TINY:
            self._fail(value, SUBNORMAL)
        return float(value) + 0.0  # (-0.0 as 0.0)

    def _in_range(self, value: float) -> bool:
        return (value > self.low if self.above else value >= self.low) and value <= self.high

    def _fail(self, value: Any, why: str = "") -> None:
        raise Problem("", f"must be {self.describe()}, not {shown(value)}" + (f": {why}" if why else ""))


SUBNORMAL = "a subnormal number, too small to compute with"


def _why(problem: Problem) -> str:
    """The reason a Problem gives after its value (`SUBNORMAL`), '' for none."""
    return SUBNORMAL if problem.message.endswith(SUBNORMAL) else ""


def _figure(value: float) -> str:
    """A limit as a person writes it: 1,000,000 rather than 1e+06."""
    return f"{value:,.0f}" if value == int(value) and abs(value) < 1e12 else f"{value:g}"


def shown(value: Any) -> str:
    """A value as a message shows it: short, and saying its kind where the value says little."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, (list, tuple)):
        text = repr(list(value))
        return text if len(text) <= 40 else f"a list of {len(value)}"
    if isinstance(value, int) and value.bit_length() > 3 * MAX_DIGITS:
        return f"a whole number of about {_digit_count(value):,} digits"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _digit_count(value: int) -> int:
    """Decimal digits of a whole number of any size, without turning it into text."""
    size = abs(value)
    digits = max(1, math.floor((size.bit_length() - 1) * math.log10(2)) + 1)
    return digits + (size >= 10**digits)


def parse_number(text: str, kind: type = float) -> float | int:
    """An option's text as a finite number of `kind` (float or int): ValueError saying why, in
    words, for text that is none, infinite or NaN, or a whole number of more than MAX_DIGITS digits."""
    body = text.strip().replace("_", "")
    digits = len(re.sub(r"[^0-9]", "", body.partition("e")[0].partition("E")[0]))
    if digits > MAX_DIGITS:
        raise ValueError(f"expected a number, got one of {digits:,} digits (at most {MAX_DIGITS})")
    try:
        value = kind(body)
    except ValueError:
        what = "a whole number" if kind is int else "a number"
        raise ValueError(f"expected {what}, got {shown(text)}") from None
    if kind is float and not math.isfinite(value):
        raise ValueError(f"expected a finite number, got {shown(text)}")
    return value


def option(field: Field, kind: type = float) -> Any:
    """An argparse `type` checking an option's value against `field`: argparse names the option
    with the reason (`argument --step-timeout: must be a number (s) greater than 0 and at most
    86,400, not 1e+308`)."""
    import argparse

    def parse(text: str) -> Any:
        try:
            number = parse_number(text, kind)
            return field.check(number)
        except Problem as problem:
            raise argparse.ArgumentTypeError(problem.message) from None
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None

    return parse


def file_stem(name: str, limit: int = 100) -> str:
    """A robot's (or an estimate's) name as the start of a file name inside a run folder: its
    runs of letters, digits, '.', '-' and '_', joined by '_' (no '/', no '..', nothing hidden);
    '' when nothing is left (such a name is refused where it is given)."""
    parts = [part for part in re.split(r"[^\w.-]+", name) if part.strip(".")]
    return "_".join(parts).lstrip(".")[:limit]


def parse_colour(text: str) -> tuple[float, float, float] | None:
    """`#rrggbb` as RGB in 0..1; None if malformed."""
    t = text.strip()
    if len(t) != 7 or t[0] != "#" or any(c not in "0123456789abcdefABCDEF" for c in t[1:]):
        return None
    return tuple(int(t[i : i + 2], 16) / 255 for i in (1, 3, 5))  # type: ignore[return-value]


# --- dataclasses whose fields are declared --------------------------------------------------------


def declared(kind: str = "number", default: Any = REQUIRED, **schema: Any) -> Any:
    """A dataclass field with its Field in the metadata: `mass: float = declared(default=0.5, unit="kg", low=0.0, above=True)`."""
    spec = Field(kind, default=default, **schema)
    if default is REQUIRED:
        return dataclass_field(metadata={"schema": spec})
    return dataclass_field(default=default, metadata={"schema": spec})


def check_fields(instance: Any) -> None:
    """Check every declared field of a (frozen) dataclass instance against its Field, storing the
    converted value; Problem naming the field."""
    for f in fields(instance):
        spec = f.metadata.get("schema")
        if spec is None:
            continue
        try:
            object.__setattr__(instance, f.name, spec.check(getattr(instance, f.name)))
        except Problem as problem:
            raise Problem(f.name, problem.message) from None


def schema_of(cls: type) -> dict[str, Field]:
    """The declared Fields of a dataclass, by name."""
    return {f.name: f.metadata["schema"] for f in fields(cls) if "schema" in f.metadata}


# --- reading --------------------------------------------------------------------------------------


class Locator:
    """Line numbers of table headers and keys, found by scanning the TOML text (tomllib reports
    line numbers for syntax errors only)."""

    _ARRAY = re.compile(r"^\s*\[\[\s*([^\[\]#]+?)\s*\]\]")
    _TABLE = re.compile(r"^\s*\[\s*([^\[\]#]+?)\s*\]")

    def __init__(self, text: str):
        self.lines = text.splitlines()
        # (table name, index among same-named arrays or None) -> (header line, last line), 1-based
        self.sections: dict[tuple[str | None, int | None], tuple[int, int]] = {}
        counts: dict[str, int] = {}
        current: tuple[str | None, int | None] = (None, None)
        start = 1
        in_string = None
        for number, line in enumerate(self.lines, 1):
            if in_string is None:
                header = self._ARRAY.match(line) or self._TABLE.match(line)
                if header:
                    self.sections[current] = (start, number - 1)
                    name = header.group(1).replace(" ", "").replace('"', "")
                    if header.re is self._ARRAY:
                        current = (name, counts.get(name, 0))
                        counts[name] = current[1] + 1
                    else:
                        current = (name, None)
                    start = number
            for quote in ('"""', "'''"):
                if line.count(quote) % 2 and in_string in (None, quote):
                    in_string = None if in_string else quote
        self.sections[current] = (start, len(self.lines))

    def line(self, table: str | None, index: int | None, key: str | None = None) -> int | None:
        """The line of `key` in the table (the header when no key, or when the key is not found)."""
        span = self.sections.get((table, index))
        if span is None:
            return None
        first, last = span
        if key is not None:
            pattern = re.compile(rf"^\s*[\"']?{re.escape(key)}[\"']?\s*=")
            for number in range(first, last + 1):
                if pattern.match(self.lines[number - 1]):
                    return number
            # not a key = value line: maybe a [key] or [[key]] table of its own
            name = key if table is None else f"{table}.{key}"
            sub = self.sections.get((name, 0)) or self.sections.get((name, None))
            if sub is not None:
                return sub[0]
        return first if table is not None else None


def open_regular(path: Path, error: type[FileError] = FileError, most: int = MAX_BYTES) -> BinaryIO:
    """A regular file of at most `most` bytes opened for reading: a FIFO, device or folder is
    refused at once (opened without blocking, checked before reading), as is a larger file."""
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as err:
        raise error(path, None, f"cannot read: {err.strerror or err}") from None
    info = os.fstat(descriptor)
    if not stat.S_ISREG(info.st_mode):
        os.close(descriptor)
        raise error(path, None, f"not a regular file ({_file_kind(info.st_mode)}); give a file ctsim can read to its end")
    if info.st_size > most:
        os.close(descriptor)
        raise error(path, None, f"the file has {info.st_size:,} bytes, more than the {most:,} ctsim reads of it")
    return os.fdopen(descriptor, "rb")


def read_bytes(path: Path, error: type[FileError] = FileError, most: int = MAX_BYTES) -> bytes:
    """A regular file's bytes, at most `most` (`open_regular`): read as long as the file is and
    a byte more (Python allocates what it is asked to read: `most` would take 64 MiB of memory
    to read a summary of a few kB), then on to `most` only where it grew meanwhile."""
    with open_regular(path, error, most) as file:
        try:
            size = os.fstat(file.fileno()).st_size
            data = file.read(size + 1)
            if len(data) > size:  # (it grew, or it is a /proc file, which says 0)
                data += file.read(most + 1 - len(data))
        except OSError as err:
            raise error(path, None, f"cannot read: {err.strerror or err}") from None
    if len(data) > most:  # (grew while read)
        raise error(path, None, f"the file has more than the {most:,} bytes ctsim reads of it")
    return data


def _file_kind(mode: int) -> str:
    kinds = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a named pipe"), (stat.S_ISCHR, "a character device"),
             (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    return next((name for test, name in kinds if test(mode)), "not a regular file")


BOM = "\ufeff"
"""The UTF-8 byte-order mark some Windows editors put first: accepted and dropped."""


def read_text(path: Path, error: type[FileError] = FileError) -> str:
    """A file's text (`read_bytes`): UTF-8 (a bad byte is named with its line), a leading
    byte-order mark dropped."""
    data = read_bytes(path, error)
    try:
        return data.decode("utf-8").removeprefix(BOM)
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1
        raise error(path, line, f"not UTF-8 text: byte 0x{data[err.start]:02x}; save the file as UTF-8") from None


def read_toml(path: Path, error: type[FileError] = FileError) -> tuple[dict, Locator]:
    """A TOML file's data and where its keys are; `error(path, line, problem)` for a file that
    cannot be read or parsed, or nests deeper than MAX_DEPTH."""
    text = read_text(path, error)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        found = re.search(r"\(at line (\d+), column \d+\)", str(e))
        line = int(found.group(1)) if found else len(text.splitlines()) if "end of document" in str(e) else None
        problem = re.sub(r"\s*\(at (line \d+, column \d+|end of document)\)", "", str(e)) or "TOML syntax error"
        raise error(path, line, f"TOML syntax: {problem}") from None
    except RecursionError:
        raise error(path, None, f"lists or tables nested deeper than {MAX_DEPTH} levels") from None
    except ValueError:  # (tomllib's int() of a number past Python's digit limit)
        found = re.search(rf"[0-9_]{{{MAX_DIGITS + 1},}}", text)
        line = text[: found.start()].count("\n") + 1 if found else None
        raise error(path, line, f"a whole number of {len(found.group()) if found else 'thousands of'} digits; "
                                f"ctsim's numbers have at most {MAX_DIGITS}") from None
    if _depth(data) > MAX_DEPTH:
        raise error(path, None, f"lists or tables nested deeper than {MAX_DEPTH} levels")
    return data, Locator(text)


def _depth(value: Any) -> int:
    """How deep lists and tables nest in `value` (without recursion)."""
    deepest, todo = 0, [(value, 0)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, dict):
            item = list(item.values())
        if isinstance(item, list):
            deepest = max(deepest, depth + 1)
            if deepest > MAX_DEPTH:
                return deepest
            todo += [(v, depth + 1) for v in item]
    return deepest
