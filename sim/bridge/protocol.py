"""c't-Sim's TCP protocol as the c't-Bot firmware speaks it (ctbot-protocol.md §3, §8): packets,
their encoding, a decoder that survives garbage, and the firmware's codes.

A packet is a 12-byte header, little-endian: '>' command subcommand(bits 0-6, bit 7 direction = 0)
payload-length data_l(int16) data_r(int16) seq from to '<', then `payload` bytes. Pure bytes in,
bytes out: no sockets here.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, replace

HEADER = struct.Struct("<cBBBhhBBBc")
HEADER_SIZE = HEADER.size  # 12
START, STOP = b">", b"<"
SIM = 0xFE
"""The simulator's address."""
BROADCAST = 0xFF
"""A bot's address until it has one; also 'to everyone'."""
ADDRESS_POOL = range(128, 192)
"""Addresses c't-Sim offers to bots that ask (DefaultController.generateBotId)."""

NORM = "N"
# sim -> bot sensor commands
SENS_IR, SENS_ENC, SENS_BORDER, SENS_LINE, SENS_LDR = "I", "E", "B", "L", "H"
SENS_TRANS, SENS_DOOR, SENS_MOUSE, SENS_ERROR, SENS_RC5, SENS_BPS, SENS_CAM = "T", "D", "m", "e", "R", "b", "S"
DONE, WELCOME, ID, REMOTE_CALL, SHUTDOWN = "X", "W", "A", "r", "q"
# bot -> sim
ACT_MOT, ACT_LED, ACT_LCD, ACT_SERVO, LOG, MAP = "M", "l", "c", "S", "O", "Q"
# subcommands
WELCOME_SIM = "S"
ID_REQUEST, ID_OFFER, ID_SET = "R", "O", "S"
RC_LIST, RC_ENTRY, RC_ORDER, RC_DONE, RC_ABORT = "L", "E", "O", "D", "A"
LCD_CLEAR, LCD_CURSOR, LCD_DATA = "c", "C", "D"
MAP_POS_X, MAP_POS_Y, MAP_HEADING, MAP_LAST_PART = "D", "E", "F", "G"
"""The four parts of a map block; the first three also carry the firmware's pose."""

REMOTE_CALL_BUFFER = 33
"""The firmware's stack buffer for a remote-call payload (bytes); longer ones overflow it."""

RC5_KEYS: dict[str, int] = {
    **{str(d): 0x1180 + d for d in range(10)},
    "PWR": 0x118C, "PLAY": 0x11B5, "UP": 0x11A9, "DOWN": 0x11B6, "LEFT": 0x11B2, "RIGHT": 0x11B4,
    "I/II": 0x11AB, "CH+": 0x11A0, "CH-": 0x11A1, "VOL+": 0x1190, "VOL-": 0x1191,
}  # fmt: skip
"""RC5 codes of c't-Sim's default remote (RC_HAVE_HQ_RC_UNIVERS29_334) by key name."""

LED_NAMES = ("blue_right", "blue_left", "red", "orange", "yellow", "green", "turquoise", "white")
"""The c't-Bot's LEDs by bit of ACT_LED's data_l."""


class ProtocolError(ValueError):
    """Bytes that are not a packet (the message says what is wrong with them)."""


@dataclass(frozen=True)
class Packet:
    """One command: command and subcommand letters, two int16 data fields, sequence number,
    sender and receiver addresses, and an optional payload (at most 255 bytes)."""

    command: str
    sub: str = NORM
    data_l: int = 0
    data_r: int = 0
    seq: int = 0
    sender: int = SIM
    to: int = BROADCAST
    payload: bytes = b""

    def encode(self) -> bytes:
        """The packet on the wire: header, then payload."""
        if len(self.payload) > 255:
            raise ProtocolError(f"payload of {len(self.payload)} bytes; at most 255 fit the length byte")
        return (
            HEADER.pack(
                START, ord(self.command), ord(self.sub) & 0x7F, len(self.payload), _int16(self.data_l), _int16(self.data_r),
                self.seq & 0xFF, self.sender, self.to, STOP,
            )
            + self.payload
        )  # fmt: skip

    @property
    def key(self) -> str:
        """Command and subcommand, e.g. 'r/D'."""
        return f"{self.command}/{self.sub}"


def _int16(value: int) -> int:
    """Saturate to int16 (sensor values never need more; a wrap would flip a sign)."""
    return max(-32768, min(32767, int(value)))


