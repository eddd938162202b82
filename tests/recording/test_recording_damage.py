"""Truncated, half-indexed, corrupt and wrong-version recordings: a clear account, and the intact part replays."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from rec_helpers import one_line_error, trackerd

from trackerd.recording.format import INDEX_ENTRY
from trackerd.recording.reader import MAX_METADATA_BYTES, Recording
from trackerd.recording.replay import ReplayPairSource


def _copy(bundle: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "copy.trec"
    shutil.copytree(bundle, copy)
    return copy


def _replay_summary(path: Path) -> tuple[dict, str, int]:
    run = trackerd("replay", path, "--speed", "max", "--delay", "0", "--endpoint", "tcp://127.0.0.1:*", "--json")
    assert "Traceback" not in run.stderr, run.stderr
    return json.loads(run.stdout), run.stderr, run.returncode


def _replay(path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """`trackerd replay PATH ARGS` on a free port, no console, its summary as JSON on stdout."""
    return trackerd(
        "replay",
        path,
        *args,
        "--delay",
        "0",
        "--endpoint",
        "tcp://127.0.0.1:*",
        "--console",
        "off",
        "--json",
        timeout=60,
    )


def _replayed_sequences(path: Path) -> list[int]:
    source = ReplayPairSource(path, speed=None)
    with source:
        sequences = []
        while (pair := source.next_pair(1.0)) is not None:
            sequences.append(pair.sequence)
    return sequences


def test_a_recording_cut_in_the_middle_of_a_pair_replays_up_to_the_last_whole_pair(bundle, tmp_path) -> None:
    copy = _copy(bundle, tmp_path)
    with Recording.open(bundle) as whole:
        cut = whole.entries[9].offset + whole.entries[9].record_bytes // 2
    with (copy / "pairs.dat").open("r+b") as handle:
        handle.truncate(cut)
    check = trackerd("recording", "check", copy)
    assert check.returncode == 1
    assert "pairs: 9 readable (9 indexed, 0 recovered past the index)" in check.stdout
    assert f"pair 9 at byte {whole.entries[9].offset}: incomplete" in check.stdout
    assert "pairs.idx: entry 9" in check.stdout and "truncated" in check.stdout
    summary, _, code = _replay_summary(copy)
    assert code == 0 and summary["pairs"] == 9 and summary["hits"] == 9
    assert _replayed_sequences(copy) == list(range(1, 10))


def test_pairs_written_but_not_yet_indexed_are_recovered(bundle, tmp_path) -> None:
    """A recorder killed between writing a pair and indexing it; or an index lost altogether."""
    copy = _copy(bundle, tmp_path)
    index = copy / "pairs.idx"
    index.write_bytes(index.read_bytes()[: 16 + 13 * INDEX_ENTRY.size + 20])  # 13 entries and a torn one
    with Recording.open(copy) as recording:
        assert (len(recording), recording.indexed) == (16, 13)
        assert any(
            "3 complete pair(s) past the end of the index (pairs 13-15), recovered" in p for p in recording.problems
        )
        assert any("partial entry (20 bytes)" in p for p in recording.problems)
    index.unlink()
    check = trackerd("recording", "check", copy, "--json")
    report = json.loads(check.stdout)
    assert (report["pairs"], report["indexed"], report["recovered"], report["replayable"]) == (16, 0, 16, 16)
    assert _replayed_sequences(copy) == list(range(1, 17))


def test_a_damaged_index_entry_ends_the_index_and_the_rest_is_recovered_by_scanning(bundle, tmp_path) -> None:
    copy = _copy(bundle, tmp_path)
    index = bytearray((copy / "pairs.idx").read_bytes())
    index[16 + 7 * INDEX_ENTRY.size + 10] ^= 0x01  # inside entry 7's record length
    (copy / "pairs.idx").write_bytes(bytes(index))
    check = trackerd("recording", "check", copy)
    assert check.returncode == 1
    assert "pairs: 16 readable (7 indexed, 9 recovered past the index)" in check.stdout
    assert "entry 7 (byte 352): index entry checksum mismatch" in check.stdout
    assert "the index is used up to pair 6" in check.stdout
    report = json.loads(trackerd("recording", "check", copy, "--json").stdout)
    assert (report["pairs"], report["indexed"], report["recovered"], report["replayable"]) == (16, 7, 9, 16)
    assert report["sequence_gaps"] == 0
    assert _replayed_sequences(copy) == list(range(1, 17))
    # The first entry damaged: none of the index is used (it said "used up to pair -1").
    index[16 + 7 * INDEX_ENTRY.size + 10] ^= 0x01
    index[16 + 10] ^= 0x01
    (copy / "pairs.idx").write_bytes(bytes(index))
    first = trackerd("recording", "check", copy)
    assert "entry 0 (byte 16): index entry checksum mismatch (the entry is damaged); the index is not used" in (
        first.stdout
    )
    assert "pairs: 16 readable (0 indexed, 16 recovered past the index)" in first.stdout


@pytest.mark.parametrize("name", ["pairs.dat", "pairs.idx"])
def test_a_damaged_file_header_is_named_as_damage_and_every_pair_still_replays(bundle, tmp_path, name) -> None:
    """Four bytes flipped over a binary file's version (its header has no checksum): the recording is of a
    format this trackerd reads (recording.json says so), so the header is named damaged and the pairs, each
    with its own checksums, are read. Before, both read as "format 65534.x is newer than this trackerd reads;
    upgrade trackerd" and not one pair was read."""
    copy = _copy(bundle, tmp_path)
    data = bytearray((copy / name).read_bytes())
    data[8:12] = bytes(b ^ 0xFF for b in data[8:12])
    (copy / name).write_bytes(bytes(data))
    check = trackerd("recording", "check", copy)
    assert check.returncode == 1 and "Traceback" not in check.stderr, check.stderr
    assert f"{name}: its file header is damaged (it says format 65534.65535" in check.stdout, check.stdout
    assert "upgrade" not in check.stdout + check.stderr
    report = json.loads(trackerd("recording", "check", copy, "--json").stdout)
    assert (report["pairs"], report["replayable"], report["sequence_gaps"]) == (16, 16, 0)
    assert _replayed_sequences(copy) == list(range(1, 17))


