"""A bridge session: one listening port, firmware bots accepted on it as robots of a run, their
LCD, LEDs, motors, log lines, remote-call results and own map written into the run's recording.

    with Bridge(port=10001) as bridge:
        setups = [bridge.setup(CTBOT, calls=[(1.0, "bot_turn(90)")]), RobotSetup(CTBOT, make("solve_maze"))]
        result = run(world, setups, 60.0, observers=[bridge.observer(recorder), recorder])
        ...  # write the run's files: the firmwares wait, and are shut down when the `with` ends
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

from bots.odometry.defaults import default_estimators
from bots.spec import EncoderSpec, RobotSpec
from sim.bridge import protocol as p
from sim.bridge.firmware import FirmwareController, FirmwareEstimator
from sim.bridge.firmware_map import window
from sim.bridge.server import Listener
from sim.errors import UserError
from sim.run.loop import RobotSetup
from sim.run.samples import RobotLog, RunResult
from sim.views.map_image import rgba_png
from sim.views.recording.layout import TIMELINE
from sim.views.recording.recorder import Recorder
from sim.world import World
from sim.world.step import DEFAULT_DT

CTSIM_STEP = DEFAULT_DT
"""c't-Sim's step (s), ctsim's default: the firmware's clock advances by it per block."""
MAP_IMAGE_EVERY = 1.0
"""Simulated seconds between two drawings of a firmware's map (when it changed): an image of the
map's known part a second keeps a recording small (its blocks arrive every few steps)."""


class Bridge:
    """Listens on `host:port` (loopback unless told otherwise) from construction on; each
    `setup` is a robot whose controller is the next firmware that connects. `list_calls`: ask
    every firmware for the remote calls it offers. `close` (or the end of a `with`) shuts the
    firmwares down: after the caller wrote its files, so that a firmware's launcher that waits
    for it to exit finds everything written."""

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 10001,
        connect_timeout: float = 60.0,
        step_timeout: float = 10.0,
        dt: float = CTSIM_STEP,
        welcome: bool = True,
        list_calls: bool = False,
    ):
        self.listener = Listener(host, port)
        self.connect_timeout, self.step_timeout, self.dt, self.welcome = connect_timeout, step_timeout, dt, welcome
        self.list_calls = list_calls
        self.bots: list[FirmwareController] = []

    @property
    def address(self) -> str:
        return f"{self.listener.host}:{self.listener.port}"

    def controller(self, rc5: tuple = (), calls: tuple = (), ctsim_ticks: bool = False) -> FirmwareController:
        """The next firmware bot: `rc5` (time s, code) key presses, `calls` (time s, 'name(args)'),
        `ctsim_ticks`: encoder ticks in c't-Sim's arithmetic (`CtsimEncoders`)."""
        n = len(self.bots)
        if n >= len(p.ADDRESS_POOL):
            raise UserError(f"at most {len(p.ADDRESS_POOL)} firmware bots (c't-Sim's address pool)")
        bot = FirmwareController(
            self.listener, f"firmware bot {n + 1}", self.dt, self.connect_timeout, self.step_timeout, self.welcome,
            p.ADDRESS_POOL[n], tuple(rc5), tuple(calls), self.list_calls, ctsim_ticks,
        )  # fmt: skip
        self.bots.append(bot)
        return bot

    def setup(self, spec: RobotSpec, rc5: tuple = (), calls: tuple = (), start=None, like_ctsim: bool = True) -> RobotSetup:
        """A robot for `sim.run.loop.run` driven by the next firmware; its estimators are ctsim's own
        plus the pose the firmware reports ('reported'). `like_ctsim`: the robot meets walls and
        sees them as in c't-Sim (`as_in_ctsim`), and ideal encoders count in c't-Sim's arithmetic,
        so that the firmware takes the path it takes there."""
        bot = self.controller(rc5, calls, ctsim_ticks=like_ctsim and spec.encoders == EncoderSpec())
        if like_ctsim:
            spec = as_in_ctsim(spec)
        estimators = [*default_estimators(spec), FirmwareEstimator(bot)]
        return RobotSetup(spec, bot, controller_name=bot.label, start=start, estimators=estimators)

    def observer(self, recorder: Recorder | None = None, realtime: bool = False) -> BridgeObserver:
        """The run observer that records the firmware's output and, at the end, sends each
        firmware its last block. List it before `recorder`, so that the last reply is recorded."""
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


CTSIM_LINE_HEIGHT = 0.003
"""m, c't-Sim's line sensors over its floor: 4 mm over the ground plane (the bot's centre 75 mm
up, the sensors 71 mm below it), the floor's top 1 mm up; its lines lie 1 mm higher still, 2 mm
below the sensors (`WorldSpec.line_height` of a parcours)."""


