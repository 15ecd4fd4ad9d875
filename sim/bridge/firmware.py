"""A c't-Bot firmware on the other end of a TCP link, as one more controller of the run loop.

The exchange follows c't-Sim step for step. c't-Sim computes a step's sensors, moves the robot
with the motors of the last reply, counts that motion's encoder ticks and mouse dots, and only
then sends the block; so a block carries the sensors from before a motion and the ticks of that
motion. The controller therefore sends the block of step k in step k+1, once the world has moved
(the readings of step k+1 hold the ticks of motion k), and returns the motors of its reply for
motion k+1: the motors the firmware chose for block k drive the robot in step k+1, as in c't-Sim.
The first block is c't-Sim's block from before its first step: every sensor 0 and DONE -1, which
the firmware expects (its clock starts at -11 ms). Sensors go out in firmware units (`Readings`
holds the devices' raw values) with two conversions at this edge: c't-Sim's mouse has its
sideways axis the other way round, and its DONE carries the time in ms modulo 10000. Motor values
are mm/s / 2, which c't-Sim drives at 1.75788 mm/s per unit (ctbot-protocol.md §8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bots.commands import WheelSpeeds
from bots.controller import ControllerStopped, Status
from bots.readings import Readings
from bots.sensor_kinds import KINDS, SensorKind
from bots.spec import RobotSpec
from sim.bridge import protocol as p
from sim.bridge.firmware_map import FirmwareMap
from sim.bridge.protocol import Packet
from sim.bridge.server import Link, LinkError, Listener
from sim.world.step import DEFAULT_DT

MM_S_PER_UNIT = 151 / 60 * 178.1283 / 255
"""c't-Sim's wheel speed per ACT_MOT unit (mm/s): PWM/255 of 151 rpm on a 178.1283 mm wheel."""
WHEEL_CIRCUMFERENCE_M = 0.1781283


ENCODER_MARKS = 60


def revs_per_second(units: int) -> float:
    """The wheel's revolutions per second c't-Sim drives for an ACT_MOT value, in its arithmetic
    (`WheelSimulator.revsThisSimStep`): the ratio PWM / 255 and the constant 151 / 60 are each
    float32, their product is double. Up to 1e-7 off the exact value, which decides the step of a
    tick wherever the exact count would be a whole number (75 units: 151 ticks in exactly 340
    steps); rounding the product to float32 as well moves such ticks by a step."""
    return float(np.float32(units) / np.float32(255)) * float(np.float32(151) / np.float32(60))


def wheel_speed(units: int) -> float:
    """The wheel's rim speed (m/s) c't-Sim drives for an ACT_MOT value."""
    return revs_per_second(units) * WHEEL_CIRCUMFERENCE_M


class CtsimEncoders:
    """c't-Sim's encoder ticks of a step, bit for bit: floor(revolutions x 60 + rest) per wheel,
    the rest carried, the revolutions of the step in its own double arithmetic. ctsim's world
    counts the same ticks through other roundings, and once in a few thousand steps a sum that
    lands on a whole number then gives a tick one step apart (seen at 94.3 s in maze.xml); for
    ideal encoders the bridge therefore sends these."""

    def __init__(self, dt: float):
        self.step_s = round(dt * 1000) / 1000.0  # c't-Sim: the step in ms / 1000.0
        self.rest = [0.0, 0.0]

    def count(self, motors: tuple[int, int]) -> tuple[int, int]:
        """The ticks of one step driven with `motors`."""
        ticks = []
        for w, units in enumerate(motors):
            total = revs_per_second(units) * self.step_s * ENCODER_MARKS + self.rest[w]
            whole = math.floor(total)
            self.rest[w] = total - whole
            ticks.append(whole)
        return ticks[0], ticks[1]
MAP_MM_PER_CELL, MAP_ORIGIN_MM = 8, 6144
"""The firmware's map grid (125 cells/m) and its centre, the start pose (map_to_world)."""
CAM_POSITION = 14
BPS_NONE = 0xFFFF
BLOCK = (p.SENS_MOUSE, p.SENS_DOOR, p.SENS_BORDER, p.SENS_LDR, p.SENS_IR, p.SENS_RC5, p.SENS_TRANS, p.SENS_LINE, p.SENS_ENC, p.SENS_CAM, p.SENS_BPS, p.SENS_ERROR)
"""A step's packets before its DONE, in the order ctsim sends them (`m D B H I R T L E S b e`):
the sensor registry's packets (`SensorKind.packet`, their values from the readings) among those of
the bot's other state (door, remote control, transport pocket, camera, beacons, error line). One
order c't-Sim sent (its own changes from run to run, a hash map's: docs/bridge.md), kept fixed so
that runs repeat byte for byte; it interleaves packets the registry does not know and follows no
rule a registry column could state, so it is this one table rather than the registry's order."""
ERROR_OK = (1, 0)
"""c't-Sim's error-line packet: 1 = OK, data_r 0."""
DOOR_OPEN_FROM = 12
"""Servo 1 position (ACT_SERVO data_l = position / 8) from which the door counts as open."""


