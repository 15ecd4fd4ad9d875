"""sim.sandbox: untrusted code answers in plain data, sees nothing of the host, and whatever it does
ends as a StudentError of its own kind, with every process of it gone afterwards."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from bots.ctbot import CTBOT
from bots.readings import Readings
from sim.sandbox import Limits, Sandbox, StudentError, unavailable, wire

pytestmark = pytest.mark.skipif(unavailable() is not None, reason=f"no OS sandbox here: {unavailable()}")

GENEROUS = 60.0  # s for a request that must succeed: the machine may be busy; never what a test decides on


def box(tmp_path: Path, text: str, **kwargs) -> Sandbox:
    path = tmp_path / "code.py"
    path.write_text(text, encoding="utf-8")
    return Sandbox(path, **kwargs)


def test_the_wire_round_trips_plain_data_and_refuses_anything_else() -> None:
    value = {"a": [1, 2.5, float("inf"), None, True, "x"], "t": (1, 2), "arr": np.arange(6).reshape(2, 3)}  # host to guest
    back = wire.loads(wire.dumps(value)[wire.HEADER.size:])
    assert back["a"] == value["a"] and back["t"] == (1, 2)
    assert back["arr"].dtype == np.int64 and (back["arr"] == value["arr"]).all()
    with pytest.raises(wire.WireError):
        wire.dumps(object())
    for forged in (b'{"__array__": ["object", [1], [1]]}', b'{"__array__": ["float64", [3], [1]]}', b"\x80", b"[" * 100000):
        with pytest.raises(wire.WireError):
            wire.loads(forged)


def test_records_reach_the_guest_with_their_fields_and_properties(tmp_path: Path) -> None:
    code = ("class Echo:\n"
            "    def reset(self, robot):\n"
            "        return [robot.wheel_diameter, robot.wheel_radius, robot.encoders.ticks_per_rev, list(robot.mouse.mount)]\n"
            "    def step(self, t, readings):\n"
            "        from bots.commands import Twist\n"
            "        return Twist(t, float(readings.encoder_ticks.sum()))\n")  # fmt: skip
    with box(tmp_path, code, modules=("bots.commands",)) as sandbox:
        handle = sandbox.new("Echo", timeout=GENEROUS)
        assert sandbox.method(handle, "reset", CTBOT, timeout=GENEROUS) == [CTBOT.wheel_diameter, CTBOT.wheel_radius, 60, list(CTBOT.mouse.mount)]
        readings = Readings(encoder_ticks=np.array([3, 4]))
        assert sandbox.step(handle, 0.5, readings, timeout=GENEROUS) == ["Twist", 0.5, 7.0, 0.0]
        assert sandbox.confined and not sandbox.degraded


SNOOP = """
import ctypes, os, socket, sys
def attach_to_the_first_process():
    if ctypes.CDLL(None, use_errno=True).ptrace(16, 1, 0, 0) != 0:  # PTRACE_ATTACH
        raise OSError(ctypes.get_errno(), "ptrace refused")
def look():
    found = {}
    for name, action in [("passwd", lambda: open("/etc/passwd").read()),
                         ("project", lambda: os.listdir(%(root)r)),
                         ("write", lambda: open("/submission/x.txt", "w").write("x")),
                         ("tmp", lambda: open("/tmp/x.txt", "w").write("x")),
                         ("fork", lambda: os.fork()),
                         ("thread", lambda: __import__("threading").Thread(target=print).start()),
                         ("ptrace", attach_to_the_first_process),
                         ("net", lambda: socket.create_connection(("1.1.1.1", 53), timeout=5)),
                         ("kinematics", lambda: __import__("sim.kinematics")),
                         ("mountinfo", lambda: open("/proc/self/mountinfo").read()),
                         ("processes", lambda: os.listdir("/proc")),
                         ("shell", lambda: os.stat("/usr/bin/sh")),
                         ("dist_packages", lambda: os.listdir("/usr/lib/python3/dist-packages")),
                         ("site_packages", lambda: (sys.path.append(%(site)r), __import__("pytest"))),
                         ("yaml", lambda: __import__("yaml"))]:
        try:
            action()
            found[name] = "done"
        except BaseException as err:
            found[name] = type(err).__name__
    found["top"] = sorted(os.listdir("/"))
    return sorted(found.items())  # a reply holds lists, no objects
"""


def test_the_guest_sees_nothing_of_the_host_and_cannot_start_processes_or_threads(tmp_path: Path) -> None:
    root = str(Path(__file__).resolve().parents[1])
    site = str(Path(pytest.__file__).parents[1])
    with box(tmp_path, SNOOP % {"root": root, "site": site}) as sandbox:
        found = dict(sandbox.call("look", timeout=GENEROUS))
    assert {"dev", "guest", "submission"} <= set(found.pop("top")) <= {"bin", "dev", "guest", "lib", "lib64", "sbin", "submission", "usr", *_interpreter_top()}
    assert "done" not in found.values(), found  # no /proc: no mount table, no other process to trace or signal
    assert not (tmp_path / "x.txt").exists()


def _interpreter_top() -> list[str]:
    """The top folder of the interpreter's installation where it is not under /usr (pyenv: /root)."""
    import sys

    top = Path(os.path.realpath(sys.base_prefix)).parts[1]
    return [] if top == "usr" else [top]


