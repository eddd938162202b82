"""Still images read as camera frames (trackerd/images.py): real pair images under hostile names and
hostile files in their place, each read or refused in one line, never a crash."""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from trackerd.config.loader import load_rig
from trackerd.errors import ImageError
from trackerd.images import read_frame

REPO = Path(__file__).resolve().parents[1]
PAIRS = REPO / "tests" / "data" / "pairs"
RIG = REPO / "config" / "simulated.toml"


@pytest.fixture(scope="module")
def left():
    return load_rig(RIG).config.cameras[0]


def _png_claiming(width: int, height: int) -> bytes:
    """A PNG whose header claims ``width`` x ``height`` pixels, with one tiny data chunk."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(bytes(11))) + chunk(b"IEND", b"")
    )


def test_a_file_name_that_is_not_utf8_reads_as_the_same_frame(left, tmp_path) -> None:
    """OpenCV's imread crashed the process (a segmentation fault) on such a name; the bytes are read here."""
    odd = Path(os.fsdecode(bytes(tmp_path) + b"/n\xffame.png"))
    shutil.copy(PAIRS / "01-left.png", odd)
    frame, fmt = read_frame(odd, left)
    original, original_fmt = read_frame(PAIRS / "01-left.png", left)
    assert fmt == original_fmt and np.array_equal(frame, original)


def test_locate_takes_a_file_name_that_is_not_utf8(tmp_path) -> None:
    odd = os.fsdecode(bytes(tmp_path) + b"/n\xffame.png")
    shutil.copy(PAIRS / "01-left.png", odd)
    run = subprocess.run(
        [sys.executable, "-m", "trackerd", "locate", "--config", str(RIG), odd, str(PAIRS / "01-right.png")],
        capture_output=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert b"wall hit:" in run.stdout


def test_hostile_files_in_a_frames_place_are_one_line_each(left, tmp_path) -> None:
    (tmp_path / "huge.png").write_bytes(_png_claiming(100_000, 100_000))
    os.symlink(tmp_path / "loop-b.png", tmp_path / "loop-a.png")
    os.symlink(tmp_path / "loop-a.png", tmp_path / "loop-b.png")
    (tmp_path / "folder.png").mkdir()
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "text.npy").write_text("left camera, frame 7\n")  # was "contains pickled (object) data"
    cases = {
        "text.npy": "not a NumPy .npy file",
        "huge.png": "its header claims more pixels than any camera frame has",
        "loop-a.png": "cannot read (Too many levels of symbolic links)",
        "folder.png": "a directory, not an image",
        "empty.png": "not an image OpenCV can read",
        "missing.png": "no such file",
    }
    for name, says in cases.items():
        with pytest.raises(ImageError) as caught:
            read_frame(tmp_path / name, left)
        message = str(caught.value)
        assert message.startswith(f"{tmp_path / name}: ") and says in message and "\n" not in message, message