def decode_header(header: bytes) -> Packet:
    """A packet without its payload from exactly 12 header bytes; ProtocolError if malformed."""
    if len(header) != HEADER_SIZE:
        raise ProtocolError(f"a header has {HEADER_SIZE} bytes, got {len(header)}")
    start, command, sub, length, dl, dr, seq, sender, to, stop = HEADER.unpack(header)
    if start != START or stop != STOP:
        raise ProtocolError(f"bad framing {header.hex(' ')} (expected '>' ... '<')")
    if not (0x20 < command < 0x7F and 0x20 < (sub & 0x7F) < 0x7F):
        raise ProtocolError(f"command code {command:#04x}/{sub:#04x} is not a letter")
    return Packet(chr(command), chr(sub & 0x7F), dl, dr, seq, sender, to, b"\0" * length)


class Decoder:
    """Turns a byte stream into packets, at command granularity whatever the chunking. Like the
    firmware, it skips bytes up to a '>' and drops a 12-byte window whose stop byte is not '<';
    the skipped bytes are counted and the last problem kept for the error message."""

    def __init__(self) -> None:
        self.buffer = bytearray()
        self.skipped = 0
        self.problem: str | None = None

    def feed(self, data: bytes) -> list[Packet]:
        """Add received bytes; return the packets completed by them."""
        self.buffer += data
        out = []
        while True:
            start = self.buffer.find(START)
            if start < 0:
                self._skip(len(self.buffer), "bytes without a start code '>'")
                return out
            if start:
                self._skip(start, "bytes before a start code '>'")
            if len(self.buffer) < HEADER_SIZE:
                return out
            try:
                packet = decode_header(bytes(self.buffer[:HEADER_SIZE]))
            except ProtocolError as err:
                self._skip(1, str(err))
                continue
            end = HEADER_SIZE + len(packet.payload)
            if len(self.buffer) < end:
                return out
            out.append(replace(packet, payload=bytes(self.buffer[HEADER_SIZE:end])))
            del self.buffer[:end]

    def _skip(self, n: int, why: str) -> None:
        if n:
            self.skipped += n
            self.problem = why
            del self.buffer[:n]


def remote_call_payload(name: str, args: tuple[int, ...] = ()) -> bytes:
    """An r/O order's payload: name, NUL, one int32 LE per parameter; must fit the firmware's
    33-byte buffer."""
    payload = name.encode("ascii") + b"\0" + b"".join(struct.pack("<i", int(a)) for a in args)
    if len(payload) > REMOTE_CALL_BUFFER:
        raise ProtocolError(f"remote call {name}{tuple(args)} needs {len(payload)} bytes; the firmware reads at most {REMOTE_CALL_BUFFER}")
    return payload


def parse_call(text: str) -> tuple[str, tuple[int, ...]]:
    """'bot_turn(90)' -> ('bot_turn', (90,)); integers only, as the firmware's parameters."""
    text = text.strip()
    name, sep, rest = text.partition("(")
    name = name.strip()
    if not name.isidentifier() or (sep and not rest.endswith(")")):
        raise ValueError(f"expected a call like bot_turn(90), got {text!r}")
    inner = rest[:-1].strip() if sep else ""
    try:
        args = tuple(int(a, 0) for a in inner.split(",")) if inner else ()
    except ValueError:
        raise ValueError(f"{text!r}: parameters must be integers") from None
    remote_call_payload(name, args)
    return name, args


def rc5_code(key: str) -> int:
    """The RC5 code of a key name ('3', 'PWR', 'UP', ...) or a number such as 0x1183."""
    upper = key.strip().upper()
    if upper in RC5_KEYS:
        return RC5_KEYS[upper]
    try:
        return int(upper, 0)
    except ValueError:
        raise ValueError(f"unknown RC5 key {key!r} (keys: {', '.join(RC5_KEYS)} or a code like 0x1183)") from None


def remote_call_entry(payload: bytes) -> str:
    """An r/E entry as 'name(parameters)', '' for the list's empty end: the raw C struct,
    parameter count and lengths in bytes 0-3, name[21] at byte 4, parameter text[41] at 25."""
    name = payload[4:25].split(b"\0", 1)[0].decode("ascii", "replace")
    params = payload[25:66].split(b"\0", 1)[0].decode("ascii", "replace")
    return f"{name}({params})" if name else ""
