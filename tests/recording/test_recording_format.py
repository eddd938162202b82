"""The recording format: round trips on real frames, the byte layouts, versions."""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from rec_helpers import trackerd

from trackerd.errors import RecordingError
from trackerd.recording.format import (
    FRAME_ENTRY,
    INDEX_ENTRY,
    RECORD_FIXED,
    FrameEntry,
    IndexEntry,
    RecordHeader,
    pack_index_entry,
    pack_record_header,
    unpack_index_entry,
    unpack_record_header,
)
from trackerd.recording.reader import Recording
from trackerd.recording.writer import RecordingWriter

u63 = st.integers(min_value=0, max_value=2**63 - 1)
i63 = st.integers(min_value=-(2**63), max_value=2**63 - 1)
frame_entries = st.builds(FrameEntry, u63, u63, i63, u63, st.integers(0, 2**32 - 1), st.integers(0, 1))
headers = st.builds(
    RecordHeader,
    u63,
    u63,
    i63,
    i63,
    st.integers(0, 2**32 - 1),
    st.lists(frame_entries, min_size=1, max_size=4).map(tuple),
)


def test_the_layout_is_the_documented_one() -> None:
    """docs/recording.md gives these sizes; a reader in another language relies on them."""
    assert (RECORD_FIXED.size, FRAME_ENTRY.size, INDEX_ENTRY.size) == (56, 40, 48)
    header = RecordHeader(0, 1, 2, 3, 0, (FrameEntry(1, 2, 3, 4, 5, 0), FrameEntry(1, 2, 3, 4, 5, 0)))
    assert len(pack_record_header(header)) == header.header_bytes == 144


@given(headers)
def test_a_record_header_reads_back_as_written(header: RecordHeader) -> None:
    assert unpack_record_header(pack_record_header(header), "test") == header


@given(headers, st.data())
def test_any_damaged_byte_of_a_record_header_is_caught(header: RecordHeader, data: st.DataObject) -> None:
    packed = bytearray(pack_record_header(header))
    position = data.draw(st.integers(0, len(packed) - 1))
    packed[position] ^= data.draw(st.integers(1, 255))
    with pytest.raises(RecordingError, match="at byte 99"):
        unpack_record_header(bytes(packed), "pairs.dat: pair 7 at byte 99")


@given(st.builds(IndexEntry, u63, u63, u63, u63, i63), st.data())
def test_index_entries_read_back_and_damage_is_caught(entry: IndexEntry, data: st.DataObject) -> None:
    packed = pack_index_entry(entry)
    assert unpack_index_entry(packed, INDEX_ENTRY.size, "idx") == entry
    damaged = bytearray(packed)
    damaged[data.draw(st.integers(0, len(packed) - 1))] ^= data.draw(st.integers(1, 255))
    with pytest.raises(RecordingError, match="checksum"):
        unpack_index_entry(bytes(damaged), INDEX_ENTRY.size, "idx")


@pytest.mark.parametrize("compression", ["none", "deflate"])
def test_frames_timestamps_and_ids_come_back_exactly(bundle, tmp_path, compression: str) -> None:
    """Bayer stays Bayer: every pixel, frame id, timestamp, skew and sequence of the bundled
    recording survives being written again, raw or deflated."""
    with Recording.open(bundle) as source:
        pairs = [source.pair(i) for i in range(len(source))]
        writer = RecordingWriter(
            tmp_path / "copy.trec", source.metadata.model_copy(update={"end": None}), compression=compression
        )
        for pair in pairs:
            writer.write(pair)
        writer.close()
        with Recording.open(tmp_path / "copy.trec") as copy:
            assert copy.problems == []
            assert len(copy) == len(pairs)
            assert copy.metadata.cameras == source.metadata.cameras
            assert copy.metadata.rig == source.metadata.rig
            for i, original in enumerate(pairs):
                again = copy.pair(i)
                assert (again.timestamp_ns, again.skew_ns, again.sequence) == (
                    original.timestamp_ns,
                    original.skew_ns,
                    original.sequence,
                )
                for a, b in zip(again.frames, original.frames, strict=True):
                    assert (a.camera_id, a.frame_id, a.device_timestamp_ns, a.host_timestamp_ns, a.pixel_format) == (
                        b.camera_id,
                        b.frame_id,
                        b.device_timestamp_ns,
                        b.host_timestamp_ns,
                        b.pixel_format,
                    )
                    assert a.image.dtype == np.uint8 and a.image.shape == (1080, 1920)
                    assert np.array_equal(a.image, b.image)
    raw_size = (tmp_path / "copy.trec" / "pairs.dat").stat().st_size
    if compression == "none":
        assert raw_size > len(pairs) * 2 * 1920 * 1080


