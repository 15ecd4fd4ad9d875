"""Bridge benchmark: lock-step steps per second of one firmware bot in the maze, the peer being
the fake firmware of the tests (tests/fake_firmware.py, Python, in its own process), so the figure
is a floor for the real firmware's C. c't-Sim's real time is 100 steps/s (10 ms per step)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

from bots.ctbot import CTBOT
from sim.bridge import Bridge
from sim.run import run
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


def figures(scale: float):
    yield "bridge_steps_per_s", "steps/s (fake firmware in Python, own process; c't-Sim real time: 100 steps/s)", lambda: bridge_steps_per_s(int(5000 * scale))