def as_in_ctsim(spec: RobotSpec) -> RobotSpec:
    """`spec` as c't-Sim simulates it where ctsim's own models differ (each measured against the
    real c't-Sim with the same firmware): a step into a wall or robot is not made at all
    (contact 'stop'); IR sensors see walls as c't-Sim's Java3D cone pick does (view 'pick'), not
    at their nearest point in the cone, and light sensors its lamps likewise (view 'pick'), not at
    their surface; line sensors average c't-Sim's cross of rays over their spot
    (`CTSIM_LINE_HEIGHT`), not the one point under them."""
    return spec.with_changes(
        contact="stop",
        ir=tuple(replace(sensor, view="pick") for sensor in spec.ir),
        light=tuple(replace(sensor, view="pick") for sensor in spec.light),
        line=tuple(replace(sensor, height=CTSIM_LINE_HEIGHT) for sensor in spec.line),
    )


class BridgeObserver:
    """Writes each firmware bot's LCD text, log lines and remote-call events (rerun TextLog), its
    LEDs and motor values (Scalars, on change) under `firmware/<robot>/`, and its own map as an
    image under `world/map/firmware/<robot>` (the part over the world, translucent, above the
    world's floor: unknown cells are clear); paces the run at c't-Sim's real time with
    `realtime`; at the end sends every firmware the block of the last step."""

    def __init__(self, bridge: Bridge, recorder: Recorder | None, realtime: bool):
        self.bridge, self.recorder, self.realtime = bridge, recorder, realtime
        self.names: dict[int, str] = {}
        self.starts: dict[int, tuple[float, float, float]] = {}
        self.seen: dict[int, tuple[int, int, tuple]] = {}
        self.drawn: dict[int, tuple[int, float]] = {}
        self.windows: dict[int, tuple[int, int, int, int]] = {}
        self.logs: dict[int, RobotLog] = {}
        self.wall_start = 0.0

    def on_start(self, world: World, logs: list[RobotLog]) -> None:
        robot_of = {log.controller_name: log for log in logs}
        for bot in self.bridge.bots:
            log = robot_of.get(bot.label)
            self.names[id(bot)] = log.name if log is not None else bot.label.replace(" ", "_")
            if log is not None:
                self.logs[id(bot)] = log
                self.starts[id(bot)] = tuple(float(v) for v in world.robots[logs.index(log)].pose)
                self.windows[id(bot)] = window(world.spec.bounds, self.starts[id(bot)])
        self.wall_start = time.monotonic()

    def on_sample(self, world: World, logs: list[RobotLog]) -> None:
        self._record_all(world.time, final=False)
        if self.realtime:
            ahead = self.wall_start + world.time - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)

    def _record_all(self, t: float, final: bool) -> None:
        streams = self.recorder.streams if self.recorder is not None else []
        if streams:
            for bot in self.bridge.bots:
                self._record(streams, bot, t)
                self._draw_map(streams, bot, t, final)

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
        _log_all(streams, t, entries)
        self.seen[id(bot)] = (len(bot.events), bot.state.leds, bot.state.motors)

    def _draw_map(self, streams: list[Any], bot: FirmwareController, t: float, final: bool) -> None:
        """The firmware's map, when it changed, at most every MAP_IMAGE_EVERY s (and at the end)."""
        import rerun as rr

        fw_map, start = bot.state.map, self.starts.get(id(bot))
        blocks, when = self.drawn.get(id(bot), (0, -MAP_IMAGE_EVERY))
        if start is None or fw_map.blocks == blocks or (t < when + MAP_IMAGE_EVERY and not final):
            return
        cells = self.windows[id(bot)]
        path = f"world/map/firmware/{self.names[id(bot)]}"
        entries = [(path, rr.EncodedImage(contents=rgba_png(fw_map.image(cells)), media_type="image/png", draw_order=-90.0))]
        if not blocks:
            corner, matrix = fw_map.placement(start, cells)
            entries.insert(0, (path, rr.Transform3D(translation=corner, mat3x3=matrix)))
        _log_all(streams, t, entries)
        self.drawn[id(bot)] = (fw_map.blocks, t)

    def on_end(self, result: RunResult) -> None:
        """Send each firmware the block of the last step (c't-Sim waits for that reply too) and
        record what it answered; a run that failed sends nothing more."""
        if result.reason.reached_end:
            for bot in self.bridge.bots:
                log = self.logs.get(id(bot))
                if log is not None and log.latest is not None:
                    bot.finish(log.latest)
        self._record_all(result.duration, final=True)


def _log_all(streams: list[Any], t: float, entries: list[tuple[str, Any]]) -> None:
    for rec in streams:
        rec.set_time(TIMELINE, duration=t)
        for path, data in entries:
            rec.log(path, data)