def test_the_data_file_can_be_read_with_nothing_but_the_spec(bundle) -> None:
    """What docs/recording.md tells a reader in another language, done with struct and zlib only."""
    meta = json.loads((bundle / "recording.json").read_text())
    index = (bundle / "pairs.idx").read_bytes()
    data = (bundle / "pairs.dat").read_bytes()
    assert index[:8] == b"TRKDINDX" and data[:8] == b"TRKDDATA"
    entry_bytes = struct.unpack_from("<I", index, 12)[0]
    offset, length, pair_index, sequence, timestamp_ns, _, crc = struct.unpack_from("<QQQqqII", index, 16 + entry_bytes)
    assert zlib.crc32(index[16 + entry_bytes : 16 + entry_bytes + 44]) == crc
    assert (pair_index, sequence) == (1, 2) and timestamp_ns > 0
    assert data[offset : offset + 4] == b"PAIR"
    header_bytes, n_frames = struct.unpack_from("<IH", data, offset + 4)
    assert n_frames == len(meta["cameras"])
    payload = offset + header_bytes
    for k, cam in enumerate(meta["cameras"]):
        frame_id, _dev, _host, stored, payload_crc, encoding = struct.unpack_from("<QQqQIB", data, offset + 56 + 40 * k)
        assert frame_id == 2
        pixels = data[payload : payload + stored]
        assert zlib.crc32(pixels) == payload_crc
        raw = zlib.decompress(pixels) if encoding == 1 else pixels
        assert len(raw) == cam["width_px"] * cam["height_px"]
        payload += stored
    assert payload == offset + length


def test_a_newer_major_version_is_refused_by_name(bundle, tmp_path) -> None:
    copy = tmp_path / "future.trec"
    copy.mkdir()
    for name in ("pairs.dat", "pairs.idx"):
        (copy / name).write_bytes((bundle / name).read_bytes())
    meta = json.loads((bundle / "recording.json").read_text())
    meta["format_version"] = "3.0"
    (copy / "recording.json").write_text(json.dumps(meta))
    with pytest.raises(RecordingError, match=r"format 3\.x is newer than this trackerd reads \(2\.0\)"):
        Recording.open(copy)
    # A newer MINOR only adds things: it still reads, unknown keys ignored.
    meta.update(format_version="1.7", colour_calibration={"left": [1, 2, 3]})
    (copy / "recording.json").write_text(json.dumps(meta))
    with Recording.open(copy) as recording:
        assert len(recording) == 16


