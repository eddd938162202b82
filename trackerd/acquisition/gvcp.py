"""A bounded-time "are you there?" for GigE Vision cameras: one GVCP discovery exchange.

Aravis blocks for about a second when asked to open a camera that does not
answer, which would make a reconnect loop deaf to a stop request. Before asking
Aravis, the loop sends one GVCP DISCOVERY_CMD (GigE Vision 2.x, section 16.1) to
the camera's last known address and waits a bounded time for the
DISCOVERY_ACK, whose payload is the start of the bootstrap register map
(manufacturer, model and serial number at fixed offsets).
"""

from __future__ import annotations

import itertools
import socket
import struct
import time
from dataclasses import dataclass

GVCP_PORT = 3956
_KEY = 0x42
_FLAG_ACK_REQUIRED = 0x01
_DISCOVERY_CMD = 0x0002
_DISCOVERY_ACK = 0x0003
_ACK_HEADER = struct.Struct(">HHHH")  # status, answer, length, ack id
_DISCOVERY_PAYLOAD = 0xF8
# Offsets in the DISCOVERY_ACK payload (the bootstrap registers 0x0000-0x00F7).
_MAC_HIGH, _MAC_LOW, _CURRENT_IP = 0x08, 0x0C, 0x24
_MANUFACTURER, _MODEL, _SERIAL = (0x48, 32), (0x68, 32), (0xD8, 16)

_request_ids = itertools.count(1)


@dataclass(frozen=True)
class GvcpDevice:
    """What a camera says about itself in a discovery acknowledgement."""

    address: str
    manufacturer: str
    model: str
    serial: str
    mac: str


def discovery_packet(request_id: int) -> bytes:
    """The 8-byte DISCOVERY_CMD (no payload)."""
    return struct.pack(">BBHHH", _KEY, _FLAG_ACK_REQUIRED, _DISCOVERY_CMD, 0, request_id & 0xFFFF or 1)


def parse_discovery_ack(packet: bytes, sender: str) -> GvcpDevice | None:
    """The device described by a DISCOVERY_ACK, or None if the packet is not one."""
    if len(packet) < _ACK_HEADER.size + _DISCOVERY_PAYLOAD:
        return None
    status, answer, length, _ = _ACK_HEADER.unpack_from(packet)
    if status != 0 or answer != _DISCOVERY_ACK or length < _DISCOVERY_PAYLOAD:
        return None
    payload = packet[_ACK_HEADER.size :]

    def text(field: tuple[int, int]) -> str:
        offset, size = field
        return payload[offset : offset + size].split(b"\0", 1)[0].decode("ascii", "replace")

    mac_high = struct.unpack_from(">I", payload, _MAC_HIGH)[0] & 0xFFFF
    mac_low = struct.unpack_from(">I", payload, _MAC_LOW)[0]
    mac = ":".join(f"{b:02x}" for b in struct.pack(">HI", mac_high, mac_low))
    address = socket.inet_ntoa(payload[_CURRENT_IP : _CURRENT_IP + 4])
    if address == "0.0.0.0":
        address = sender
    return GvcpDevice(address, text(_MANUFACTURER), text(_MODEL), text(_SERIAL), mac)


def probe(address: str, timeout_s: float) -> GvcpDevice | None:
    """Ask the camera at ``address`` to identify itself; None if no answer within ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    request_id = next(_request_ids)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.sendto(discovery_packet(request_id), (address, GVCP_PORT))
        except OSError:
            return None  # no route to the camera (its network is down)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            sock.settimeout(remaining)
            try:
                packet, (sender, _) = sock.recvfrom(2048)
            except (TimeoutError, OSError):
                return None
            device = parse_discovery_ack(packet, sender)
            if device is not None:
                return device
