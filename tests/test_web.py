"""`ctsim view` and `ctsim run --web`: rerun's web viewer served on this machine, its page and
assets fetched over HTTP, the recording read back through its gRPC proxy, and (where Chromium
is installed) the page drawn by a headless browser; the one-line refusals of bad input; a run's
self-contained report.html."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

import pytest

from sim.cli.entry import main
from sim.views import palette
from sim.web.serve import _rerun_command
from tests.browser import Browser, chromium, share_of

CTSIM = [sys.executable, "-m", "sim.cli"]
RERUN = _rerun_command()
"""rerun's own executable, not the venv's `rerun` script: that script runs it as a child, which
terminating the script would leave running."""
LIMIT_S = 300.0
"""Generous limit for anything that waits on a loaded two-core machine (never decides a test)."""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("web") / "run"
    assert main(["run", "maze", "--duration", "1", "--out", str(out)]) == 0
    return out


def _serve(*args: str) -> tuple[subprocess.Popen, str]:
    """`ctsim ARGS` in the background, and the page's address once it prints it."""
    process = subprocess.Popen([*CTSIM, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for line in process.stdout:
        if found := re.search(r"(http://\S+)", line):
            return process, found.group(1)
    _, stderr = _stop(process)
    raise AssertionError(f"no address printed: {stderr}")


def _stop(process: subprocess.Popen) -> tuple[int, str]:
    """Ctrl-C, as a user ends `ctsim view`; killed if it does not end (its rerun server dies with it)."""
    process.send_signal(signal.SIGINT)
    try:
        _, stderr = process.communicate(timeout=LIMIT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        _, stderr = process.communicate()
    return process.returncode, stderr


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _summary(path: Path) -> str | None:
    """Entities, rows and columns of a recording (None while it cannot be read yet)."""
    import warnings

    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a file still being written has no footer yet
            return RrdReader(path).stream().collect().summary()
    except (RuntimeError, ValueError):
        return None


def _read_back(grpc_url: str, into: Path, expected: str) -> str | None:
    """What rerun's own client saves from the gRPC proxy, once it holds all of `expected`."""
    saver = subprocess.Popen([str(RERUN), "--save", str(into), "--bind", "127.0.0.1", "--port", str(_free_port()), grpc_url],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "RERUN_APP_ONLY": "true"})
    try:
        deadline = time.monotonic() + LIMIT_S
        while (got := into.exists() and _summary(into)) != expected and time.monotonic() < deadline:
            time.sleep(0.5)
        return got
    finally:
        saver.terminate()
        saver.wait(timeout=LIMIT_S)


def test_view_serves_the_page_its_assets_and_the_recording(run_dir, tmp_path):
    process, url = _serve("view", str(run_dir), "--port", "0")
    try:
        parts = urlsplit(url)
        assert parts.hostname == "127.0.0.1"  # this machine only, unless --host says otherwise
        page = urllib.request.urlopen(url, timeout=LIMIT_S).read().decode()
        assert "re_viewer.js" in page and "re_viewer_bg.wasm" in page
        base = f"http://{parts.netloc}/"
        assert b"wasm_bindgen" in urllib.request.urlopen(base + "re_viewer.js", timeout=LIMIT_S).read()
        assert urllib.request.urlopen(base + "re_viewer_bg.wasm", timeout=LIMIT_S).read(4) == b"\0asm"
        grpc_url = parse_qs(parts.query)["url"][0]
        expected = _summary(run_dir / "run.rrd")
        assert _read_back(grpc_url, tmp_path / "back.rrd", expected) == expected  # every entity, row and column
    finally:
        status, stderr = _stop(process)
    assert status == 0 and "stopped serving" in stderr and "Traceback" not in stderr  # Ctrl-C is the normal end


def test_view_refuses_with_one_line(run_dir, tmp_path, capsys):
    recording = (run_dir / "run.rrd").read_bytes()
    newer = tmp_path / "newer.rrd"
    newer.write_bytes(recording[:4] + bytes([0, 99, 0, 0]) + recording[8:])  # the header's version: 0.99.0
    older = tmp_path / "older.rrd"
    older.write_bytes(recording[:4] + bytes([0, 15, 0, 0]) + recording[8:])
    text = tmp_path / "notes.rrd"
    text.write_text("not a recording\n")
    header = tmp_path / "header.rrd"
    header.write_bytes(recording[:12])  # the stream header alone: a run killed before it recorded
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(recording[:40])
    cases = {
        header: "a recording with no data in it",
        cut: "a recording with no data in it",
        tmp_path / "nothing": "no such run",
        tmp_path: "no run.rrd in this folder",
        newer: "recorded by rerun 0.99.0, newer than rerun 0.41",
        older: "recorded by rerun 0.15.0, which rerun 0.41",
        text: "not a rerun recording",
    }
    for target, reason in cases.items():
        assert main(["view", str(target)]) == 2
        err = capsys.readouterr().err
        assert reason in err and str(target) in err and err.count("\n") == 1, err


def test_view_and_run_web_refuse_a_port_in_use(run_dir, tmp_path, capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["view", str(run_dir), "--port", str(port)]) == 2
        first = capsys.readouterr().err
        assert main(["run", "maze", "--duration", "1", "--out", str(tmp_path / "never"), "--web", "--port", str(port)]) == 2
        second = capsys.readouterr().err
    for err in (first, second):
        assert f"port {port} on 127.0.0.1 is in use" in err and err.count("\n") == 1, err
    assert not (tmp_path / "never").exists()  # refused before the run's folder is made


def test_run_web_streams_the_run_into_the_page(tmp_path):
    out = tmp_path / "live"
    process, url = _serve("run", "maze", "--duration", "1", "--no-report", "--out", str(out), "--web", "--port", "0")
    try:
        grpc_url = parse_qs(urlsplit(url).query)["url"][0]
        deadline = time.monotonic() + LIMIT_S
        while not (out / "summary.json").exists() and time.monotonic() < deadline:
            time.sleep(0.5)  # the run ends; the page goes on being served
        expected = _summary(out / "run.rrd")
        assert _read_back(grpc_url, tmp_path / "back.rrd", expected) == expected  # the live stream held all the file has
    finally:
        status, stderr = _stop(process)
    assert status == 0 and "stopped serving" in stderr, stderr


@pytest.mark.skipif(chromium() is None, reason="no Chromium installed (Debian: apt-get install chromium)")
def test_the_page_draws_the_run_in_headless_chromium(run_dir):
    """The viewer draws the map view with the blueprint's background and the estimates' colours
    (trails and error plots): the blueprint and the data both reached the canvas."""
    process, url = _serve("view", str(run_dir), "--port", "0")
    estimate = palette.estimate_colour("fused")

    def drawn(image) -> bool:
        return share_of(image, palette.BACKGROUND) > 0.05 and share_of(image, estimate) > 1e-4

    try:
        with Browser() as browser:
            browser.open(url)
            image = browser.wait_for(drawn, LIMIT_S)
    finally:
        _stop(process)
    assert share_of(image, palette.BACKGROUND) > 0.05, "no map view drawn"  # the map view: about a third of the page
    assert share_of(image, estimate) > 1e-4, "no estimate drawn"  # a trail and a plot line: some thousand pixels


def test_a_run_folder_has_a_self_contained_report(run_dir):
    page = (run_dir / "report.html").read_text()
    summary = json.loads((run_dir / "summary.json").read_text())
    for estimate, errors in summary["robots"][0]["estimates"].items():  # the table `ctsim run` prints
        assert f"{estimate}</td>" in page and f"<td>{errors['ate_rmse']:.4f}</td>" in page
    assert page.count("src='data:image/png;base64,") == 2  # trajectories.png and errors.png, inside the page
    assert set(re.findall(r"src='([a-z]+):", page)) == {"data"}  # nothing it needs beside it
    assert f"ctsim view {run_dir}" in page and "http://127.0.0.1:9090/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9091%2Fproxy" in page
    assert "<td>seed</td><td class='text'>0</td>" in page and "<td>world</td><td class='text'>Maze" in page


@pytest.mark.parametrize(
    ("host", "page", "recording"),
    [
        ("127.0.0.1", "http://127.0.0.1:8000/", "rerun+http://127.0.0.1:8001/proxy"),
        ("::1", "http://[::1]:8000/", "rerun+http://[::1]:8001/proxy"),  # IPv6 in brackets
        ("0.0.0.0", f"http://{socket.gethostname()}:8000/", f"rerun+http://{socket.gethostname()}:8001/proxy"),  # a name others can reach
    ],
)
def test_the_printed_address_names_the_page_and_the_recording(host, page, recording):
    from sim.web.serve import WebViewer

    web = WebViewer(None, host, 8000)
    assert web.url.startswith(page) and parse_qs(urlsplit(web.url).query)["url"] == [recording] and web.grpc_url == recording