def _as_newer_minor(bundle, folder, frame_entry_bytes: int, index_entry_bytes: int) -> None:
    """Rewrite a 1.0 recording as the 1.1 docs/recording.md allows: longer frame and index entries
    (new fields at their ends, here filled with 0xAA/0xBB), a new flag, a new metadata key."""
    folder.mkdir()
    meta = json.loads((bundle / "recording.json").read_text())
    data = (bundle / "pairs.dat").read_bytes()
    index = (bundle / "pairs.idx").read_bytes()
    out = bytearray(b"TRKDDATA" + struct.pack("<HHI", 1, 1, 0))
    idx = bytearray(b"TRKDINDX" + struct.pack("<HHI", 1, 1, index_entry_bytes))
    for k in range((len(index) - 16) // INDEX_ENTRY.size):
        offset, length, pair_index, sequence, timestamp_ns, _, _ = INDEX_ENTRY.unpack_from(index, 16 + 48 * k)
        header_bytes, n_frames, entry_bytes = struct.unpack_from("<IHH", data, offset + 4)
        fixed = bytearray(data[offset : offset + RECORD_FIXED.size])
        new_header_bytes = RECORD_FIXED.size + n_frames * frame_entry_bytes + 8
        struct.pack_into("<IHHI", fixed, 4, new_header_bytes, n_frames, frame_entry_bytes, 0x4)
        entries = b"".join(
            data[offset + 56 + i * entry_bytes : offset + 56 + (i + 1) * entry_bytes]
            + b"\xaa" * (frame_entry_bytes - entry_bytes)
            for i in range(n_frames)
        )
        body = bytes(fixed) + entries + struct.pack("<I", 0)
        payloads = data[offset + header_bytes : offset + length]
        record = body + struct.pack("<I", zlib.crc32(body)) + payloads
        entry = struct.pack("<QQQqqI", len(out), len(record), pair_index, sequence, timestamp_ns, 0)
        entry += b"\xbb" * (index_entry_bytes - 4 - len(entry))
        idx += entry + struct.pack("<I", zlib.crc32(entry))
        out += record
    meta.update(format_version="1.1", lens_model={"left": "unknown"})
    meta["end"]["data_bytes"] = len(out)
    (folder / "recording.json").write_text(json.dumps(meta))
    (folder / "pairs.dat").write_bytes(bytes(out))
    (folder / "pairs.idx").write_bytes(bytes(idx))


def test_a_newer_minor_with_longer_entries_reads_the_fields_it_knows(bundle, tmp_path) -> None:
    """docs/recording.md's version rule: longer frame entries and index entries are skipped past."""
    newer = tmp_path / "newer.trec"
    _as_newer_minor(bundle, newer, frame_entry_bytes=48, index_entry_bytes=56)
    with Recording.open(bundle) as original, Recording.open(newer) as copy:
        assert copy.problems == []
        assert (len(copy), copy.indexed) == (16, 16)
        assert copy.header(0).header_bytes == 56 + 2 * 48 + 8
        for i in range(len(original)):
            a, b = original.pair(i), copy.pair(i)
            assert (a.timestamp_ns, a.skew_ns, a.sequence) == (b.timestamp_ns, b.skew_ns, b.sequence)
            for fa, fb in zip(a.frames, b.frames, strict=True):
                assert (fa.frame_id, fa.device_timestamp_ns, fa.host_timestamp_ns) == (
                    fb.frame_id,
                    fb.device_timestamp_ns,
                    fb.host_timestamp_ns,
                )
                assert np.array_equal(fa.image, fb.image)
    # Without an index, the scan past it finds the same pairs from the record headers alone.
    (newer / "pairs.idx").unlink()
    with Recording.open(newer) as scanned, Recording.open(bundle) as original:
        assert (len(scanned), scanned.indexed) == (16, 0)
        assert np.array_equal(scanned.pair(15).images[1], original.pair(15).images[1])
    _as_newer_minor(bundle, tmp_path / "again.trec", frame_entry_bytes=48, index_entry_bytes=56)
    check = trackerd("recording", "check", tmp_path / "again.trec")
    assert check.returncode == 0, check.stdout
    assert "16 readable (16 indexed, 0 recovered past the index)" in check.stdout
    assert "16 of 16 pairs pass their checksums" in check.stdout


def test_what_is_not_a_recording_says_so(tmp_path) -> None:
    (tmp_path / "empty.trec").mkdir()
    (tmp_path / "file.trec").write_text("hello")
    assert "no such recording" in trackerd("recording", "check", tmp_path / "missing.trec").stderr
    run = trackerd("replay", tmp_path / "empty.trec")
    assert run.returncode == 1 and "Traceback" not in run.stderr
    assert run.stderr.strip() == (
        f"trackerd replay: {tmp_path / 'empty.trec'}: not a recording (no recording.json; a recording is a folder"
        " holding recording.json, pairs.dat and pairs.idx)"
    )
    run = trackerd("recording", "check", tmp_path / "file.trec")
    assert run.returncode == 1 and "not a recording" in run.stderr
