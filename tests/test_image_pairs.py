"""Folders of image pairs in the common layouts, on real (empty) files."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackerd.errors import ImageError
from trackerd.image_pairs import pair_images


def _touch(folder: Path, *names: str) -> None:
    for name in names:
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"")


def _pairs(folder: Path, ids=("left", "right")) -> tuple[list[tuple[str, dict[str, str]]], str]:
    found = pair_images(folder, list(ids))
    return [(m.name, {c: p.name for c, p in m.files.items()}) for m in found.moments], found.layout


def test_each_layout_pairs_by_name_in_natural_order(tmp_path: Path) -> None:
    _touch(tmp_path / "suffix", "10-left.png", "10-right.png", "2_left.png", "2_right.png", "notes.txt")
    pairs, layout = _pairs(tmp_path / "suffix")
    assert [name for name, _ in pairs] == ["2", "10"]
    assert pairs[1] == ("10", {"left": "10-left.png", "right": "10-right.png"})
    assert layout == "files named <name>-<camera> (left, right)"

    _touch(tmp_path / "prefix", "left01.jpg", "right01.jpg", "left-02.jpg", "right-02.jpg")
    pairs, layout = _pairs(tmp_path / "prefix")
    assert pairs == [
        ("01", {"left": "left01.jpg", "right": "right01.jpg"}),
        ("02", {"left": "left-02.jpg", "right": "right-02.jpg"}),
    ]
    assert layout == "files named <camera><name> (left, right)"

    _touch(tmp_path / "split", "left/left01.jpg", "right/right01.jpg", "left/02.png", "right/02.png")
    pairs, layout = _pairs(tmp_path / "split")
    assert [name for name, _ in pairs] == ["01", "02"]
    assert layout == "subfolders left/, right/ (files paired by name)"


def test_a_camera_whose_id_starts_another_ones_is_told_apart(tmp_path: Path) -> None:
    _touch(tmp_path, "left1.png", "left21.png", "07-left.png", "07-left2.png")
    pairs, _ = _pairs(tmp_path, ids=("left", "left2"))
    assert pairs == [("07", {"left": "07-left.png", "left2": "07-left2.png"})]


def test_folders_that_cannot_be_paired_say_why(tmp_path: Path) -> None:
    with pytest.raises(ImageError, match="no such folder"):
        pair_images(tmp_path / "absent", ["left", "right"])
    _touch(tmp_path / "none", "a.png", "b.png")
    with pytest.raises(ImageError, match=r"no images of cameras left, right: name them <name>-<camera>"):
        pair_images(tmp_path / "none", ["left", "right"])
    _touch(tmp_path / "one", "01-left.png", "01-right.png", "02-left.png")
    with pytest.raises(ImageError, match=r"'02' has 02-left\.png but no image from right"):
        pair_images(tmp_path / "one", ["left", "right"])
    _touch(tmp_path / "twice", "left/01.png", "left/left01.png", "right/01.png")
    with pytest.raises(ImageError, match="two images of camera 'left' for '01'"):
        pair_images(tmp_path / "twice", ["left", "right"])
