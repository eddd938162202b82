"""Where record, snap, import and export write: a bad output is one line before any work, and a refused
recording leaves nothing behind."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from rec_helpers import BUNDLE, one_line_error, trackerd

from trackerd.config.recording import RecordingConfig
from trackerd.recording.reader import Recording
from trackerd.recording.recorder import Recorder
from trackerd.recording.writer import DiskFullError, RecordingWriter, build_metadata

RIG = Path(__file__).resolve().parents[2] / "config" / "simulated.toml"


@pytest.fixture
def a_file(tmp_path) -> Path:
    path = tmp_path / "afile"
    path.write_text("not a folder\n")
    return path


@pytest.mark.parametrize("where", ["the file", "under the file", "/proc"])
def test_export_to_a_folder_it_cannot_write_is_one_line(a_file, tmp_path, where: str) -> None:
    out = {"the file": a_file, "under the file": a_file / "sub", "/proc": Path("/proc/trackerd-export")}[where]
    run = trackerd("recording", "export", BUNDLE, out, "--no-images")
    line = one_line_error(run, "recording", str(out))
    assert "folder" in line
    assert not (tmp_path / "hits.csv").exists()


def test_export_into_a_recording_is_refused_and_leaves_it_as_it_was(tmp_path) -> None:
    recording = tmp_path / "session.trec"
    shutil.copytree(BUNDLE, recording)  # a copy: were it written into, the test data would be spoilt
    before = sorted(p.name for p in recording.iterdir())
    run = trackerd("recording", "export", BUNDLE, recording, "--no-images")
    one_line_error(run, "recording", str(recording), "is a recording")
    assert sorted(p.name for p in recording.iterdir()) == before


def test_snap_into_a_file_is_refused_before_the_cameras_open(a_file) -> None:
    # No --virtual and no cameras on this machine: refused for the folder, it never reaches the cameras
    # (the pair a snap takes is not lost for a folder it cannot write).
    run = trackerd("snap", "--config", RIG, a_file)
    one_line_error(run, "snap", str(a_file), "is not a folder")
    assert "camera" not in run.stderr.lower()


@pytest.mark.parametrize("command", ["record", "import"])
def test_a_recording_that_cannot_be_created_is_refused_before_any_work(a_file, tmp_path, command: str) -> None:
    out = a_file / "x.trec"
    if command == "record":
        run = trackerd("record", "--config", RIG, out, "--pairs", "1")
    else:
        run = trackerd("recording", "import", tmp_path, out, "--config", RIG)
    label = "record" if command == "record" else "recording"
    one_line_error(run, label, str(out), f"{a_file} is a file, not a folder")
    assert "camera" not in run.stderr.lower() and "no images" not in run.stderr


def test_record_refused_for_free_space_leaves_no_folder_behind(small_disk) -> None:
    out = small_disk / "session.trec"
    run = trackerd("record", "--config", RIG, out, "--seconds", "1")  # the rig leaves 1024 MB free
    one_line_error(run, "record", str(out), "less than the 1024 MB", "min_free_space_mb", "nothing was recorded")
    assert "camera" not in run.stderr.lower()
    assert not out.exists()


def test_a_recorder_refused_for_free_space_leaves_no_folder_behind(small_disk) -> None:
    """The daemon's path: the recorder makes the recording when the first pair arrives."""
    with Recording.open(BUNDLE) as recording:
        rig, pair = recording.rig(), recording.pair(0)
    out = small_disk / "ondemand.trec"
    recorder = Recorder(out, rig, producer="test", config=RecordingConfig(min_free_space_mb=100)).start()
    recorder.put(pair)
    assert recorder.stop(10.0)
    assert isinstance(recorder.error, DiskFullError) and "nothing was recorded" in str(recorder.error)
    assert recorder.status().state == "failed"
    assert not out.exists()
    # Once there is room the same name records (no "already exists" for a leftover folder).
    metadata = build_metadata(rig, pair, producer="test", clock_offset_ns=0)
    writer = RecordingWriter(out, metadata)
    writer.write(pair)
    writer.close()
    with Recording.open(out) as again:
        assert len(again) == 1 and again.problems == []


def _fill(disk: Path, leave_bytes: int) -> None:
    """Fill ``disk`` to within ``leave_bytes`` of full."""
    free = shutil.disk_usage(disk).free
    with (disk / "filler").open("wb") as handle:
        handle.write(b"\0" * max(free - leave_bytes, 0))


