"""Bridge benchmarks: lock-step steps per second of one firmware bot in the maze, the peer being
the fake firmware of the tests (tests/fake_firmware.py, Python, in its own process), so the figure
is a floor for the real firmware's C (c't-Sim's real time is 100 steps/s, 10 ms per step); and
the end work of a bridged run, what the firmware's launcher waits for after the last step: from
the last block to SHUTDOWN, which comes once summary, TUM files and figures are written."""

from __future__ import annotations

import contextlib
import io
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bots.ctbot import CTBOT
from sim.bridge import Bridge
from sim.run.loop import run
from sim.world.files import load_world

ROOT = Path(__file__).resolve().parents[1]


def bridge_steps_per_s(steps: int) -> float:
    """Steps per second of a bridged run of `steps` steps, after the firmware connected."""
    with Bridge(port=0, connect_timeout=30, step_timeout=10) as bridge:
        setup = bridge.setup(CTBOT, rc5=[(0.0, 0x1183)])
        fake = subprocess.Popen([sys.executable, str(ROOT / "tests" / "fake_firmware.py"), "--port", str(bridge.listener.port)], stdin=subprocess.DEVNULL)
        try:
            clock = _Clock()
            result = run(load_world("maze"), [setup], steps * 0.01, observers=[clock, bridge.observer()])
        finally:
            bridge.close()
            fake.wait(timeout=30)
    if result.reason != "duration":
        raise RuntimeError(f"bridge benchmark failed: {result.error}")
    return (len(result.time) - 2) / (clock.last - clock.first)


class _Clock:
    """Wall time of the first and the last sample (the first waits for the connection)."""

    first = last = 0.0

    def on_sample(self, world, logs) -> None:
        self.last = time.perf_counter()
        if world.steps == 1:
            self.first = self.last


def bridge_end_work(seconds: float) -> float:
    """Wall seconds from the fake firmware's last block to its SHUTDOWN in `ctsim bridge maze`
    for a run of `seconds` simulated seconds (solve_maze started by RC5 5, figures written)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from fake_firmware import FakeFirmware

    from sim.cli.entry import main

    class Timed(FakeFirmware):
        last = 0.0

        def _reply(self, sock, time_ms):
            Timed.last = time.perf_counter()
            return super()._reply(sock, time_ms)

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    shutdown: list[float] = []
    fake = Timed(port, map_every=0, on_shutdown=lambda: shutdown.append(time.perf_counter())).start()
    with tempfile.TemporaryDirectory() as out, contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main(["bridge", "maze", "--port", str(port), "--duration", f"{seconds:g}", "--rc5", "0.5:5", "--out", out])
    fake.join(60)
    if code != 0 or not shutdown:
        raise RuntimeError(f"bridge end-work benchmark failed (exit {code}, fake error {fake.error})")
    return shutdown[0] - Timed.last


def run_end_work(seconds: float) -> float:
    """The same end work of a plain run (solve_maze, no bridge, same world and length): from its
    last sample to the last file, the recording closed and the files and figures `ctsim run`
    writes after the loop, for comparison."""
    from bots.behaviours import make
    from sim.cli.output import finish
    from sim.run.loop import RobotSetup
    from sim.views.recording.recorder import Recorder

    clock = _Clock()
    with tempfile.TemporaryDirectory() as out:
        recorder = Recorder(Path(out) / "run.rrd")
        result = run(load_world("maze"), [RobotSetup(CTBOT, make("solve_maze"), "solve_maze")], seconds, observers=[clock, recorder])
        with contextlib.redirect_stdout(io.StringIO()):
            finish(result, Path(out), {"duration": seconds})
        return time.perf_counter() - clock.last


def figures(scale: float):
    yield "bridge_steps_per_s", "steps/s (fake firmware in Python, own process; c't-Sim real time: 100 steps/s)", lambda: bridge_steps_per_s(int(5000 * scale))
    length = 300 * scale
    yield f"bridge_end_work_{length:g}s_run", "s (last block to SHUTDOWN: summary, TUM, figures written; bar < 1 s for 300 s)", lambda: bridge_end_work(length)
    yield f"run_end_work_{length:g}s_run", "s (the same files of a plain solve_maze run, beside it)", lambda: run_end_work(length)
