"""The TCP side of the bridge: a listening socket the firmware connects to, and one link per bot
that writes a step's block in one `sendall` and reads the bot's reply up to its DONE.

Every socket has a timeout; a peer that stalls, vanishes, floods or sends bytes that are not
packets raises `LinkError` with a message for the user. Packets that arrive after a DONE (the
firmware's map thread can straddle one) are kept for the next reply.
"""

from __future__ import annotations

import socket
import time

from sim.bridge.protocol import DONE, Decoder, Packet
from sim.errors import UserError

MAX_REPLY_BYTES = 1 << 20
"""A reply longer than this without a DONE is a flood, not a firmware (its send buffer is 4 KB)."""


class LinkError(ConnectionError):
    """A bot connection that failed: closed, silent past its timeout, or talking garbage."""


class Listener:
    """A listening TCP socket, bound at construction so the firmware can be started right after.
    `port` 0 picks a free port (tests); `host` defaults to loopback only."""

    def __init__(self, host: str = "127.0.0.1", port: int = 10001):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self.sock.bind((host, port))
        except OSError as err:
            self.sock.close()
            raise UserError(f"cannot listen on {host}:{port}: {err.strerror or err}") from None
        self.sock.listen(8)
        self.host, self.port = self.sock.getsockname()[:2]

    def accept(self, timeout: float) -> Link:
        """The next bot that connects within `timeout` seconds."""
        self.sock.settimeout(timeout)
        try:
            conn, peer = self.sock.accept()
        except TimeoutError:
            raise LinkError(f"no firmware connected to {self.host}:{self.port} within {timeout:g} s") from None
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return Link(conn, peer)

    def close(self) -> None:
        self.sock.close()


class Link:
    """One bot's connection."""

    def __init__(self, sock: socket.socket, peer: tuple = ("?", 0)):
        self.sock = sock
        self.peer = peer
        self.decoder = Decoder()
        self.pending: list[Packet] = []
        self.closed = False

    def send(self, data: bytes, timeout: float) -> None:
        """Write `data` in one piece (the firmware reads a payload with a single recv)."""
        self.sock.settimeout(timeout)
        try:
            self.sock.sendall(data)
        except TimeoutError:
            raise LinkError(f"the firmware took no data for {timeout:g} s (it does not read)") from None
        except OSError as err:
            raise LinkError(f"the connection broke while sending ({err.strerror or err})") from None

    def receive(self, timeout: float) -> list[Packet]:
        """The bot's packets up to and including its next DONE, waiting at most `timeout` s."""
        deadline = time.monotonic() + timeout
        received = 0
        while True:
            for k, packet in enumerate(self.pending):
                if packet.command == DONE:
                    reply, self.pending = self.pending[: k + 1], self.pending[k + 1 :]
                    return reply
            left = deadline - time.monotonic()
            if left <= 0:
                raise LinkError(f"no DONE from the firmware within {timeout:g} s (it hangs or runs too slowly)")
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            except OSError as err:
                raise LinkError(f"the connection broke ({err.strerror or err})") from None
            if not data:
                self.closed = True
                raise LinkError("the firmware closed the connection (it exited or crashed)")
            received += len(data)
            self.pending += self.decoder.feed(data)
            if self.decoder.skipped:
                raise LinkError(f"the firmware sent {self.decoder.skipped} bytes that are not packets ({self.decoder.problem})")
            if received > MAX_REPLY_BYTES:
                raise LinkError(f"the firmware sent {received} bytes without a DONE")

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self.sock.close()
