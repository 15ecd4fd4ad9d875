"""Serve a recording and rerun's web viewer to a browser: `ctsim view` and `ctsim run --web`.

rerun's own command, shipped inside the rerun-sdk wheel, does the serving (`rerun --serve-web`):
a gRPC proxy that holds the recording (read from a `.rrd`, or streamed into it by a running
run) and an HTTP server for the viewer's page (HTML, JS, wasm) that connects the page to the
proxy. Both listen on the one address of `--bind`: 127.0.0.1 unless the user asks for another.
(The Python SDK's `rr.serve_web_viewer` cannot be told an address and listens on every one.)
The blueprint travels with the data, in the file or as the live stream's default, so the page
shows the native viewer's layout.
"""

from __future__ import annotations

import ctypes
import errno
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from urllib.parse import quote

from sim.analysis.run_folder import RunFolder
from sim.errors import UserError

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 9090
"""The page's port (rerun's default); the gRPC proxy listens on the next one."""
START_WAIT_S = 300.0
"""How long rerun's server may take to listen (it unpacks the viewer's assets first: 15 s were
seen on a loaded two-core machine); it ends sooner if rerun exits."""
MAGIC = b"RRF2"
"""The first bytes of an .rrd file of every rerun since 0.23; the next four are its version."""


class ViewError(UserError):
    """Something the user asked to view or serve that cannot be: one line, no traceback."""


def recording_of(target: str | Path) -> Path:
    """The .rrd file of a run folder (its run.rrd) or the file itself, checked readable by this
    rerun: a missing run, a file that is no recording or one from another rerun version is
    refused with the reason."""
    path = Path(target)
    if path.is_dir():
        recording = RunFolder(path).recording
        if not recording.is_file():
            raise ViewError(f"{path}: no {recording.name} in this folder (give a folder written by `ctsim run`, or a .rrd file)")
        path = recording
    elif not path.is_file():
        raise ViewError(f"{path}: no such run (give a folder written by `ctsim run`, or a .rrd file)")
    check_version(path)
    _holds_data(path)
    return path


def _holds_data(path: Path) -> None:
    """Refuse a recording with nothing in it (a header alone: a run killed before it recorded,
    or a file cut short), rather than serve an empty viewer as if it held a run."""
    import warnings

    from rerun.chunk import RrdReader

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (rerun warns of a file without its index, then reads it whole)
        try:
            reader = RrdReader(path)
            empty = not reader.recordings() or next(iter(reader.stream()), None) is None
        except (RuntimeError, ValueError):
            empty = True
    if empty:
        raise ViewError(f"{path}: a recording with no data in it (a header alone, or cut short before its first chunk): nothing to view")


def rerun_version() -> tuple[int, ...]:
    """The version of the installed rerun (major, minor, patch)."""
    import rerun

    return tuple(int(part) for part in rerun.__version__.split(".")[:3])


def check_version(path: Path) -> None:
    """Refuse a file that is not a rerun recording, or one that this rerun cannot show: one
    written by a newer rerun (this one would only warn, then show what it misreads) or by one so
    old that rerun itself refuses it."""
    with path.open("rb") as file:
        header = file.read(8)
    ours = ".".join(map(str, rerun_version()))
    if header[:3] == b"RRF" and header[:4] != MAGIC:
        raise ViewError(f"{path}: recorded by an old rerun that rerun {ours} (the one ctsim uses) cannot read")
    if header[:4] != MAGIC or len(header) < 8:
        raise ViewError(f"{path}: not a rerun recording")
    theirs = tuple(header[4:7])
    if theirs[:2] != rerun_version()[:2]:
        written = ".".join(map(str, theirs))
        if theirs[:2] > rerun_version()[:2]:
            raise ViewError(f"{path}: recorded by rerun {written}, newer than rerun {ours} that ctsim uses: open it with `rerun` {written}")
        _readable(path, written, ours)


def _readable(path: Path, written: str, ours: str) -> None:
    """An older recording: rerun reads those back to 0.23; whether it can, it says itself."""
    from rerun.chunk import RrdReader

    try:
        next(iter(RrdReader(path).stream()), None)
    except RuntimeError as err:
        why = str(err).splitlines()[0].removeprefix(f"Failed to read RRD file at {path}: ")
        raise ViewError(f"{path}: recorded by rerun {written}, which rerun {ours} (the one ctsim uses) cannot read ({why})") from None


