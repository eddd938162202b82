"""A minimal OSC 1.0 decoder, written from the specification and independent of python-osc (which sends)."""

from __future__ import annotations

import struct


def _string(data: bytes, offset: int) -> tuple[str, int]:
    end = data.index(b"\0", offset)
    text = data[offset:end].decode("ascii")
    return text, offset + ((end - offset) // 4 + 1) * 4  # padded to four bytes, at least one NUL


def decode_message(data: bytes) -> tuple[str, list]:
    address, offset = _string(data, 0)
    tags, offset = _string(data, offset)
    if not tags.startswith(","):
        raise ValueError(f"no type tag string in {data[:32]!r}")
    args: list = []
    for tag in tags[1:]:
        if tag == "i":
            args.append(struct.unpack_from(">i", data, offset)[0])
            offset += 4
        elif tag == "f":
            args.append(struct.unpack_from(">f", data, offset)[0])
            offset += 4
        elif tag == "s":
            value, offset = _string(data, offset)
            args.append(value)
        else:
            raise ValueError(f"type tag {tag!r} not handled")
    return address, args


def decode_bundle(data: bytes) -> tuple[int, list[tuple[str, list]]]:
    """(time tag, messages) of an OSC bundle datagram (nested bundles flattened)."""
    if not data.startswith(b"#bundle\0"):
        raise ValueError("not a bundle")
    timetag = struct.unpack_from(">Q", data, 8)[0]
    offset, messages = 16, []
    while offset < len(data):
        size = struct.unpack_from(">i", data, offset)[0]
        element = data[offset + 4 : offset + 4 + size]
        offset += 4 + size
        if element.startswith(b"#bundle"):
            messages += decode_bundle(element)[1]
        else:
            messages.append(decode_message(element))
    return timetag, messages
