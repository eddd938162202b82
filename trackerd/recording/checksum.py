"""The frame checksum of pairs.dat (CRC-32, the zlib polynomial), computed as fast as this machine can.

Every frame's payload carries a CRC-32 (docs/recording.md, "pairs.dat"). zlib's
CRC-32 runs at about 1-2 GB/s here: 1.1-2.0 ms of CPU for one 1080p Bayer frame,
2.3-4 ms a raw pair, which alone bounded a checked raw replay to 300-500 pairs/s
on one reader thread. ISA-L's CRC-32 (the ``isal`` package; carry-less multiply
instructions) computes the same function 20x faster (0.06 ms a frame, measured
on this machine: docs/recording.md, "Replay speed"). It is used when installed;
without it zlib's gives the same checksums, only slower.
"""

from __future__ import annotations

import importlib
import zlib
from collections.abc import Callable
from typing import cast

Crc32 = Callable[[bytes | memoryview], int]


def _fastest() -> tuple[Crc32, str]:
    try:
        module = importlib.import_module("isal.isal_zlib")
    except ImportError:
        return zlib.crc32, "zlib"
    # Imported by name: the module is optional, so the type checker may not see it.
    return cast(Crc32, module.crc32), "isal"


frame_crc32, CRC32_IMPLEMENTATION = _fastest()
"""``frame_crc32(buffer)``: the CRC-32 of a frame's payload, equal to ``zlib.crc32(buffer)``;
CRC32_IMPLEMENTATION says which library computes it (``isal`` or ``zlib``)."""
