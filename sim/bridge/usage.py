"""The bridge's command-line helpers: how to start the firmware, and `T:VALUE` options. Light to
import (the CLI builds its parser from it on every call)."""

from __future__ import annotations

from typing import Any


def timed(text: str, parse) -> tuple[float, Any]:
    """'T:VALUE' (T in seconds of simulated time) -> (T, parse(VALUE)); ValueError if malformed."""
    when, sep, value = text.partition(":")
    try:
        at = float(when)
    except ValueError:
        at = float("nan")
    if not sep or not (at >= 0):
        raise ValueError(f"expected T:VALUE with T in seconds, got {text!r}")
    return at, parse(value)


HOW_TO_START = """\
How to start the firmware (the c't-Bot's PC build, e.g. ct-bot/build/ct-Bot or a platformio
native build): start `ctsim bridge` first, it listens on 127.0.0.1:10001 (the port the firmware
connects to; it does not retry), then the firmware in a fresh working directory with stdin kept
open (on end-of-input its console thread spins at 100 % CPU; it reuses ctbot.map from its cwd):

    mkdir -p /tmp/bot1 && cd /tmp/bot1 && sleep infinity | /path/to/ct-Bot

Give the firmware at most one option (-t HOST or -a ADDRESS): with two it prints its usage and
exits without connecting. For --robots N start N firmwares, each in its own folder; connections
become robots in the order they arrive. Once the run's files are written ctsim sends SHUTDOWN and
the firmware exits 0.
"""