def _check_free(host: str, port: int) -> None:
    """Refuse a port that something else listens on, before rerun would fail on it in its log."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
        except OSError as err:
            if err.errno == errno.EADDRINUSE:
                raise ViewError(f"port {port} on {host} is in use (another `ctsim view` or rerun?): choose another with --port") from None
            raise ViewError(f"cannot listen on {host}:{port}: {err.strerror or err}") from None


def _free_ports(host: str) -> tuple[int, int]:
    """Two ports free on `host` now (both held while the second is found, so they differ)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as first, socket.socket(family, socket.SOCK_STREAM) as second:
        first.bind((host, 0))
        second.bind((host, 0))
        return first.getsockname()[1], second.getsockname()[1]


def _in_url(host: str) -> str:
    """A host as a URL spells it (an IPv6 address in brackets)."""
    return f"[{host}]" if ":" in host else host


def addresses(host: str, port: int, grpc_port: int) -> tuple[str, str]:
    """The page's address (the viewer, told where the recording is) and the recording's (gRPC)."""
    recording = f"rerun+http://{_in_url(host)}:{grpc_port}/proxy"
    return f"http://{_in_url(host)}:{port}/?url={quote(recording, safe='')}", recording


def _rerun_command() -> Path:
    """rerun's executable as the rerun-sdk wheel ships it (the Python package `rerun_cli`)."""
    import rerun_cli

    return Path(rerun_cli.__file__).parent / ("rerun.exe" if sys.platform == "win32" else "rerun")


def _die_with_parent() -> None:
    """(In the child, Linux) end rerun's server when ctsim ends, however ctsim ends."""
    PR_SET_PDEATHSIG = 1
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


class WebViewer:
    """rerun's web viewer and gRPC proxy, served on `host` from `port` (the page) and `port + 1`
    (the proxy); port 0 picks two free ones. With `recording` the proxy holds that file; without,
    it waits for a run to stream in (`grpc_url`). Use as a context manager: the server stops on
    leaving it."""

    def __init__(self, recording: Path | None = None, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT):
        if not 0 <= port <= 65534:
            raise ViewError(f"--port must be between 0 and 65534 (the page's port; the next one is the recording's), got {port}")
        self.recording = recording
        self.host = host
        self.port, self.grpc_port = (port, port + 1) if port else _free_ports(host)
        self.process: subprocess.Popen | None = None
        self._log = tempfile.TemporaryFile()

    @property
    def _reach(self) -> str:
        """The host a browser uses: this machine's name when serving on every address."""
        return socket.gethostname() if self.host in ("0.0.0.0", "::") else self.host

    @property
    def grpc_url(self) -> str:
        """Where a recording stream connects (`Recorder(connect=...)`)."""
        return addresses(self._reach, self.port, self.grpc_port)[1]

    @property
    def url(self) -> str:
        """The page to open: the viewer, told where the recording is."""
        return addresses(self._reach, self.port, self.grpc_port)[0]

    def __enter__(self) -> WebViewer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Start rerun's server and wait until both ports listen; one line if it cannot."""
        from sim.views.recording.live import listening

        for port in (self.port, self.grpc_port):
            _check_free(self.host, port)
        command = [str(_rerun_command()), "--serve-web", "--bind", self.host, "--port", str(self.grpc_port), "--web-viewer-port", str(self.port)]
        if self._reach not in ("127.0.0.1", "localhost", "::1"):  # the page's origin may call the proxy
            command += ["--cors-allow-origin", f"http://{self._reach}:{self.port}"]
        if self.recording is not None:
            command.append(str(self.recording))
        env = {**os.environ, "RERUN_APP_ONLY": "true", "RUST_LOG": os.environ.get("RUST_LOG", "warn")}  # no analytics notice
        self.process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=self._log, stderr=self._log, env=env,
                                        preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
        deadline = time.monotonic() + START_WAIT_S
        for port in (self.grpc_port, self.port):
            while not listening(f"http://{_in_url(self.host)}:{port}", 0.2):
                if self.process.poll() is not None or time.monotonic() > deadline:
                    self.close()
                    raise ViewError(f"rerun's web viewer did not start on {self.host}:{self.port}: {self._last_words()}")

    def _last_words(self) -> str:
        """rerun's last line of complaint, for the one line the user sees."""
        self._log.seek(0)
        lines = [line.strip() for line in self._log.read().decode(errors="replace").splitlines() if line.strip()]
        errors = [line for line in lines if "error" in line.lower()]
        return (errors or lines or ["it said nothing"])[-1][-300:]

    def wait(self) -> None:
        """Serve until Ctrl-C (KeyboardInterrupt) or until rerun's server ends by itself."""
        if self.process is not None:
            self.process.wait()

    def close(self) -> None:
        """Stop the server; safe to call twice."""
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None