def test_export_onto_a_full_disk_says_so_and_keeps_what_it_wrote(small_disk) -> None:
    """Found by a new user's audit: a full disk met by the table's rows escaped as an OSError (a traceback),
    and one met by an image said only "cannot write the image" after libpng's own line, leaving a cut PNG."""
    import cv2

    _fill(small_disk, 0)
    run = trackerd("recording", "export", BUNDLE, small_disk / "rows", "--no-images")
    one_line_error(run, "recording", "rows/hits.csv: cannot write: No space left on device")
    (small_disk / "filler").unlink()
    _fill(small_disk, 256 * 1024)  # room for the table's rows, not for a 1080p pair's images
    run = trackerd("recording", "export", BUNDLE, small_disk / "images", "--every", "1")
    one_line_error(run, "recording", "images/000000-", ".png: cannot write the image: No space left on device")
    assert "libpng" not in run.stderr, run.stderr
    # Every image left is whole, and the table holds every row written before the disk filled.
    for image in (small_disk / "images").glob("*.png"):
        assert cv2.imread(str(image), cv2.IMREAD_UNCHANGED) is not None, image
    rows = (small_disk / "images" / "hits.csv").read_text().splitlines()
    assert rows[0].startswith("pair_index,") and rows[1].startswith("0,"), rows[:2]


def test_a_recording_whose_first_pair_meets_a_full_disk_leaves_nothing_behind(small_disk) -> None:
    """Found by a new user's audit: with no free-space margin (min_free_space_mb = 0) a disk with room for
    the recording's files but not its first pair said "nothing was recorded" and left the folder, its
    recording.json without an end record (the full disk took none), read as a recording never finished."""
    with Recording.open(BUNDLE) as recording:
        rig, pair = recording.rig(), recording.pair(0)
    _fill(small_disk, 64 * 1024)
    out = small_disk / "ondemand.trec"
    recorder = Recorder(out, rig, producer="test", config=RecordingConfig(min_free_space_mb=0)).start()
    recorder.put(pair)
    assert recorder.stop(10.0)
    assert isinstance(recorder.error, DiskFullError) and recorder.status().pairs == 0, recorder.error
    assert not out.exists()
    # And an import into the same room: one line, nothing imported, nothing left.
    import cv2

    images = small_disk.parent / "images"
    images.mkdir()
    for frame in pair.frames:
        cv2.imwrite(str(images / f"00-{frame.camera_id}.png"), frame.image)
    run = trackerd("recording", "import", images, small_disk / "imported.trec", "--config", RIG)
    one_line_error(run, "recording", "imported.trec", "disk full", "nothing was imported")
    assert not (small_disk / "imported.trec").exists()


def test_a_snapshot_that_meets_a_full_disk_says_why_and_leaves_no_half_of_itself(small_disk) -> None:
    """A new user's audit: a snapshot on a full disk said "cannot write the image" after libpng's own line,
    without the cause, and left its folder behind (empty, or with one camera's image)."""
    from trackerd.errors import ImageError
    from trackerd.locator import Locator
    from trackerd.recording.snapshot import write_snapshot

    with Recording.open(BUNDLE) as recording:
        rig, pair = recording.rig(), recording.pair(0)
    locator = Locator(rig)
    fix = locator.locate(pair.images)
    _fill(small_disk, 64 * 1024)
    folder = small_disk / "snaps" / "snap-1"
    with pytest.raises(ImageError, match=r"snap-1-left.png: cannot write the image: No space left on device"):
        write_snapshot(pair, fix, locator, rig, folder, "snap-1")
    assert not folder.exists()
    # A folder the user made (`trackerd snap OUT`) stays, empty, as it was.
    mine = small_disk / "mine"
    mine.mkdir()
    with pytest.raises(ImageError, match="No space left on device"):
        write_snapshot(pair, fix, locator, rig, mine, "snap-2")
    assert mine.is_dir() and not any(mine.iterdir())


def test_a_conversion_that_reads_no_pair_leaves_nothing(tmp_path) -> None:
    """A new user's review: a source whose every pair is damaged converted into an empty recording and said
    nothing of it (docs/recording.md says a conversion that wrote no pair leaves nothing)."""
    copy = tmp_path / "damaged.trec"
    shutil.copytree(BUNDLE, copy)
    with Recording.open(copy) as recording:
        inside = [entry.offset + entry.record_bytes - 100 for entry in recording.entries]  # in each last frame
    data = bytearray((copy / "pairs.dat").read_bytes())
    for at in inside:
        data[at] ^= 0xFF
    (copy / "pairs.dat").write_bytes(bytes(data))
    out = tmp_path / "converted.trec"
    run = trackerd("recording", "convert", copy, out, "--mode", "compressed")
    assert "nothing was converted" in run.stderr and run.returncode == 1, (run.returncode, run.stderr)
    assert "Traceback" not in run.stderr
    assert not out.exists()