def test_a_damaged_frame_is_named_and_skipped_and_the_rest_replays(bundle, tmp_path) -> None:
    copy = _copy(bundle, tmp_path)
    with Recording.open(bundle) as whole:
        header = whole.header(5)
        frame_at = whole.entries[5].offset + header.header_bytes
        header_at = whole.entries[3].offset
    data = bytearray((copy / "pairs.dat").read_bytes())
    data[frame_at + 1000] ^= 0x5A
    data[header_at + 30] ^= 0x01  # inside pair 3's timestamp
    (copy / "pairs.dat").write_bytes(bytes(data))
    check = trackerd("recording", "check", copy)
    assert check.returncode == 1
    assert f"pair 5, camera 'left' (byte {frame_at}): frame checksum mismatch" in check.stdout
    assert f"pair 3 at byte {header_at}: record header checksum mismatch" in check.stdout
    assert "14 of 16 pairs pass their checksums; 2 damaged" in check.stdout
    # Both pairs are there, damaged: none is missing from the sequence.
    assert "gaps in the pair sequence: 0" in check.stdout
    report = json.loads(trackerd("recording", "check", copy, "--json").stdout)
    assert (report["sequence_gaps"], report["damaged_pairs"], report["replayable"]) == (0, [3, 5], 14)
    summary, stderr, code = _replay_summary(copy)
    assert code == 1
    assert summary["pairs"] == 14 and summary["skipped_damaged"] == 2
    assert "frame checksum mismatch (the pixels are damaged); pair skipped" in stderr
    assert "2 damaged pair(s) skipped" in stderr
    assert _replayed_sequences(copy) == [s for s in range(1, 17) if s not in (4, 6)]


def test_a_wrong_version_or_a_foreign_folder_is_one_clear_line(bundle, tmp_path) -> None:
    copy = _copy(bundle, tmp_path)
    meta = json.loads((copy / "recording.json").read_text())
    (copy / "recording.json").write_text(json.dumps({**meta, "format_version": "3.1"}))
    one_line_error(trackerd("replay", copy), "replay", "recording.json", "format 3.x is newer than this trackerd")
    (copy / "recording.json").write_text(json.dumps({**meta, "format": "something-else"}))
    one_line_error(
        trackerd("recording", "export", copy, tmp_path / "out"),
        "recording",
        "format is 'something-else'",
        "not a trackerd recording",
    )
    (copy / "recording.json").write_text(json.dumps(meta))
    (copy / "pairs.dat").write_bytes(b"GIF89a" + bytes(100))
    one_line_error(trackerd("replay", copy), "replay", "pairs.dat: does not begin with TRKDDATA")


def test_frames_recorded_in_a_format_without_colour_are_one_line_not_a_crashed_pipeline(bundle, tmp_path) -> None:
    """recording.json says a camera's frames are Mono8 (edited by hand, or a recording of a rig used to
    calibrate): replay and export refuse it in one line before the pipeline starts. Before, every pair crashed
    the locator's thread with a traceback (ImageError from the colour sampling). (A format a recording does
    not store, Mono16, is refused as the metadata is read: the next test but one.)"""
    copy = _copy(bundle, tmp_path)
    meta = json.loads((copy / "recording.json").read_text())
    meta["cameras"][0]["pixel_format"] = "Mono8"
    (copy / "recording.json").write_text(json.dumps(meta))
    fragments = ("camera 'left': its recorded frames' pixel format 'Mono8' cannot show the pointer's colours",)
    one_line_error(
        trackerd("replay", copy, "--speed", "max", "--delay", "0", "--endpoint", "tcp://127.0.0.1:*"),
        "replay",
        *fragments,
    )
    one_line_error(trackerd("recording", "export", copy, tmp_path / "out"), "recording", *fragments)