class BridgeError(ControllerStopped):
    """A firmware bot that cannot go on: never connected, hung, vanished or sent garbage."""


@dataclass
class Event:
    """Something the firmware did at a step: a log line, an LCD change, a remote-call result."""

    step: int
    time: float
    kind: str
    text: str


@dataclass
class Call:
    """A remote call scheduled for time `at` (s); `result` 1/0 once the firmware's r/D came."""

    at: float
    name: str
    args: tuple[int, ...] = ()
    sent_step: int | None = None
    done_step: int | None = None
    result: int | None = None

    @property
    def text(self) -> str:
        return f"{self.name}({', '.join(map(str, self.args))})"


@dataclass
class FirmwareState:
    """What the firmware has shown so far: LEDs, the 20x4 LCD, motors, its map and map pose,
    address, the remote calls it offers (once asked) and the RC5 toggle bit."""

    address: int = p.BROADCAST
    features: int | None = None
    motors: tuple[int, int] = (0, 0)
    leds: int = 0
    lcd: list[list[str]] = field(default_factory=lambda: [[" "] * 20 for _ in range(4)])
    cursor: tuple[int, int] = (0, 0)
    map_pose: tuple[float, float, float] | None = None
    map: FirmwareMap = field(default_factory=FirmwareMap)
    door_open: bool = False
    functions: list[str] = field(default_factory=list)
    functions_complete: bool = False
    rc5_toggle: int = 0
    removed: bool = False

    @property
    def lcd_text(self) -> str:
        return "\n".join("".join(row).rstrip() for row in self.lcd)


