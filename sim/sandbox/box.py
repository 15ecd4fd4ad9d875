"""The host's handle on one sandboxed guest: start it, send requests with a deadline, end it.

Whatever the untrusted code does (raise, hang, exit, print without end, answer nonsense, fork,
eat memory), the host gets a `StudentError` with a clear message, never a crash of its own, and
`close()` returns only when every process of the sandbox is gone.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from sim import sanitize
from sim.sandbox import launch, reply, wire


@dataclass(frozen=True)
class Limits:
    """What one guest may use. cpu: CPU seconds over its whole life (the kernel ends it after);
    memory: bytes of address space; files: open file descriptors; processes: of its user where the
    kernel counts them (new processes and threads are refused anyway); output: bytes of stdout and stderr
    before it is ended; excerpt: characters of that output kept; reply: bytes of one answer;
    startup: seconds to start and load the file (not the code's own time: the machine may be busy)."""

    cpu: float = 60.0
    memory: int = 1 << 30
    files: int = 64
    processes: int = 16
    output: int = 1 << 20
    excerpt: int = 2000
    reply: int = 1 << 20
    startup: float = 20.0


GRACE = 10.0
"""Seconds to wait for an ended guest's processes to be gone before their whole group is killed."""


class SandboxUnavailable(RuntimeError):
    """No OS isolation here and degraded running was not asked for (the message says what is missing)."""


@dataclass
class StudentError(Exception):
    """The untrusted code failed. `kind`: load, forbidden (an import of the project that is not
    there), raised, timeout, crash, output (printed too much), protocol (a malformed answer), and
    the checks' own (type, shape, nan). `detail` may name values of the request; `public` never
    does (for hidden scenarios). `exception`: the exception's type name, `line` its line in the file,
    `value_error`: it is a ValueError (the code refused its input on purpose)."""

    kind: str
    detail: str
    public: str
    exception: str = ""
    line: int | None = None
    value_error: bool = False

    def __str__(self) -> str:
        return self.detail


def _said(kind: str, message: str) -> StudentError:
    return StudentError(kind, message, message)


def _raised(info: dict[str, Any], what: str, loading: bool, memory: int) -> StudentError:
    """The guest's error description (fields checked by `reply.error`) as a StudentError;
    `memory`: the guest's limit (bytes), for the message."""
    kind_name, message, line = sanitize.name(info["type"], 80), sanitize.name(info["message"], 300), info["line"]
    missing = sanitize.name(info["missing"] or "", 120)
    where = f" at line {line}" if line else ""
    if kind_name == "MemoryError":
        text = f"{what} ran out of memory{where} (the limit is {human_size(memory)} of address space)"
        return StudentError("memory", text, text, kind_name, line)
    if missing and missing.split(".")[0] in launch.PROJECT:
        text = f"{what}: import of {missing}{where} is not available here (the robot's code sees only its readings and what the template imports)"
        return StudentError("forbidden", text, text, kind_name, line)
    detail = f"{what} raised {kind_name}{where}" + (f": {message}" if message else "")
    kind = "load" if loading else "raised"
    return StudentError(kind, detail, f"{what} raised {kind_name}{where}", kind_name, line, info["value_error"])


def human_size(memory: int) -> str:
    """Bytes as people say them: 1 GiB, 512 MiB."""
    return f"{memory / (1 << 30):g} GiB" if memory >= 1 << 30 else f"{memory / (1 << 20):g} MiB"


def _first_pid(info: int, deadline: float) -> int | None:
    """The host's pid of the sandbox's first process, from bubblewrap's --info-fd (closed here)."""
    data = b""
    try:
        while select.select([info], [], [], max(deadline - time.monotonic(), 0.0))[0]:
            chunk = os.read(info, 4096)
            if not chunk:
                break
            data += chunk
    finally:
        os.close(info)
    try:
        return int(json.loads(data.decode())["child-pid"])
    except (ValueError, KeyError, TypeError):
        return None


class Sandbox:
    """One untrusted file, run by the guest in a sandbox of its own (started by `start`, or by the
    first request). `modules`: project modules its code may import (with what they import);
    `folder`: bind the file's whole folder (its own helper modules), not the file alone;
    `degraded`: run without isolation where bubblewrap is missing (else SandboxUnavailable)."""

    def __init__(self, code: str | Path, modules: tuple[str, ...] = (), limits: Limits = Limits(), folder: bool = False,
                 degraded: bool = False):  # fmt: skip
        self.code = Path(code).resolve()
        self.modules, self.limits, self.folder = tuple(modules), limits, folder
        reason = launch.unavailable()
        if reason is not None and not degraded:
            raise SandboxUnavailable(f"{reason}: cannot isolate untrusted code (see the README: the teacher's machine needs bubblewrap)")
        self.degraded = reason is not None
        self.confined = False
        self.process: subprocess.Popen | None = None
        self._pid1: int | None = None
        self._reader: threading.Thread | None = None
        """(Both None until `start` has them: a start cut short by a signal is ended by `close` all the same.)"""
        self._handles = 0
        self._excerpt = bytearray()
        self._segment = 0
        self._lock = threading.Lock()
        self.printed = 0
        self.flooded = False

    @property
    def output(self) -> str:
        """The start of what the code printed (stdout and stderr) since the last `take_output`, at
        most `limits.excerpt` characters."""
        text = self._excerpt.decode("utf-8", errors="replace")[: self.limits.excerpt]
        return text + (f"\n[... {self._segment - len(self._excerpt)} more bytes]" if self._segment > len(self._excerpt) else "")

    def take_output(self) -> str:
        """`output`, with everything the code printed before its last answer (or its end), and a
        fresh excerpt begun: what one scenario printed stays with that scenario."""
        with self._lock:
            if self.process is not None:
                self._read_pending()
            text = self.output
            self._excerpt, self._segment = bytearray(), 0
        return text

    def start(self, startup: float | None = None) -> None:
        """Start the guest and load the file within `startup` seconds (default `limits.startup`);
        a StudentError if it does not load (a timeout if it takes longer)."""
        startup = self.limits.startup if startup is None else startup
        requests, self._requests = os.pipe()
        self._replies, replies = os.pipe()
        info, info_write = os.pipe()
        config = {"requests": requests, "replies": replies, "limits": asdict(self.limits)}
        command = launch.command(self.code, self.folder, self.modules, config, self.degraded)
        passed = (requests, replies)
        if not self.degraded:
            command[1:1] = ["--info-fd", str(info_write)]
            passed += (info_write,)
        environment = launch.ENVIRONMENT | ({"HOME": str(self.code.parent)} if self.degraded else {})
        try:
            self.process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                            pass_fds=passed, start_new_session=True, env=environment)  # fmt: skip
        finally:
            for fd in (*passed, info_write) if self.degraded else passed:
                os.close(fd)
        self._pid1 = None if self.degraded else _first_pid(info, time.monotonic() + startup)
        if self.degraded:
            os.close(info)
        self.flooded, self._printed_now = False, 0
        os.set_blocking(self.process.stdout.fileno(), False)
        self._reader = threading.Thread(target=self._drain, daemon=True)
        self._reader.start()
        hello = self._receive(time.monotonic() + startup, "loading your file")
        if "error" in hello:
            error = _raised(hello["error"], "loading your file", True, self.limits.memory)
            self.close()
            raise error
        self.confined = hello.get("confined") is True

    def request(self, message: dict[str, Any], timeout: float, what: str, name_call: Callable[[int], str] | None = None) -> Any:
        """Send `message` (see `sim.sandbox.guest`) and return the answer's value within `timeout`
        seconds; `what` names the request in messages (`name_call(i)` the call i of a feed that
        raised). A timeout or a broken guest closes it."""
        if self.process is None:
            self.start()
        deadline = time.monotonic() + max(timeout, 0.0)
        try:
            self._send(wire.dumps(message), deadline)
        except TimeoutError:
            self.close()
            raise _said("timeout", f"{what} took longer than the time limit (an endless loop?)") from None
        except OSError:
            raise self._ended(what) from None
        answer = self._receive(deadline, what)
        if "error" in answer:
            index = answer["error"]["index"]
            if name_call is not None and index is not None and index >= 0:
                what = name_call(index)
            raise _raised(answer["error"], what, False, self.limits.memory)
        return answer["ok"]

    def call(self, name: str, *args: Any, timeout: float) -> Any:
        """`name(*args)` in the file; plain data back."""
        return self.request({"op": "call", "name": name, "args": list(args)}, timeout, f"{name}()")

    def new(self, name: str, timeout: float, **kwargs: Any) -> int:
        """Make `name(**kwargs)` (a class of the file) in the guest; returns a handle."""
        self._handles += 1
        self.request({"op": "new", "handle": self._handles, "name": name, "kwargs": kwargs}, timeout, f"{name}()")
        return self._handles

    def method(self, handle: int, name: str, *args: Any, timeout: float, attribute: str | None = None, what: str = "") -> Any:
        """`object.name(*args)` of a handle's object; its `attribute` after the call if given."""
        message = {"op": "method", "handle": handle, "name": name, "args": list(args), "attribute": attribute}
        return self.request(message, timeout, what or f"{name}()")

    def step(self, handle: int, t: float, readings: Any, timeout: float, what: str = "step()") -> list:
        """A controller's `step(t, readings)`: the command as [type name, numbers...] or ["bad", type name]."""
        return self.request({"op": "step", "handle": handle, "t": t, "readings": readings}, timeout, what)

    def feed(self, handle: int, name: str, series: list[tuple], attribute: str, timeout: float,
             name_call: Callable[[int], str] | None = None) -> list:
        """`object.name(*args)` for each args of `series` in turn, in one request; the object's
        `attribute` after each call, a list (an estimator fed a whole run's readings at once)."""
        message = {"op": "feed", "handle": handle, "name": name, "series": [list(args) for args in series], "attribute": attribute}
        return self.request(message, timeout, f"{name}()", name_call)

    def _send(self, data: bytes, deadline: float) -> None:
        view = memoryview(data)
        while view:
            if not select.select([], [self._requests], [], max(deadline - time.monotonic(), 0.0))[1]:
                raise TimeoutError
            view = view[os.write(self._requests, view[: select.PIPE_BUF]):]

    def _receive(self, deadline: float, what: str) -> dict[str, Any]:
        def wait(fd: int) -> None:
            if not select.select([fd], [], [], max(deadline - time.monotonic(), 0.0))[0]:
                raise TimeoutError

        try:
            answer = reply.read(wire.receive_body(self._replies, self.limits.reply, wait))
        except TimeoutError:
            self.close()
            raise _said("timeout", f"{what} took longer than the time limit (an endless loop?)") from None
        except EOFError:
            raise self._ended(what) from None
        except wire.WireError as err:
            self.close()
            raise _said("protocol", f"{what}: the answer could not be read ({err})") from None
        return answer

    def _ended(self, what: str) -> StudentError:
        """The guest is gone: why, as far as the exit status tells."""
        try:
            code = self.process.wait(timeout=1.0)  # only for the message: an exit status or none
        except subprocess.TimeoutExpired:  # it closed its end of the pipe and lives on
            code = None
        flooded = self.flooded
        self.close()
        if flooded:
            return _said("output", f"your code printed more than {self.limits.output} bytes while {what}; it was stopped")
        signalled = -code if code is not None and code < 0 else code - 128 if code and code > 128 and not self.degraded else None
        if signalled == signal.SIGXCPU:
            return _said("timeout", f"your code used more than {self.limits.cpu:g} s of CPU time while {what}")
        return _said("crash", f"your code ended the checking process while {what} (exit code {code}: sys.exit, os._exit or a crash)")

    def _drain(self) -> None:
        """Keep the start of the output (over every guest of this sandbox); end this guest when it
        prints more than the limit. Reads happen under the lock, so `take_output` sees every byte
        the guest wrote before it answered."""
        stream = self.process.stdout.fileno()
        while True:
            select.select([stream], [], [])
            with self._lock:
                if not self._read_pending():
                    return

    def _read_pending(self) -> bool:
        """Read what the guest's output pipe holds now (the lock held); False at its end."""
        stream = self.process.stdout.fileno()
        while True:
            try:
                chunk = os.read(stream, 1 << 16)
            except BlockingIOError:
                return True
            except OSError:
                return False
            if not chunk:
                return False
            self._printed_now += len(chunk)
            self.printed += len(chunk)
            self._segment += len(chunk)
            room = self.limits.excerpt * 4 - len(self._excerpt)
            if room > 0:
                self._excerpt += chunk[:room]
            if self._printed_now > self.limits.output and not self.flooded:
                self.flooded = True
                self._kill()

    def _kill(self) -> None:
        """SIGKILL the sandbox's first process: the kernel ends every process of its pid namespace
        before bubblewrap sees it end. Degraded (or if bubblewrap never said), the process group."""
        try:
            if self._pid1:
                os.kill(self._pid1, signal.SIGKILL)
            else:
                os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    def close(self) -> None:
        """End the guest and every process it started; returns when they are gone."""
        if self.process is None:
            return
        for fd in (self._requests, self._replies):
            os.close(fd)
        self._kill()
        try:
            self.process.wait(timeout=GRACE)
        except subprocess.TimeoutExpired:  # bubblewrap itself stuck: its group goes too
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()
        if self._reader is not None:
            self._reader.join()
        self.process.stdout.close()
        self.process, self._pid1, self._reader = None, None, None

    def __enter__(self) -> Sandbox:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