def test_hostile_metadata_is_one_clear_line_never_a_traceback_or_a_hang(bundle, tmp_path) -> None:
    """recording.json nested 1,200 deep (the JSON parser runs out of recursion), nested past what any
    recording has, a FIFO in its place (reading it would wait for a writer), and one far too large."""
    copy = _copy(bundle, tmp_path)
    meta = copy / "recording.json"
    meta.write_text('{"format": ' + "[" * 1200 + "]" * 1200 + "}")
    one_line_error(trackerd("recording", "check", copy), "recording", "nested too deeply")
    one_line_error(trackerd("replay", copy), "replay", "nested too deeply")
    meta.write_text('{"format": ' + "[" * 40 + "]" * 40 + "}")
    one_line_error(trackerd("replay", copy), "replay", "nested more than 32 levels deep")
    meta.unlink()
    os.mkfifo(meta)
    # (the timeout is only a guard: the command answers at once, as it does not open the FIFO)
    one_line_error(trackerd("recording", "check", copy, timeout=60), "recording", "not a regular file (a FIFO)")
    meta.unlink()
    with meta.open("wb") as handle:
        handle.truncate(MAX_METADATA_BYTES + 1)
    one_line_error(trackerd("replay", copy), "replay", "larger than such a file can be")


def test_an_integer_too_long_for_python_in_the_metadata_is_one_line(bundle, tmp_path) -> None:
    """Found by tests/test_fuzz.py: json reads integers with int(), which refuses more than 4300
    digits with a plain ValueError (not a JSONDecodeError), and that escaped read_metadata."""
    copy = _copy(bundle, tmp_path)
    meta = (copy / "recording.json").read_text()
    (copy / "recording.json").write_text(
        meta.replace('"clock_offset_ns": 1795000000000000000', '"clock_offset_ns": ' + "9" * 5000, 1)
    )
    one_line_error(trackerd("recording", "check", copy), "recording", "not readable JSON", "4300 digits")


def test_a_fifo_directory_or_device_in_place_of_the_data_or_index_is_never_read(bundle, tmp_path) -> None:
    """Found by tests/test_fuzz.py: pairs.dat and pairs.idx were opened as they were, so a FIFO in their
    place made the reader wait for a writer for ever, /dev/zero as the index was read without end, and
    a directory as pairs.dat escaped as an IsADirectoryError. (The timeouts are only guards.)"""
    copy = _copy(bundle, tmp_path)
    data = copy / "pairs.dat"
    data.unlink()
    os.mkfifo(data)
    one_line_error(
        trackerd("recording", "check", copy, timeout=60), "recording", "pairs.dat: not a regular file (a FIFO)"
    )
    data.unlink()
    data.mkdir()
    one_line_error(trackerd("replay", copy, timeout=60), "replay", "pairs.dat: a directory")
    data.rmdir()
    shutil.copy(bundle / "pairs.dat", data)
    index = copy / "pairs.idx"
    for hostile in ("fifo", "/dev/zero"):
        index.unlink()
        if hostile == "fifo":
            os.mkfifo(index)
        else:
            index.symlink_to(hostile)
        check = trackerd("recording", "check", copy, "--json", timeout=60)
        assert "Traceback" not in check.stderr, check.stderr
        report = json.loads(check.stdout)
        assert (report["pairs"], report["indexed"], report["recovered"]) == (16, 0, 16), report
        assert "pairs.idx: not a regular file" in report["problems"][0], report["problems"]


def _rewritten(bundle: Path, out: Path, retimed) -> Path:
    """The bundle written again by the real writer with each pair's capture time ``retimed(index, ns)``,
    as another program or a broken clock would (every checksum valid)."""
    import dataclasses

    from trackerd.recording.writer import RecordingWriter

    with Recording.open(bundle) as source:
        writer = RecordingWriter(out, source.metadata.model_copy(update={"end": None}))
        for index in range(len(source)):
            pair = source.pair(index)
            writer.write(dataclasses.replace(pair, timestamp_ns=retimed(index, pair.timestamp_ns)))
        writer.close("test")
    return out