class FirmwareController:
    """The controller of one robot driven by a c't-Bot firmware over TCP (see the module doc).

    `rc5`: (time s, RC5 code) key presses; `calls`: (time s, 'bot_turn(90)') remote calls;
    `list_calls`: ask for the remote calls the firmware offers (c't-Sim's RemoteCallViewer) with
    the first block after the handshake. The link is accepted from `listener` in the first step
    (after `connect_timeout` s: an error); each reply must end within `step_timeout` s. After the
    run, `finish` sends the last block; `close` shuts the firmware down."""

    def __init__(
        self,
        listener: Listener,
        label: str = "firmware bot",
        dt: float = DEFAULT_DT,
        connect_timeout: float = 60.0,
        step_timeout: float = 10.0,
        welcome: bool = True,
        address: int = p.ADDRESS_POOL[0],
        rc5: tuple[tuple[float, int], ...] = (),
        calls: tuple[tuple[float, str], ...] = (),
        list_calls: bool = False,
        ctsim_ticks: bool = False,
    ):
        self.listener = listener
        self.label = label
        self.dt = dt
        self.connect_timeout = connect_timeout
        self.step_timeout = step_timeout
        self.welcome = welcome
        self.offer = address
        self.rc5 = sorted(rc5)
        self.calls = sorted((Call(at, *p.parse_call(text)) for at, text in calls), key=lambda c: c.at)
        self.list_calls = list_calls
        self.encoders = CtsimEncoders(dt) if ctsim_ticks else None
        self.link: Link | None = None
        self.state = FirmwareState()
        self.events: list[Event] = []
        self.blocks = 0
        """Blocks sent so far: the next block is that of step `blocks`."""
        self.seq = 0
        self.status = Status.RUNNING
        self._extra: list[Packet] = []
        self._held: tuple[float, Readings, tuple[int, int] | None] | None = None
        """The step whose block waits for the next step's ticks: its time, readings and (with
        `ctsim_ticks`) the ticks of its motion."""

    def reset(self, robot: RobotSpec) -> None:
        self.robot = robot

    # --- one step ---------------------------------------------------------------------------

    def step(self, t: float, readings: Readings) -> WheelSpeeds:
        """Send the last step's block with the ticks the world just counted, read the reply,
        return its motors (for this step's motion)."""
        try:
            if self.link is None:
                self.link = self.listener.accept(self.connect_timeout)
                if self.welcome:
                    self.link.send(self._packet(p.WELCOME, to=0).encode(), self.step_timeout)
            else:
                self._exchange(readings)
        except LinkError as err:
            raise BridgeError(f"{self.label}: {err} (reply to the block of step {self.blocks - 1})" if self.blocks else f"{self.label}: {err}") from None
        motors = self.state.motors
        self._held = (t, _block_sensors(readings), self.encoders.count(motors) if self.encoders is not None else None)
        return WheelSpeeds(wheel_speed(motors[0]), wheel_speed(motors[1]))

    def finish(self, readings: Readings) -> None:
        """Send the block of the run's last step (with the ticks of its motion, `readings` the
        final sample's) and read the reply, as c't-Sim does before it removes a bot; the link
        stays open for `close`. A firmware that fails now only ends in an event."""
        if self.link is None or self.link.closed or self._held is None:
            return
        try:
            self._exchange(readings)
        except LinkError as err:
            self.events.append(Event(self.blocks - 1, self._held[0], "log", f"no reply to the last block: {err}"))
        self._held = None

    def _exchange(self, after: Readings) -> None:
        """Block of the held step (its sensors, the ticks of the motion since, in `after`), then
        the firmware's reply to it."""
        if self.state.removed or self._held is None:
            return
        t, before, ticks = self._held
        step = self.blocks
        self.link.send(self._block(step, t, before, after, ticks), self.step_timeout)
        self.blocks += 1
        for packet in self.link.receive(self.step_timeout):
            self._handle(packet, step, t)

    def _packet(self, command: str, dl: int = 0, dr: int = 0, sub: str = p.NORM, payload: bytes = b"", to: int | None = None) -> Packet:
        packet = Packet(command, sub, dl, dr, self.seq, p.SIM, self.state.address if to is None else to, payload)
        self.seq = (self.seq + 1) & 0xFF
        return packet

    def _block(self, step: int, t: float, readings: Readings, after: Readings, ticks: tuple[int, int] | None = None) -> bytes:
        """One step's packets (`m D B H I R T L E S b e X`, orders and offers first), one write:
        the sensors of `readings`, the encoder ticks (or `ticks`) and mouse dots of `after` (the
        motion that followed). The first block is c't-Sim's from before its first step: sensors
        0, DONE -1."""
        packets = self._extra
        self._extra = []
        if step == 0:
            packets += [self._packet(command, *(ERROR_OK if command == p.SENS_ERROR else (0, 0))) for command in BLOCK]
            packets.append(self._packet(p.DONE, dl=-1))
            return b"".join(packet.encode() for packet in packets)
        key = self.rc5.pop(0)[1] if self.rc5 and self.rc5[0][0] <= t + 1e-9 else 0  # one key per block
        if key:
            self.state.rc5_toggle ^= 1  # c't-Sim flips it per key and sends it in every block
        if self.list_calls and step == 1:
            packets.append(self._packet(p.REMOTE_CALL, sub=p.RC_LIST))
        for call in self.calls:
            if call.sent_step is None and call.at <= t + 1e-9:
                call.sent_step = step
                packets.append(self._packet(p.REMOTE_CALL, sub=p.RC_ORDER, payload=p.remote_call_payload(call.name, call.args)))
                self.events.append(Event(step, t, "call", f"sent {call.text}"))
        state = {p.SENS_DOOR: (int(self.state.door_open), 0), p.SENS_RC5: (key, self.state.rc5_toggle), p.SENS_TRANS: (0, 0),
                 p.SENS_CAM: (CAM_POSITION, 0), p.SENS_BPS: (BPS_NONE - 0x10000, 0), p.SENS_ERROR: ERROR_OK}  # fmt: skip
        if ticks is not None:  # (the firmware's own encoder model's, in place of the world's)
            state[p.SENS_ENC] = ticks
        packets += [self._packet(command, *(state[command] if command in state else _sensor_pair(BY_PACKET[command], readings, after))) for command in BLOCK]
        packets.append(self._packet(p.DONE, dl=round((t + self.dt) * 1000) % 10000))
        return b"".join(packet.encode() for packet in packets)

    # --- the firmware's reply ---------------------------------------------------------------

    def _handle(self, packet: Packet, step: int, t: float) -> None:
        state = self.state
        key = packet.key
        if packet.command == p.ACT_MOT:
            if state.address != p.BROADCAST and packet.sender not in (state.address, p.BROADCAST):
                raise LinkError(f"a motor packet from address {packet.sender} (0x{packet.sender:02x}), not this bot's {state.address}: refused")
            state.motors = (packet.data_l, packet.data_r)
        elif packet.command == p.ACT_LED:
            state.leds = packet.data_l & 0xFF
        elif packet.command == p.ACT_LCD:
            self._lcd(packet, step, t)
        elif packet.command == p.LOG:
            self.events.append(Event(step, t, "log", _text(packet.payload)))
        elif packet.command == p.ACT_SERVO:
            state.door_open = packet.data_l >= DOOR_OPEN_FROM
        elif packet.command == p.MAP:
            state.map.add(packet)
            if packet.sub in (p.MAP_POS_X, p.MAP_POS_Y, p.MAP_HEADING):
                self._map_pose(packet)
        elif key == f"{p.ID}/{p.ID_REQUEST}":
            self._extra.append(self._packet(p.ID, self.offer, sub=p.ID_OFFER, to=p.BROADCAST))
        elif key == f"{p.ID}/{p.ID_SET}":
            state.address = packet.data_l & 0xFF
        elif packet.command == p.WELCOME:
            state.features = packet.data_l
        elif key == f"{p.REMOTE_CALL}/{p.RC_DONE}":
            self._call_done(packet, step, t)
        elif key == f"{p.REMOTE_CALL}/{p.RC_ENTRY}":
            entry = p.remote_call_entry(packet.payload)
            if entry:
                state.functions.append(entry)
            else:
                state.functions_complete = True
                self.events.append(Event(step, t, "call", "offers " + ", ".join(state.functions)))
        elif packet.command == p.SHUTDOWN:
            state.removed, state.motors = True, (0, 0)
            self.events.append(Event(step, t, "log", "the firmware asked to be removed (RC5 I/II); it stands still from here"))
            self.close()
        if packet.sender not in (p.BROADCAST, p.SIM) and state.address == p.BROADCAST:
            state.address = packet.sender  # a bot started with a fixed address (-a N)

    def _lcd(self, packet: Packet, step: int, t: float) -> None:
        state = self.state
        if packet.sub == p.LCD_CLEAR:
            state.lcd = [[" "] * 20 for _ in range(4)]
        elif packet.sub in (p.LCD_CURSOR, p.LCD_DATA):
            state.cursor = (packet.data_l, packet.data_r)
        if packet.sub == p.LCD_DATA:
            col, row = state.cursor
            before = state.lcd_text
            for ch in _text(packet.payload):
                if 0 <= row < 4 and 0 <= col < 20:
                    state.lcd[row][col] = ch
                col += 1
            state.cursor = (col, row)
            if state.lcd_text != before:
                self.events.append(Event(step, t, "lcd", state.lcd_text))

    def _map_pose(self, packet: Packet) -> None:
        """The pose the firmware believes in, sent with each map block: x, y on its 8 mm map grid
        (mm = cell * 8 - 6144, origin at its start) and its heading in degrees."""
        x, y, heading = self.state.map_pose or (0.0, 0.0, 0.0)
        if packet.sub == p.MAP_POS_X:
            x = (packet.data_r * MAP_MM_PER_CELL - MAP_ORIGIN_MM) / 1000
        elif packet.sub == p.MAP_POS_Y:
            y = (packet.data_r * MAP_MM_PER_CELL - MAP_ORIGIN_MM) / 1000
        else:
            heading = math.radians(packet.data_r)
        self.state.map_pose = (x, y, heading)

    def _call_done(self, packet: Packet, step: int, t: float) -> None:
        name = _text(packet.payload)
        for call in self.calls:
            if call.name == name and call.sent_step is not None and call.result is None:
                call.done_step, call.result = step, packet.data_l
                break
        self.events.append(Event(step, t, "call", f"{name} finished with result {packet.data_l}"))

    def close(self) -> None:
        """Ask the firmware to shut down (it exits 0 on SHUTDOWN) and close the link."""
        if self.link is not None and not self.link.closed:
            try:
                self.link.send(self._packet(p.SHUTDOWN).encode(), 1.0)
            except LinkError:
                pass
            self.link.close()

    def summary(self) -> dict:
        """Plain data for summary.json: address, the remote calls it offers (if asked) and those
        sent with their results."""
        return {
            "label": self.label,
            "address": self.state.address,
            "steps": self.blocks,
            "functions": self.state.functions,
            "calls": [{"call": c.text, "at": c.at, "sent_step": c.sent_step, "done_step": c.done_step, "result": c.result} for c in self.calls],
            "lcd": self.state.lcd_text,
            "map_blocks": self.state.map.blocks,
        }


