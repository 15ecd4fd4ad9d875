"""A c't-Bot firmware on the other end of a TCP link, as one more controller of the run loop.

Each step the controller reads the firmware's reply to the previous step's block (up to its DONE),
then sends this step's sensor block and returns the motors of that reply: the motors the firmware
chose for the block of step k drive the robot in step k+1, as in c't-Sim (which moves first and
transmits after). Sensors go out in firmware units (they already are: `Readings` holds the
devices' raw values) with two conversions at this edge: c't-Sim's mouse has its sideways axis the
other way round, and its DONE carries the time in ms modulo 10000. Motor values are mm/s ÷ 2,
which c't-Sim drives at 1.75788 mm/s per unit (ctbot-protocol.md §8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bots.commands import WheelSpeeds
from bots.controller import ControllerStopped, Status
from bots.spec import RobotSpec
from sim.bridge import protocol as p
from sim.bridge.protocol import Packet
from sim.bridge.server import Link, LinkError, Listener
from sim.world.readings import Readings

MM_S_PER_UNIT = 151 / 60 * 178.1283 / 255
"""c't-Sim's wheel speed per ACT_MOT unit (mm/s): PWM/255 of 151 rpm on a 178.1283 mm wheel."""
IR_NOTHING = (100, 80)
"""GP2D12 raw values with nothing in view (left, right), c't-Sim's curves beyond 85 cm."""
MAP_MM_PER_CELL, MAP_ORIGIN_MM = 8, 6144
"""The firmware's map grid (125 cells/m) and its centre, the start pose (map_to_world)."""
CAM_POSITION = 14
BPS_NONE = 0xFFFF
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
    """What the firmware has shown so far: LEDs, the 20x4 LCD, motors, its map pose, address."""

    address: int = p.BROADCAST
    features: int | None = None
    motors: tuple[int, int] = (0, 0)
    leds: int = 0
    lcd: list[list[str]] = field(default_factory=lambda: [[" "] * 20 for _ in range(4)])
    cursor: tuple[int, int] = (0, 0)
    map_pose: tuple[float, float, float] | None = None
    door_open: bool = False
    functions: list[str] = field(default_factory=list)
    removed: bool = False

    @property
    def lcd_text(self) -> str:
        return "\n".join("".join(row).rstrip() for row in self.lcd)