@pytest.mark.parametrize(
    ("moved", "bad", "said"),
    [
        ("pairs 10 on 1000 s back", range(10, 16), "pair 10 at byte {offset}: captured 999.933 s before pair 9"),
        (
            "the first pair a day ahead",
            range(0, 1),
            "pair 0 at byte {offset}: captured 86399.933 s after pair 1, which",
        ),
    ],
    ids=["back", "first ahead"],
)
def test_pairs_whose_capture_times_go_back_are_damaged_not_replayed(
    bundle, tmp_path, moved: str, bad: range, said: str
) -> None:
    """Found by a new user's audit: pairs 10 on of a recording moved 1000 s back in time (checksums made
    again) were called intact, and replay crashed its publishing thread on the negative duration of the
    pointer's stay on the display. The time line is the longest run of pairs whose times never go back, so a
    single bogus time, even the first pair's, is the pair left out."""
    shift_ns = -1000 * 10**9 if moved.startswith("pairs 10") else 86_400 * 10**9
    retimed = _rewritten(bundle, tmp_path / "retimed.trec", lambda i, ns: ns + (shift_ns if i in bad else 0))
    with Recording.open(retimed) as recording:
        offset = recording.entries[bad[0]].offset
    check = trackerd("recording", "check", retimed)
    assert check.returncode == 1, check.stdout
    assert f"pairs.dat: {said.format(offset=offset)}" in check.stdout and "(times go back)" in check.stdout
    assert f"{len(bad)} problem(s); {16 - len(bad)} pairs replay" in check.stdout, check.stdout
    run = _replay(retimed)
    assert "Traceback" not in run.stderr and "crashed" not in run.stderr, run.stderr
    summary = json.loads(run.stdout)
    # The pairs left replay as the same pairs of the untouched recording do.
    first, count = (1, 15) if bad[0] == 0 else (0, 10)
    same = _replay(bundle, "--first", str(first), "--count", str(count), "--speed", "max")
    untouched = json.loads(same.stdout)
    assert summary["pairs"] == 16 - len(bad) == untouched["pairs"] and summary["hits"] == untouched["hits"], summary
    assert f"{len(bad)} damaged pair(s) skipped" in run.stderr and run.returncode == 1, (run.returncode, run.stderr)


def test_a_gap_of_days_is_no_damage_and_replay_does_not_wait_it(bundle, tmp_path) -> None:
    """Found by a new user's audit: pairs moved days ahead made replay at the recorded speed wait for them (it
    would have sat for days). Such a gap can be real (stills imported from two sessions), so it is no damage:
    replay waits at most MAX_REPLAY_GAP_NS for it (at four times the recorded speed here, 2.5 s) and publishes
    the recorded capture times."""
    from trackerd.recording.replay import MAX_REPLAY_GAP_NS

    retimed = _rewritten(bundle, tmp_path / "gap.trec", lambda i, ns: ns + (3 * 86_400 * 10**9 if i >= 10 else 0))
    check = trackerd("recording", "check", retimed)
    assert check.returncode == 0 and "intact" in check.stdout, check.stdout
    run = _replay(retimed, "--speed", "4")
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr
    summary = json.loads(run.stdout)
    as_recorded, _, _ = _replay_summary(bundle)
    assert summary["pairs"] == 16 and summary["hits"] == as_recorded["hits"], (summary, as_recorded)
    assert summary["seconds"] < 3 * 86_400 / 4, summary  # not the recorded gap's wait
    assert summary["seconds"] >= MAX_REPLAY_GAP_NS / 4 / 1e9, summary  # but the capped one


def test_check_counts_what_replay_refuses_and_what_an_error_cut_short(bundle, tmp_path) -> None:
    """Found by a new user's audit: `recording check` called "intact" (exit 0) a recording whose stated pixel
    format has another frame size (Mono16, 16 bits a pixel), one whose recorded rig replay refuses, and one
    a failed import closed as interrupted."""
    copy = _copy(bundle, tmp_path)
    meta_path = copy / "recording.json"
    original = json.loads(meta_path.read_text())

    def with_meta(change) -> None:
        meta = json.loads(json.dumps(original))
        change(meta)
        meta_path.write_text(json.dumps(meta))

    with_meta(lambda m: m["cameras"][0].update(pixel_format="Mono16"))
    said = "cameras.0.pixel_format: 'Mono16' is not a format a recording stores"
    one_line_error(trackerd("recording", "check", copy), "recording", said)
    one_line_error(trackerd("replay", copy, "--endpoint", "tcp://127.0.0.1:*"), "replay", said)
    one_line_error(trackerd("recording", "export", copy, tmp_path / "out"), "recording", said)
    with_meta(lambda m: m["rig"]["pointer"].update(length_m=-1))
    check = trackerd("recording", "check", copy)
    assert check.returncode == 1 and "the recorded rig does not validate" in check.stdout, check.stdout
    assert "16 pairs replay" in check.stdout
    with_meta(lambda m: m["end"].update(reason="error: import interrupted"))
    check = trackerd("recording", "check", copy)
    assert check.returncode == 1, check.stdout
    assert "recording.json: the recording ended with an error (error: import interrupted)" in check.stdout