BY_PACKET = {getattr(p, kind.packet): kind for kind in KINDS if kind.packet is not None}
"""The sensor registry's kinds by the command letter of their packet."""


def _block_sensors(readings: Readings) -> Readings:
    """The readings a block sends besides ticks and dots, copied: they go out a step later, and a
    run may reuse the arrays behind a sample's readings."""
    return Readings(readings.time, **{kind.field: getattr(readings, kind.field).copy() for kind in KINDS if kind.section and kind.packet})


def _sensor_pair(kind: SensorKind, readings: Readings, after: Readings) -> tuple[int, int]:
    """What a registry kind's packet carries: a list of sensors' first two values at the step's
    start (`readings`; the kind's `idle` where the robot has fewer), counts' of the motion that
    followed (`after`), as the kind's `wire` names its channels where it does."""
    values = getattr(readings if kind.section is not None else after, kind.field)
    if kind.wire is not None:
        left, right = ((-1 if name.startswith("-") else 1) * int(values[kind.channels.index(name.removeprefix("-"))]) for name in kind.wire)
        return left, right
    v = [int(x) for x in values[:2]] + list(kind.idle[len(values[:2]) :])
    return v[0], v[1]


class FirmwareEstimator:
    """The pose the firmware itself believes in (its map packets), in world coordinates: an
    estimator beside ctsim's own, for the comparison. It updates when the firmware sends a map
    block (8 mm grid, whole degrees) and holds the last pose in between."""

    def __init__(self, controller: FirmwareController, name: str = "reported"):
        self.controller = controller
        self.name = name

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        self.start = np.array(pose, dtype=np.float64)
        self.pose = self.start.copy()

    def update(self, readings: Readings) -> None:
        reported = self.controller.state.map_pose
        if reported is None:
            return
        x, y, heading = reported
        c, s = math.cos(self.start[2]), math.sin(self.start[2])
        turn = self.start[2] + heading - self.pose[2]
        self.pose = np.array((self.start[0] + c * x - s * y, self.start[1] + s * x + c * y, self.pose[2] + math.remainder(turn, math.tau)))


def _text(payload: bytes) -> str:
    return payload.split(b"\0", 1)[0].decode("latin-1")