class FirmwareController:
    """The controller of one robot driven by a c't-Bot firmware over TCP (see the module doc).

    `rc5`: (time s, RC5 code) key presses; `calls`: (time s, 'bot_turn(90)') remote calls. The
    link is accepted from `listener` in the first step (after `connect_timeout` s: an error);
    each reply must end within `step_timeout` s."""

    def __init__(
        self,
        listener: Listener,
        label: str = "firmware bot",
        dt: float = 0.01,
        connect_timeout: float = 60.0,
        step_timeout: float = 10.0,
        welcome: bool = True,
        address: int = p.ADDRESS_POOL[0],
        rc5: tuple[tuple[float, int], ...] = (),
        calls: tuple[tuple[float, str], ...] = (),
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
        self.link: Link | None = None
        self.state = FirmwareState()
        self.events: list[Event] = []
        self.steps = 0
        self.seq = 0
        self.status = Status.RUNNING
        self._extra: list[Packet] = []

    def reset(self, robot: RobotSpec) -> None:
        self.robot = robot

    # --- one step ---------------------------------------------------------------------------

    def step(self, t: float, readings: Readings) -> WheelSpeeds:
        """Read the reply to the last block, send this step's block, return the reply's motors."""
        try:
            if self.link is None:
                self.link = self.listener.accept(self.connect_timeout)
                if self.welcome:
                    self.link.send(self._packet(p.WELCOME, to=0).encode(), self.step_timeout)
            elif not self.state.removed:
                for packet in self.link.receive(self.step_timeout):
                    self._handle(packet, t)
            if not self.state.removed:
                self.link.send(self._block(t, readings), self.step_timeout)
        except LinkError as err:
            raise BridgeError(f"{self.label}: {err} (reply to the block of step {self.steps - 1})" if self.steps else f"{self.label}: {err}") from None
        self.steps += 1
        left, right = self.state.motors
        return WheelSpeeds(left * MM_S_PER_UNIT / 1000, right * MM_S_PER_UNIT / 1000)

    def _packet(self, command: str, dl: int = 0, dr: int = 0, sub: str = p.NORM, payload: bytes = b"", to: int | None = None) -> Packet:
        packet = Packet(command, sub, dl, dr, self.seq, p.SIM, self.state.address if to is None else to, payload)
        self.seq = (self.seq + 1) & 0xFF
        return packet

    def _block(self, t: float, readings: Readings) -> bytes:
        """One step's packets (`m D B H I R T L E S b e X`, orders and offers first), one write."""

        forward, left = (int(x) for x in readings.mouse_counts)
        key = self.rc5.pop(0)[1] if self.rc5 and self.rc5[0][0] <= t + 1e-9 else 0  # one key per block
        packets = self._extra
        self._extra = []
        for call in self.calls:
            if call.sent_step is None and call.at <= t + 1e-9:
                call.sent_step = self.steps
                packets.append(self._packet(p.REMOTE_CALL, sub=p.RC_ORDER, payload=p.remote_call_payload(call.name, call.args)))
                self.events.append(Event(self.steps, t, "call", f"sent {call.text}"))
        packets += [
            self._packet(p.SENS_MOUSE, dl=-left, dr=forward),  # c't-Sim: dX sideways to the right, dY forward
            self._packet(p.SENS_DOOR, dl=int(self.state.door_open)),
            self._packet(p.SENS_BORDER, *_pair(readings.border, (0, 0))),
            self._packet(p.SENS_LDR, *_pair(readings.light, (1023, 1023))),
            self._packet(p.SENS_IR, *_pair(readings.ir_raw, IR_NOTHING)),
            self._packet(p.SENS_RC5, dl=key),
            self._packet(p.SENS_TRANS),
            self._packet(p.SENS_LINE, *_pair(readings.line, (0, 0))),
            self._packet(p.SENS_ENC, *_pair(readings.encoder_ticks, (0, 0))),
            self._packet(p.SENS_CAM, dl=CAM_POSITION),
            self._packet(p.SENS_BPS, dl=BPS_NONE - 0x10000),
            self._packet(p.SENS_ERROR, dl=1, dr=1),
            self._packet(p.DONE, dl=round((t + self.dt) * 1000) % 10000),
        ]
        return b"".join(packet.encode() for packet in packets)

    # --- the firmware's reply ---------------------------------------------------------------

    def _handle(self, packet: Packet, t: float) -> None:
        state, step = self.state, self.steps - 1
        key = packet.key
        if packet.command == p.ACT_MOT:
            state.motors = (packet.data_l, packet.data_r)
        elif packet.command == p.ACT_LED:
            state.leds = packet.data_l & 0xFF
        elif packet.command == p.ACT_LCD:
            self._lcd(packet, step, t)
        elif packet.command == p.LOG:
            self.events.append(Event(step, t, "log", _text(packet.payload)))
        elif packet.command == p.ACT_SERVO:
            state.door_open = packet.data_l >= DOOR_OPEN_FROM
        elif packet.command == p.MAP and packet.sub in (p.MAP_POS_X, p.MAP_POS_Y, p.MAP_HEADING):
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
            name = p.remote_call_entry_name(packet.payload)
            if name:
                state.functions.append(name)
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
        """Plain data for summary.json: address, functions, remote calls and their results."""
        return {
            "label": self.label,
            "address": self.state.address,
            "steps": self.steps,
            "functions": self.state.functions,
            "calls": [{"call": c.text, "at": c.at, "sent_step": c.sent_step, "done_step": c.done_step, "result": c.result} for c in self.calls],
            "lcd": self.state.lcd_text,
        }


def _pair(values: np.ndarray, default: tuple[int, int]) -> tuple[int, int]:
    """The first two values of a sensor group; the default where the robot has fewer sensors."""
    v = [int(x) for x in values[:2]] + list(default[len(values[:2]) :])
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
