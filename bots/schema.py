"""Declared schemas of the files a user gives ctsim, and a TOML reader that cannot be made to hang.

Each file kind declares each of its keys once, as a `Field`: its type, its unit and the range it
must lie in. Robot descriptions declare theirs on their dataclasses (`declared`, `bots/spec.py`),
world files and sweep specs in tables of Fields beside their readers. A value that breaks its
Field is a `Problem`; a reader turns it into a `FileError`, one line `file:line: key: problem`,
the line found by `Locator`. `read_toml` bounds a file's size and nesting depth.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, fields
from dataclasses import field as dataclass_field
from pathlib import Path
from typing import Any

from sim.errors import UserError

MAX_BYTES = 16 * 2**20
"""Largest file ctsim reads (bytes): the largest c't-Sim parcours is 4 KB, a hand-written world
or robot a few KB; a file beyond this is a mistake, not a world."""
MAX_DEPTH = 16
"""Deepest nesting of tables and lists in a file: ctsim's deepest is 4 (a robot's chassis wheels)."""
WORLD_EXTENT = 1e4
"""Largest coordinate (m) anywhere in a world or on a robot: ±10 km."""
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
            except Problem:
                self._fail(value)  # (naming the whole list)
        if kind == "points":
            if not isinstance(value, (list, tuple)) or len(value) < self.minimum or not all(isinstance(p, (list, tuple)) and len(p) == 2 for p in value):
                self._fail(value)
            try:
                return tuple((self._number(p[0]), self._number(p[1])) for p in value)
            except Problem:
                self._fail(value)
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
        if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
            self._fail(value)
        if math.isinf(value) and not (self.infinite and value > 0):
            self._fail(value)
        if not self._in_range(value):
            self._fail(value)
        return float(value)

    def _in_range(self, value: float) -> bool:
        return (value > self.low if self.above else value >= self.low) and value <= self.high

    def _fail(self, value: Any) -> None:
        raise Problem("", f"must be {self.describe()}, not {shown(value)}")


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
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


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


def read_text(path: Path, error: type[FileError] = FileError) -> str:
    """A file's text: at most MAX_BYTES, UTF-8 (a bad byte is named with its line)."""
    try:
        size = path.stat().st_size
        if size > MAX_BYTES:
            raise error(path, None, f"the file has {size:,} bytes, more than the {MAX_BYTES:,} a ctsim file may have")
        data = path.read_bytes()
    except OSError as err:
        raise error(path, None, f"cannot read: {err.strerror or err}") from None
    try:
        return data.decode("utf-8")
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
