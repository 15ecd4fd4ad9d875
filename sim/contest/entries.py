"""Contest entries: what the command line names, as plain data, and the robot each becomes in a game.

An entry is `[NAME=]SOURCE[,KEY=VALUE...]`:

- a registered controller (`solve_maze`) or a Python file (`wanderer.py`, `wanderer.py:Wanderer`),
  with parameters: the teacher's own code, run in the game's process;
- `firmware:PATH`: a c't-Bot firmware's PC build (or a Python script that speaks its protocol),
  driven through the bridge; parameters `rc5=T:KEY` and `call=T:NAME(ARGS)` as `ctsim bridge`'s;
- a folder of student submissions (every *.py in it, or `<student>/controller.py`): one entry
  each, named after the student, run in the sandbox of `ctsim lab grade` (`sim.sandbox.controller`,
  `sim.sandbox`).

Names are unique and safe in file names and recordings (letters, digits, `_ . -`).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import zlib
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

from bots.controller import ControllerError, make
from bots.spec import RobotSpec
from sim import sanitize
from sim.errors import UserError
from sim.run.loop import RobotSetup
from sim.world.spec import Start

KINDS = ("controller", "file", "firmware", "student")
FIRMWARE = "firmware:"
FIRMWARE_PORT = 10001
"""The port the c't-Bot firmware connects to (fixed in its tcp.h): games in parallel each listen on
an address of their own in 127.0.0.0/8 and start the firmware with `-t ADDRESS`."""
CONNECT_TIMEOUT, STEP_TIMEOUT = 30.0, 10.0
"""Seconds for a firmware to connect, and to answer a step (c't-Sim's), before it fails its game."""
STUDENT_FILE = "controller.py"
"""The file of a submission in a sub-folder `<student>/controller.py`."""
NAME = re.compile(r"[A-Za-z0-9_.-]+")


class EntryError(UserError):
    """A user mistake in naming an entry (message for the command line)."""


@dataclass(frozen=True)
class Entry:
    """One contestant: `name`, `kind` (KINDS), `source` (a registered name, or an absolute path,
    `file.py:Class` for a file's class) and its parameters as text."""

    name: str
    kind: str
    source: str
    params: tuple[tuple[str, str], ...] = ()

    @property
    def label(self) -> str:
        """What it is, for tables: `solve_maze (hand=left)`."""
        params = ", ".join(f"{k}={v}" for k, v in self.params)
        source = Path(self.source).name if self.kind != "controller" else self.source  # file.py:Class, not its folder
        return f"{source} ({params})" if params else source


def parse(texts: list[str]) -> list[Entry]:
    """The entries the command line names, in its order (a folder's submissions in name order)."""
    given: list[tuple[Entry, bool]] = []  # (entry, named by the user)
    for text in texts:
        given += [(entry, "=" in text.split(",")[0] and not Path(text).is_dir()) for entry in _parse_one(text)]
    chosen = [entry.name for entry, named in given if named]
    clash = sorted({n for n in chosen if chosen.count(n) > 1})
    if clash:
        raise EntryError(f"two entries are called {clash[0]!r}: give each its own NAME=")
    taken = set(chosen)
    named = []
    for entry, explicit in given:  # a default name already taken gets -2, -3, ...
        name, count = entry.name, 1
        while not explicit and name in taken:
            count += 1
            name = f"{entry.name}-{count}"
        taken.add(name)
        named.append(entry if name == entry.name else Entry(name, entry.kind, entry.source, entry.params))
    return named


def _parse_one(text: str) -> list[Entry]:
    head, *rest = text.split(",")
    params = []
    for part in rest:
        key, sep, value = part.partition("=")
        if not sep or not key.strip():
            raise EntryError(f"entry {text!r}: expected KEY=VALUE after a comma, got {part!r}")
        params.append((key.strip(), value.strip()))
    name, sep, source = head.partition("=")
    if not sep:
        name, source = "", head
    name, source = name.strip(), source.strip()
    if name and not NAME.fullmatch(name):
        raise EntryError(f"entry {text!r}: a name takes letters, digits, '_', '.' and '-' only, not {name!r}")
    if not source:
        raise EntryError(f"entry {text!r}: names no controller, file, firmware or folder")
    if source.startswith(FIRMWARE):
        return [_firmware(name, source.removeprefix(FIRMWARE), tuple(params), text)]
    if Path(source).is_dir():
        if params:
            raise EntryError(f"entry {text!r}: the submissions of a folder take no parameters")
        return _students(Path(source), name)
    if source.endswith(".py") or ".py:" in source:
        path, _, cls = source.partition(".py")
        path = Path(path + ".py")
        if not path.is_file():
            raise EntryError(f"entry {text!r}: {path}: no such controller file")
        make(f"{path.resolve()}{cls}", dict(params))  # loads it: a mistake shows now, not in a game
        return [Entry(name or _safe(path.stem), "file", f"{path.resolve()}{cls}", tuple(params))]
    import bots.behaviours  # noqa: F401  (registers the shipped controllers)

    try:
        make(source, dict(params))
    except ControllerError as err:
        raise EntryError(f"entry {text!r}: {err}") from None
    return [Entry(name or _safe(source), "controller", source, tuple(params))]


def _firmware(name: str, path: str, params: tuple[tuple[str, str], ...], text: str) -> Entry:
    from sim.bridge.protocol import parse_call, rc5_code
    from sim.bridge.usage import timed

    binary = Path(path)
    if not binary.is_file():
        raise EntryError(f"entry {text!r}: {binary}: no such firmware file")
    if binary.suffix != ".py" and not os.access(binary, os.X_OK):
        raise EntryError(f"entry {text!r}: {binary}: not executable (chmod +x, or the firmware's PC build)")
    for key, value in params:
        if key not in ("rc5", "call"):
            raise EntryError(f"entry {text!r}: a firmware takes rc5=T:KEY and call=T:NAME(ARGS), not {key!r}")
        try:
            timed(value, rc5_code if key == "rc5" else parse_call)
        except ValueError as err:
            raise EntryError(f"entry {text!r}: {key}: {err}") from None
    return Entry(name or _safe(binary.stem), "firmware", str(binary.resolve()), params)


def _students(folder: Path, prefix: str) -> list[Entry]:
    from sim.lab.grading import refusal, student_id, submissions
    from sim.sandbox.controller import check_available

    check_available()
    folder = folder.resolve()
    files = []
    for file in submissions(folder, STUDENT_FILE):
        refused = refusal(file, folder, file.parent != folder)
        if refused is None:
            files.append(file)
        else:  # (a link, a pipe, a student without the file: said, never entered)
            print(f"ctsim contest: not entered: {sanitize.name(str(file))}: {refused[1]}", file=sys.stderr)
    if not files:
        raise EntryError(f"{folder}: no submissions (*.py files, or */{STUDENT_FILE})")
    return [Entry(_safe(f"{prefix}.{student_id(f, folder)}" if prefix else student_id(f, folder)), "student", str(f.resolve())) for f in files]


def _safe(text: str) -> str:
    return "_".join(NAME.findall(text)) or "entry"


def robot_spec(entry: Entry, base: RobotSpec) -> RobotSpec:
    """The robot an entry drives: `base` named after the entry (its name in the recording)."""
    return base.with_changes(name=entry.name)


class Seat:
    """An entry made into a robot of one game, with what it needs around the run (a firmware's
    process and bridge, a sandboxed process) and their clean-up. Use as a context manager:
    everything it started is gone when the block ends."""

    def __init__(self, entry: Entry, spec: RobotSpec, start: Start, dt: float, game: str):
        self.entry, self.spec, self.start, self.dt, self.game = entry, spec, start, dt, game
        self.observers: list = []
        self._stack = ExitStack()

    def __enter__(self) -> Seat:
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.close()

    def setup(self, recorder=None) -> RobotSetup:  # noqa: ANN001 (a Recorder or None)
        """The robot for the run loop (its observers, a firmware's, in `observers`)."""
        entry = self.entry
        if entry.kind in ("controller", "file"):
            controller = make(entry.source, dict(entry.params))
        elif entry.kind == "firmware":
            controller = self._firmware(recorder)
        else:
            from sim.sandbox.controller import sandboxed_controller

            controller = self._stack.enter_context(sandboxed_controller(Path(entry.source)))
        return RobotSetup(self.spec, controller, entry.label, dict(entry.params), self.start, estimators=[], name=entry.name)

    def _firmware(self, recorder):  # noqa: ANN001, ANN202
        from sim.bridge.protocol import parse_call, rc5_code
        from sim.bridge.usage import timed

        bridge = self._stack.enter_context(_listen(self.game, self.entry.name, self.dt))
        rc5 = [timed(v, rc5_code) for k, v in self.entry.params if k == "rc5"]
        calls = [(at, f"{name}({', '.join(map(str, args))})") for at, (name, args) in (timed(v, parse_call) for k, v in self.entry.params if k == "call")]
        controller = bridge.controller(rc5, calls)
        self.observers.append(bridge.observer(recorder))
        folder = Path(self._stack.enter_context(tempfile.TemporaryDirectory(prefix="ctsim-firmware-")))
        binary = self.entry.source
        command = [sys.executable, binary] if binary.endswith(".py") else [binary]
        log = self._stack.enter_context((folder / "firmware.log").open("wb"))
        process = subprocess.Popen([*command, "-t", bridge.listener.host], cwd=folder, stdin=subprocess.PIPE, stdout=log, stderr=subprocess.STDOUT)  # stdin kept open: see sim.bridge.usage
        self._stack.callback(_stop, process)
        self._stack.callback(bridge.close)  # (first) SHUTDOWN, on which the firmware exits
        return controller


def _listen(game: str, name: str, dt: float):  # noqa: ANN202 (a Bridge)
    """A bridge listening on FIRMWARE_PORT at a loopback address of this game's own (tried in turn
    from one derived from the game and entry, in case another process holds one)."""
    from sim.bridge import Bridge

    seed = zlib.crc32(f"{game}/{name}".encode())
    for attempt in range(64):
        code = (seed + 7919 * attempt) % (254 * 254 * 254)
        host = f"127.{1 + code // (254 * 254)}.{1 + code // 254 % 254}.{1 + code % 254}"
        try:
            return Bridge(host, FIRMWARE_PORT, CONNECT_TIMEOUT, STEP_TIMEOUT, dt=dt)
        except OSError:
            continue
    raise OSError(f"no free loopback address for a firmware's port {FIRMWARE_PORT}")


def _stop(process: subprocess.Popen) -> None:
    """End a firmware: it exits on the bridge's SHUTDOWN; killed if it has not within 5 s."""
    try:
        process.wait(timeout=5)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    if process.stdin is not None:
        process.stdin.close()
