"""Headless Chromium for tests that look at a page as a person would (Debian's `chromium`).

Chromium's own `--screenshot` shoots as soon as the page has loaded, before rerun's viewer has
compiled its wasm and drawn anything. So it is driven through the DevTools protocol over a pipe
(`--remote-debugging-pipe`: JSON messages ended by a NUL byte on file descriptors 3 and 4), which
needs no websocket library: open a page, then take screenshots until one shows what is wanted.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--remote-debugging-pipe",
    "--use-gl=swiftshader", "--enable-unsafe-swiftshader",  # WebGL in software: rerun's viewer draws with it
    "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",  # this machine only (the page asks for web fonts)
)  # fmt: skip


def chromium() -> str | None:
    """The Chromium executable, or None where none is installed."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


class Browser:
    """One headless Chromium with one page; `with Browser() as b: b.open(url); b.screenshot()`."""

    def __init__(self, width: int = 1600, height: int = 1000):
        self._profile = tempfile.TemporaryDirectory()
        to_chrome, self._send = os.pipe()
        self._receive, from_chrome = os.pipe()

        def give_pipes() -> None:  # in the child: its ends as fds 3 (commands in) and 4 (answers out)
            ours = os.dup(to_chrome), os.dup(from_chrome)
            os.dup2(ours[0], 3)
            os.dup2(ours[1], 4)

        command = [chromium(), *FLAGS, f"--user-data-dir={self._profile.name}", f"--window-size={width},{height}", "about:blank"]
        self.process = subprocess.Popen(command, preexec_fn=give_pipes, close_fds=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_chrome)
        os.close(from_chrome)
        self._buffer = b""
        self._id = 0
        self._session: str | None = None

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def call(self, method: str, **params: object) -> dict:
        """One DevTools command (to the page once one is open); its result."""
        self._id += 1
        message = {"id": self._id, "method": method, "params": params}
        if self._session and not method.startswith(("Target.", "Browser.")):
            message["sessionId"] = self._session
        os.write(self._send, json.dumps(message).encode() + b"\0")
        while True:
            while b"\0" not in self._buffer:
                chunk = os.read(self._receive, 1 << 20)
                if not chunk:
                    raise RuntimeError(f"chromium closed its pipe (exit status {self.process.poll()})")
                self._buffer += chunk
            raw, self._buffer = self._buffer.split(b"\0", 1)
            answer = json.loads(raw)
            if answer.get("id") == self._id:
                if "error" in answer:
                    raise RuntimeError(f"{method}: {answer['error']}")
                return answer["result"]

    def open(self, url: str) -> None:
        target = self.call("Target.createTarget", url=url)["targetId"]
        self._session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]

    def screenshot(self) -> np.ndarray:
        """The page as an (h, w, 3) uint8 RGB array."""
        import matplotlib.image

        png = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        with tempfile.NamedTemporaryFile(suffix=".png") as file:
            Path(file.name).write_bytes(png)
            return (matplotlib.image.imread(file.name)[..., :3] * 255).round().astype(np.uint8)

    def wait_for(self, drawn: Callable[[np.ndarray], bool], limit_s: float, every_s: float = 2.0) -> np.ndarray:
        """Screenshots until `drawn(image)`; the last one either way (the caller asserts on it)."""
        deadline = time.monotonic() + limit_s
        while True:
            image = self.screenshot()
            if drawn(image) or time.monotonic() > deadline:
                return image
            time.sleep(every_s)

    def close(self) -> None:
        if self.process.poll() is None:
            try:
                self.call("Browser.close")
            except (RuntimeError, OSError):
                pass
            try:
                self.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        os.close(self._send)
        os.close(self._receive)
        self._profile.cleanup()


def share_of(image: np.ndarray, rgb: tuple[int, int, int]) -> float:
    """Fraction of the image's pixels that are exactly `rgb`."""
    return float(np.all(image == np.asarray(rgb, dtype=np.uint8), axis=-1).mean())
