"""A bridge session: one listening port, firmware bots accepted on it as robots of a run, their
LCD, LEDs, motors, log lines and remote-call results written into the run's recording.

    with Bridge(port=10001) as bridge:
        setups = [bridge.setup(CTBOT, calls=[(1.0, "bot_turn(90)")]), RobotSetup(CTBOT, make("solve_maze"))]
        result = run(world, setups, 60.0, observers=[recorder, bridge.observer(recorder)])
"""

from __future__ import annotations

import time
from typing import Any

from bots.odometry import default_estimators
from bots.spec import RobotSpec
from sim.bridge import protocol as p
from sim.bridge.firmware import FirmwareController, FirmwareEstimator
from sim.bridge.server import Listener
from sim.run import RobotLog, RobotSetup, RunResult
from sim.views.recording import TIMELINE, Recorder
from sim.world import World

CTSIM_STEP = 0.01
"""c't-Sim's step (s): the firmware's clock advances by it per block."""


class Bridge:
    """Listens on `host:port` (loopback unless told otherwise) from construction on; each
    `setup` is a robot whose controller is the next firmware that connects."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 10001,
        connect_timeout: float = 60.0,
        step_timeout: float = 10.0,
        dt: float = CTSIM_STEP,
        welcome: bool = True,
    ):
        self.listener = Listener(host, port)
        self.connect_timeout, self.step_timeout, self.dt, self.welcome = connect_timeout, step_timeout, dt, welcome
        self.bots: list[FirmwareController] = []

    @property
    def address(self) -> str:
        return f"{self.listener.host}:{self.listener.port}"

    def controller(self, rc5: tuple = (), calls: tuple = ()) -> FirmwareController:
        """The next firmware bot: `rc5` (time s, code) key presses, `calls` (time s, 'name(args)')."""
        n = len(self.bots)
        if n >= len(p.ADDRESS_POOL):
            raise ValueError(f"at most {len(p.ADDRESS_POOL)} firmware bots (c't-Sim's address pool)")
        bot = FirmwareController(
            self.listener, f"firmware bot {n + 1}", self.dt, self.connect_timeout, self.step_timeout, self.welcome,
            p.ADDRESS_POOL[n], tuple(rc5), tuple(calls),
        )  # fmt: skip
        self.bots.append(bot)
        return bot

    def setup(self, spec: RobotSpec, rc5: tuple = (), calls: tuple = (), start=None) -> RobotSetup:
        """A robot for `sim.run.run` driven by the next firmware; its estimators are ctsim's own
        plus the pose the firmware reports ('reported')."""
        bot = self.controller(rc5, calls)
        estimators = [*default_estimators(spec), FirmwareEstimator(bot)]
        return RobotSetup(spec, bot, controller_name=bot.label, start=start, estimators=estimators)

    def observer(self, recorder: Recorder | None = None, realtime: bool = False) -> BridgeObserver:
        """The run observer that records the firmware's output and closes the bridge at the end."""
        return BridgeObserver(self, recorder, realtime)

    def summary(self) -> list[dict[str, Any]]:
        return [bot.summary() for bot in self.bots]

    def close(self) -> None:
        """Shut every firmware down (SHUTDOWN: it exits 0) and stop listening; safe twice."""
        for bot in self.bots:
            bot.close()
        self.listener.close()

    def __enter__(self) -> Bridge:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class BridgeObserver:
    """Writes each firmware bot's LCD text, log lines and remote-call events (rerun TextLog), its
    LEDs and motor values (Scalars, on change) under `firmware/<robot>/`; paces the run at
    c't-Sim's real time with `realtime`; closes the bridge when the run ends."""

    def __init__(self, bridge: Bridge, recorder: Recorder | None, realtime: bool):
        self.bridge, self.recorder, self.realtime = bridge, recorder, realtime
        self.names: dict[int, str] = {}
        self.seen: dict[int, tuple[int, int, tuple]] = {}
        self.wall_start = 0.0

    def on_start(self, world: World, logs: list[RobotLog]) -> None:
        robot_of = {log.controller_name: log.name for log in logs}
        self.names = {id(bot): robot_of.get(bot.label, bot.label.replace(" ", "_")) for bot in self.bridge.bots}
        self.wall_start = time.monotonic()

    def on_sample(self, world: World, logs: list[RobotLog]) -> None:
        streams = self.recorder.streams if self.recorder is not None else []
        if streams:
            for bot in self.bridge.bots:
                self._record(streams, bot, world.time)
        if self.realtime:
            ahead = self.wall_start + world.time - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)

    def _record(self, streams: list[Any], bot: FirmwareController, t: float) -> None:
        """What changed on a firmware bot since the last sample (log lines, LEDs, motors), to every
        stream of the recording (the file and a live viewer)."""
        import rerun as rr

        name = self.names[id(bot)]
        shown, leds, motors = self.seen.get(id(bot), (0, -1, ()))
        if shown == len(bot.events) and leds == bot.state.leds and motors == bot.state.motors:
            return
        entries = []
        for event in bot.events[shown:]:
            level = {"lcd": "DEBUG", "call": "INFO"}.get(event.kind, "TRACE")
            entries.append((f"firmware/{name}/{event.kind}", rr.TextLog(f"step {event.step}: {event.text}", level=level)))
        if leds != bot.state.leds:
            bits = [(bot.state.leds >> k) & 1 for k in range(len(p.LED_NAMES))]
            entries += [(f"firmware/{name}/leds/{led}", rr.Scalars(bit)) for led, bit in zip(p.LED_NAMES, bits)]
        if motors != bot.state.motors:
            entries.append((f"firmware/{name}/motors", rr.Scalars(list(bot.state.motors))))
        for rec in streams:
            rec.set_time(TIMELINE, duration=t)
            for path, data in entries:
                rec.log(path, data)
        self.seen[id(bot)] = (len(bot.events), bot.state.leds, bot.state.motors)

    def on_end(self, result: RunResult) -> None:
        self.bridge.close()


