"""The bridge: the unmodified c't-Bot firmware (its PC build) drives a ctsim robot over c't-Sim's
TCP protocol, in lock-step with the world (ctbot-protocol.md). A firmware bot is one more
controller of the run loop; see `Bridge`. Names load on first use, so that the command line can
read the protocol module without building a world."""

from __future__ import annotations

import importlib
from typing import Any

_WHERE = {
    "Bridge": "session", "BridgeObserver": "session",
    "BridgeError": "firmware", "FirmwareController": "firmware", "FirmwareEstimator": "firmware",
    "Decoder": "protocol", "Packet": "protocol", "ProtocolError": "protocol", "parse_call": "protocol", "rc5_code": "protocol",
}  # fmt: skip
__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module 'sim.bridge' has no attribute {name!r}")
    return getattr(importlib.import_module(f"sim.bridge.{_WHERE[name]}"), name)
