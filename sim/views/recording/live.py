"""The live view beside the file: a second stream to a rerun viewer that is missing or goes away at
the cost of the live view only, with one line on stderr."""

from __future__ import annotations

import socket
import sys
import time
from typing import Any
from urllib.parse import urlsplit

LIVE_PORT = 9876
"""Port of a viewer that `--live` spawns (rerun's default)."""
LIVE_WAIT_S = 10.0
"""How long to wait for a spawned viewer to listen, and for a live chunk to reach the viewer."""
LIVE_EVERY_S = 0.5
"""Wall-clock seconds after which a live view gets what is buffered, full chunk or not: a run
paced at real time (`ctsim bridge --realtime`) fills a chunk only every 80 s."""


def listening(url: str, wait_s: float) -> bool:
    """Whether something accepts TCP connections at the URL's host and port, trying for up to
    `wait_s` seconds (a spawned viewer takes a moment to listen)."""
    parts = urlsplit(url)
    host, port = parts.hostname or "127.0.0.1", parts.port or LIVE_PORT
    deadline = time.monotonic() + wait_s
    while True:
        try:
            with socket.create_connection((host, port), timeout=1.0):
                return True
        except OSError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.2)


class LiveStream:
    """The live view's part of a `Recorder`: the second stream, opened beside the file's, checked
    as chunks go out, and given up (with one line) when the viewer is missing or goes away."""

    def _open_live(self, rr: Any, blueprint: Any) -> None:
        """A second stream to the viewer at `connect` (or one spawned here), sharing the file's
        recording id; if no viewer answers, say so and record to the file alone."""
        url = self.connect or f"rerun+http://127.0.0.1:{LIVE_PORT}/proxy"
        same = {"recording_id": self.streams[0].get_recording_id()} if self.streams else {}
        live = rr.RecordingStream(self.application_id, send_properties=False, **same)
        wait = 0.0
        if self.connect is None:
            try:  # spawned for this stream: rerun ignores a spawn without an active recording
                live.spawn(port=LIVE_PORT, connect=False, hide_welcome_screen=True)
            except Exception as err:  # no viewer executable, no display: the file still counts
                return self._lose_live(f"could not start a rerun viewer ({err})")
            wait = LIVE_WAIT_S
        if not listening(url, wait):
            return self._lose_live(f"no rerun viewer answers at {url}")
        live.set_sinks(rr.GrpcSink(url), default_blueprint=blueprint)
        self._live = live
        self.streams.append(live)

    def _check_live(self) -> None:
        """Wait for the live stream to deliver what it has; a viewer that went away or stalls
        ends the live view, never the run."""
        self._live_due = time.monotonic() + LIVE_EVERY_S
        try:
            self._live.flush(timeout_sec=LIVE_WAIT_S)
        except Exception as err:  # rerun raises RuntimeError with gRPC's own words
            self.streams.remove(self._live)
            self._live = None
            self._lose_live(f"the rerun viewer stopped taking data ({str(err).splitlines()[0]})")

    def _lose_live(self, why: str) -> None:
        self.live_lost = why
        target = f"; still recording to {self.path}" if self.path is not None else ""
        print(f"ctsim: live view off: {why}{target}", file=sys.stderr)
