"""The frame checksum is zlib's CRC-32, whichever library computes it (trackerd/recording/checksum.py)."""

from __future__ import annotations

import zlib

import numpy as np
from rec_helpers import BUNDLE

from trackerd.recording.checksum import CRC32_IMPLEMENTATION, frame_crc32
from trackerd.recording.reader import Recording


def test_the_frame_checksum_is_zlibs_crc32_on_frames_and_odd_buffers() -> None:
    rng = np.random.default_rng(7)
    noisy = rng.integers(0, 256, size=(1080, 1920), dtype=np.uint8)
    buffers: list[bytes | memoryview] = [b"", b"a", bytes(range(256)) * 3, noisy.tobytes()]
    # Views that start and end off any alignment the fast path may assume.
    buffers += [memoryview(noisy.tobytes())[offset : offset + 4099] for offset in (1, 3, 4093)]
    for data in buffers:
        assert frame_crc32(data) == zlib.crc32(data)
    assert CRC32_IMPLEMENTATION in ("isal", "zlib")


def test_the_bundled_recordings_frames_match_their_recorded_checksums() -> None:
    """The checksums the recorder wrote (with whichever library it had) check with this one."""
    with Recording.open(BUNDLE) as recording:
        for index in range(len(recording)):
            header = recording.header(index)
            offset = recording.entries[index].offset + header.header_bytes
            for frame in header.frames:
                assert frame_crc32(recording.view(offset, frame.stored_bytes)) == frame.payload_crc32
                offset += frame.stored_bytes
