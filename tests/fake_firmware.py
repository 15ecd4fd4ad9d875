"""A fake c't-Bot firmware written from ctbot-protocol.md (§4-§8), for testing the bridge.

It speaks the wire format with its own encoder (not the bridge's), so a test checks both sides
against the spec: unsolicited W/S on connect (unless `handshake=False`), W/S + A/R + DONE as its
first reply when the sim sent a WELCOME, A/S once offered an address, then `l M [c/D] [Q/D..G] X`
per block (a map block around its pose every `map_every` blocks). It integrates the encoder
deltas like the firmware (2.9688 mm per tick, 97.2 mm track) and acts on RC5 keys 1/3/PWR (motors
from the next reply), the remote call bot_turn(deg) (motors in the same reply, r/D 1 when its
encoder heading reaches the angle) and the list request r/L. `misbehave` makes it stall, vanish,
babble garbage or flood at a given step.

    python tests/fake_firmware.py --port 10001     # a peer for `ctsim bridge` by hand or in bench
"""

from __future__ import annotations

import argparse
import math
import socket
import struct
import threading
import time

HEADER = struct.Struct("<cBBBhhBBBc")
MM_PER_TICK = 178.1283 / 60
TRACK_MM = 97.2
KEYS = {0x1181: (25, 25), 0x1183: (75, 75), 0x118C: (0, 0)}


def packet(cmd: str, sub: str = "N", dl: int = 0, dr: int = 0, seq: int = 0, frm: int = 0xFF, to: int = 0xFE, payload: bytes = b"") -> bytes:
    return HEADER.pack(b">", ord(cmd), ord(sub), len(payload), dl, dr, seq & 0xFF, frm, to, b"<") + payload


