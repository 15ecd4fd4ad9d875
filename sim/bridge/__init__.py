"""The bridge: the unmodified c't-Bot firmware (its PC build) drives a ctsim robot over c't-Sim's
TCP protocol, in lock-step with the world (ctbot-protocol.md). A firmware bot is one more
controller of the run loop; see `Bridge`."""

from sim.bridge.firmware import BridgeError, FirmwareController, FirmwareEstimator
from sim.bridge.protocol import Decoder, Packet, ProtocolError, parse_call, rc5_code
from sim.bridge.session import Bridge, BridgeObserver

__all__ = [
    "Bridge", "BridgeError", "BridgeObserver", "Decoder", "FirmwareController", "FirmwareEstimator",
    "Packet", "ProtocolError", "parse_call", "rc5_code",
]  # fmt: skip