REPLIES = "import json, os, sys\nREPLIES = json.loads(sys.argv[1])['replies']\n"
"""The guest's reply pipe, as untrusted code finds it."""


@pytest.mark.parametrize(("code", "kind"), [
    ("def f():\n    while True:\n        pass\n", "timeout"),
    ("import os\ndef f():\n    while True:\n        os.write(1, b'x' * 65536)\n", "output"),
    ("def f():\n    return bytearray(4 << 30)\n", "memory"),
    ("import os\ndef f():\n    os._exit(3)\n", "crash"),
    (REPLIES + "def f():\n    os.close(REPLIES)\n    return 1\n", "crash"),
    (REPLIES + "def f():\n    os.write(REPLIES, b'\\x00\\x00\\x00\\x05{\"ok\"')\n    return 1\n", "protocol"),
])  # fmt: skip
def test_whatever_the_code_does_it_ends_as_an_error_of_its_kind_and_a_fresh_guest_follows(tmp_path: Path, code: str, kind: str) -> None:
    code += "def g():\n    return 42\n"
    with box(tmp_path, code, limits=Limits(memory=1 << 30, output=1 << 20)) as sandbox:
        with pytest.raises(StudentError) as caught:
            sandbox.call("f", timeout=2.0 if kind == "timeout" else GENEROUS)  # the loop is endless: any limit ends it
        assert caught.value.kind == kind, caught.value.detail
        assert kind != "memory" or "the limit is 1 GiB" in caught.value.detail  # the limit it has, said as it is
        if sandbox.process is None:
            sandbox.start()
        assert sandbox.call("g", timeout=GENEROUS) == 42


def test_close_returns_when_every_process_of_the_sandbox_is_gone(tmp_path: Path) -> None:
    sandbox = box(tmp_path, "def f():\n    return 1\n")
    assert sandbox.call("f", timeout=GENEROUS) == 1
    first, outer = sandbox._pid1, sandbox.process.pid
    sandbox.close()
    for pid in (first, outer):
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def test_signals_to_the_sandbox_s_first_process_or_to_everyone_are_lost(tmp_path: Path) -> None:
    code = ("import os, signal\ndef f():\n    for pid in (os.getppid(), 1, -1):\n        try:\n            os.kill(pid, signal.SIGKILL)\n"
            "        except OSError:\n            pass\n    return 7\n")
    with box(tmp_path, code) as sandbox:
        assert sandbox.call("f", timeout=GENEROUS) == 7
        assert sandbox.call("f", timeout=GENEROUS) == 7


KERNEL_STATE = """
import ctypes, os, platform
from confine import NUMBERS
libc = ctypes.CDLL(None, use_errno=True)
SQPOLL = 2
def attempt(name, *args):
    result = libc.syscall(NUMBERS[platform.machine()][name], *args)
    return [name, result, ctypes.get_errno()]
def make_shared_state(description):
    params = (ctypes.c_uint32 * 30)(0, SQPOLL)  # struct io_uring_params, flags = IORING_SETUP_SQPOLL
    return [attempt("add_key", b"user", description, b"answers", 7, -4),  # the user's keyring
            attempt("add_key", b"user", description, b"answers", 7, -3),  # the session's
            attempt("keyctl", 1, 0),                                       # join a session keyring
            attempt("request_key", b"user", description, None, 0),
            attempt("io_uring_setup", 8, params),
            attempt("bpf", 0, None, 0), attempt("perf_event_open", None, 0, -1, -1, 0),
            attempt("unshare", 0x10000000), attempt("userfaultfd", 0)]
"""


def test_the_kernel_s_shared_state_is_refused_and_nothing_a_guest_did_remains(tmp_path: Path) -> None:
    description = f"ctsim-probe-{os.getpid()}-{tmp_path.name}".encode()
    with box(tmp_path, KERNEL_STATE) as sandbox:
        attempts = sandbox.call("make_shared_state", description.decode(), timeout=GENEROUS)
    assert [(name, result, code) for name, result, code in attempts if (result, code) != (-1, 1)] == []  # every one EPERM
    keys = Path("/proc/keys")
    if keys.exists():  # the host's view of the keys it may see: the guest's key is not among them
        assert description not in keys.read_bytes()


@pytest.mark.skipif(not Path("/usr/include/x86_64-linux-gnu/asm/unistd_64.h").is_file(), reason="the kernel's x86-64 headers are not installed")
def test_the_refused_calls_have_the_kernel_s_numbers() -> None:
    import re

    from sim.sandbox import confine

    headers = {"x86_64": "/usr/include/x86_64-linux-gnu/asm/unistd_64.h", "aarch64": "/usr/include/asm-generic/unistd.h"}
    for machine, header in headers.items():
        numbers = {name: int(n) for name, n in re.findall(r"#define __NR(?:3264)?_(\w+)\s+(\d+)", Path(header).read_text())}
        assert confine.NUMBERS[machine] == {name: numbers[name] for group in confine.REFUSED.values() for name in group if name in numbers}