class FakeFirmware:
    """Connects to `port` and answers blocks until the sim sends SHUTDOWN or closes.

    misbehave: (step, what) with what in 'stall' (never answer again), 'vanish' (close),
    'garbage' (junk bytes in the reply), 'flood' (bytes without end), or None."""

    def __init__(self, port: int, handshake: bool = True, address: int | None = None, misbehave: tuple[int, str] | None = None, map_every: int = 10,
                 on_shutdown=None, host: str = "127.0.0.1"):  # fmt: skip
        self.host = host
        self.port, self.handshake, self.fixed_address, self.misbehave, self.map_every = port, handshake, address, misbehave, map_every
        self.on_shutdown = on_shutdown  # called when SHUTDOWN arrives (a test looks at what exists then)
        self.address = address if address is not None else 0xFF
        self.seq = 0
        self.blocks: list[list[tuple]] = []  # every received packet, grouped by block
        self.motors = (0, 0)
        self.next_motors: tuple[int, int] | None = None
        self.pose = [0.0, 0.0, 0.0]  # mm, mm, rad from the encoders
        self.turn: tuple[float, str] | None = None
        self.welcomed = False
        self._pending_set = False
        self.shutdown = False
        self.done_times: list[int] = []
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._guarded, daemon=True)

    def start(self) -> FakeFirmware:
        self.thread.start()
        return self

    def join(self, timeout: float = 10.0) -> None:
        self.thread.join(timeout)

    def _send(self, sock: socket.socket, parts: list[tuple]) -> None:
        data = b""
        for cmd, sub, dl, dr, payload in parts:
            self.seq += 1
            data += packet(cmd, sub, dl, dr, self.seq, self.address, 0xFE, payload)
        sock.sendall(data)

    def _guarded(self) -> None:
        try:
            self.run()
        except BaseException as err:  # noqa: BLE001 (reported to the test through .error)
            self.error = err

    def run(self) -> None:
        deadline = time.monotonic() + 10
        while True:
            try:
                sock = socket.create_connection((self.host, self.port), timeout=60)
                sock.settimeout(600)  # before its first block the sim may compile its kernels: minutes on a loaded machine
                break
            except ConnectionRefusedError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.02)
        buffer = b""
        with sock:
            if self.handshake:
                self._send(sock, [("W", "S", 0x32, 0, b"")])
            block: list[tuple] = []
            while not self.shutdown:
                data = sock.recv(65536)
                if not data:
                    return
                buffer += data
                while len(buffer) >= 12:
                    start = buffer.find(b">")
                    if start < 0:
                        buffer = b""
                        break
                    buffer = buffer[start:]
                    if len(buffer) < 12:
                        break
                    _, cmd, sub, length, dl, dr, seq, frm, to, stop = HEADER.unpack(buffer[:12])
                    if len(buffer) < 12 + length:
                        break
                    payload, buffer = buffer[12 : 12 + length], buffer[12 + length :]
                    assert stop == b"<" and frm == 0xFE, f"bad packet {cmd:c} from {frm:#x}"
                    item = (chr(cmd), chr(sub), dl, dr, to, payload)
                    if chr(cmd) == "W":
                        self.welcomed = True
                        continue
                    if chr(cmd) == "A" and chr(sub) == "O" and self.address == 0xFF:
                        self.address = dl
                        self._pending_set = True
                        continue
                    if chr(cmd) == "q":
                        self.shutdown = True
                        if self.on_shutdown is not None:
                            self.on_shutdown()
                        return
                    block.append(item)
                    if chr(cmd) == "X":
                        if to not in (0xFF, self.address):
                            block = []
                            continue  # a DONE to another address is dropped, like the firmware does
                        self.blocks.append(block)
                        block = []
                        if not self._reply(sock, dl):
                            return

    def _reply(self, sock: socket.socket, time_ms: int) -> bool:
        """Answer the last block; False to stop."""
        n = len(self.blocks) - 1
        if self.misbehave and self.misbehave[0] == n:
            what = self.misbehave[1]
            if what == "stall":  # keep reading, never answer, until the sim hangs up
                sock.settimeout(30)
                while sock.recv(65536):
                    pass
                return False
            if what == "vanish":
                return False
            if what == "garbage":
                sock.sendall(b"\x00garbage-not-a-packet" * 3)
            if what == "foreign":  # motors from another bot's address, on this bot's link
                sock.sendall(packet("M", "N", 50, 50, 0, (self.address + 7) & 0xFF, 0xFE))
            if what == "flood":
                try:
                    sock.sendall(b"x" * (2 << 20))
                except OSError:
                    pass  # the sim stopped reading and hung up: what a flood gets
                return False
        block = {cmd: (dl, dr, payload) for cmd, sub, dl, dr, to, payload in self.blocks[-1]}
        self.done_times.append(time_ms)
        if "E" in block:
            left, right = block["E"][0] * MM_PER_TICK, block["E"][1] * MM_PER_TICK
            d, a = (left + right) / 2, (right - left) / TRACK_MM
            self.pose[0] += d * math.cos(self.pose[2] + a / 2)
            self.pose[1] += d * math.sin(self.pose[2] + a / 2)
            self.pose[2] += a
        parts: list[tuple] = []
        if n == 0 and self.welcomed:  # the first reply: re-register and ask for an address
            parts += [("W", "S", 0x32, 0, b"")] + ([("A", "R", 0, 0, b"")] if self.fixed_address is None else [])
            parts.append(("X", "N", time_ms, 0, b""))
            self._send(sock, parts)
            return True
        if self._pending_set:
            self._pending_set = False
            parts.append(("A", "S", self.address, 0, b""))
        if self.next_motors is not None:  # a key of the last block acts now
            self.motors, self.next_motors = self.next_motors, None
        code = block.get("R", (0, 0, b""))[0] & 0xFFFF
        if code in KEYS:
            self.next_motors = KEYS[code]
        for cmd, sub, _dl, _dr, _to, payload in self.blocks[-1]:
            if cmd == "r" and sub == "O":
                name, _, args = payload.partition(b"\0")
                if name == b"bot_turn":
                    (degrees,) = struct.unpack("<i", args[:4])
                    self.turn = (self.pose[2] + math.radians(degrees), "bot_turn")
                    self.motors = (-25, 25) if degrees > 0 else (25, -25)
            if cmd == "r" and sub == "L":  # one entry, then the empty one that ends the list
                entry = bytes([1, 2, 0, 0]) + b"bot_turn".ljust(21, b"\0") + b"int16 degrees".ljust(41, b"\0") + b"\0" * 22
                parts += [("r", "E", 0, 0, entry), ("r", "E", 0, 0, b"\0" * 88)]
        if self.turn is not None:
            target, name = self.turn
            direction = 1 if self.motors[1] > self.motors[0] else -1
            if direction * (self.pose[2] - target) >= 0:  # the encoder heading reached the angle
                parts.append(("r", "D", 1, 1, name.encode()))
                self.motors, self.turn = (0, 0), None
        parts.append(("l", "N", 8, 0, b""))
        parts.append(("M", "N", *self.motors, b""))
        if n % 11 == 0:
            parts.append(("c", "D", 0, 0, f"step {n}".encode()))
        if self.map_every and n % self.map_every == 0:
            parts += self._map_block()
        parts.append(("X", "N", time_ms, 0, b""))
        self._send(sock, parts)
        return True


    def _map_block(self) -> list[tuple]:
        """The map block under the bot as the firmware sends it (ctbot-protocol.md §5), the
        bot's own cell marked driven (+100), the others unknown: block address from the map
        cell as the firmware's `get_block` (map.c) computes it, cell (x, y) at byte
        (x % 32) * 16 + y % 16 of the block (two 16 x 16 sections along x, each x-major)."""
        x, y = (round((v + 6144) / 8) for v in self.pose[:2])
        local = (x % 512) // 32 + ((y % 512) // 16) * 16
        block = local + (x // 512 + (y // 512) * 3) * 512
        data = bytearray(512)
        data[(x % 32) * 16 + y % 16] = 100
        sub_pose = [("D", x), ("E", y), ("F", round(math.degrees(self.pose[2]))), ("G", 0)]
        return [("Q", sub, block, value, bytes(data[k * 128 : (k + 1) * 128])) for k, (sub, value) in enumerate(sub_pose)]


def main() -> None:
    parser = argparse.ArgumentParser(description="A fake c't-Bot firmware for `ctsim bridge` (tests, benchmarks).")
    parser.add_argument("--port", type=int, default=10001)
    parser.add_argument("-t", dest="host", default="127.0.0.1", help="the sim's host, as the firmware's -t option")
    args = parser.parse_args()
    fake = FakeFirmware(args.port, map_every=0, host=args.host)
    fake.run()


if __name__ == "__main__":
    main()
