"""Folders of still images, one per camera and moment: which files belong together.

Calibration (``--pairs DIR``, a folder of one camera's board photos) and ``trackerd recording import``
both read folders made elsewhere, named in one of the common ways:

* files ``<name>-<camera>.<ext>`` (or ``_``): ``07-left.png``, trackerd's own snapshots;
* files ``<camera><name>.<ext>`` (with or without ``-``/``_``): ``left07.jpg``, as OpenCV's samples;
* one subfolder per camera, named by its id: ``left/07.png`` (a camera prefix or suffix on the file
  name is dropped from the moment's name, so ``left/left07.png`` pairs with ``right/right07.png``).

:func:`pair_images` uses the layout that pairs the most images and says which it was.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from trackerd.errors import ImageError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".pgm", ".bmp", ".npy")


@dataclass(frozen=True)
class Moment:
    """One moment of a folder: its name and one image per camera."""

    name: str
    files: dict[str, Path]


@dataclass(frozen=True)
class PairedImages:
    """A folder's images grouped by moment, and how they were paired (to tell the user)."""

    moments: list[Moment]
    """In natural order of the names (``2`` before ``10``)."""
    layout: str
    """Which naming paired them, e.g. 'files named <camera><name> (left, right)'."""


def natural_key(text: str) -> list[object]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", text)]


def images_in(folder: Path) -> list[Path]:
    """The image files directly in a folder, in natural order of their names."""
    return sorted(
        (p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()),
        key=lambda p: natural_key(p.name),
    )


def _name_by_suffix(stem: str, cam_id: str) -> str | None:
    """``07-left`` -> ``07``: the camera's id ends the name, after ``-`` or ``_``."""
    for sep in "-_":
        if stem.endswith(sep + cam_id) and len(stem) > len(cam_id) + 1:
            return stem[: -len(cam_id) - 1]
    return None


def _name_by_prefix(stem: str, cam_id: str) -> str | None:
    """``left07``, ``left-07``, ``left_07`` -> ``07``: the camera's id starts the name."""
    for sep in ("-", "_", ""):
        if stem.startswith(cam_id + sep) and len(stem) > len(cam_id) + len(sep):
            return stem[len(cam_id) + len(sep) :]
    return None


def camera_named_in(stem: str, ids_longest_first: Sequence[str]) -> str | None:
    """The camera a file name is named for (``07-left``, ``left07``), or None."""
    for cam_id in ids_longest_first:
        if _name_by_suffix(stem, cam_id) or _name_by_prefix(stem, cam_id):
            return cam_id
    return None


class _Groups:
    """Moments being filled in, refusing two images of one camera for one moment."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.by_name: dict[str, dict[str, Path]] = {}

    def add(self, name: str, cam_id: str, path: Path) -> None:
        files = self.by_name.setdefault(name, {})
        if cam_id in files:
            raise ImageError(
                f"{self.folder}: two images of camera '{cam_id}' for '{name}': {files[cam_id].name} and {path.name}"
            )
        files[cam_id] = path

    @property
    def count(self) -> int:
        return sum(len(files) for files in self.by_name.values())


def _files_by(folder: Path, ids: Sequence[str], name_of: Callable[[str, str], str | None]) -> _Groups:
    groups = _Groups(folder)
    for path in images_in(folder):
        for cam_id in ids:
            name = name_of(path.stem, cam_id)
            if name:
                groups.add(name, cam_id, path)
                break
    return groups


def _subfolders(folder: Path, camera_ids: Sequence[str]) -> _Groups:
    groups = _Groups(folder)
    for cam_id in camera_ids:
        for path in images_in(folder / cam_id):
            name = _name_by_prefix(path.stem, cam_id) or _name_by_suffix(path.stem, cam_id) or path.stem
            groups.add(name, cam_id, path)
    return groups


def pair_images(folder: str | Path, camera_ids: Sequence[str]) -> PairedImages:
    """Group a folder's images by moment, in whichever layout pairs the most of them.

    Raises ImageError for a missing folder, a folder without images of these cameras, two images of
    one camera for one moment, or a moment that lacks one camera's image.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ImageError(f"{folder}: no such folder")
    ids = sorted(camera_ids, key=len, reverse=True)  # 'left2' is tried before 'left'
    cameras = ", ".join(camera_ids)
    candidates = [
        (f"files named <name>-<camera> ({cameras})", _files_by(folder, ids, _name_by_suffix)),
        (f"files named <camera><name> ({cameras})", _files_by(folder, ids, _name_by_prefix)),
    ]
    if all((folder / cam_id).is_dir() for cam_id in camera_ids):
        subfolders = ", ".join(f"{c}/" for c in camera_ids)
        candidates.append((f"subfolders {subfolders} (files paired by name)", _subfolders(folder, camera_ids)))
    layout, groups = max(candidates, key=lambda candidate: candidate[1].count)
    if not groups.count:
        first = camera_ids[0]
        raise ImageError(
            f"{folder}: no images of cameras {cameras}: name them <name>-<camera>.<ext> (07-{first}.png) or"
            f" <camera><name>.<ext> ({first}07.png), or put each camera's images in a subfolder named by its"
            f" id ({first}/07.png)"
        )
    moments = []
    for name in sorted(groups.by_name, key=natural_key):
        files = groups.by_name[name]
        missing = [cam_id for cam_id in camera_ids if cam_id not in files]
        if missing:
            have = ", ".join(p.name for p in files.values())
            raise ImageError(
                f"{folder}: '{name}' has {have} but no image from {', '.join(missing)}:"
                " every moment needs one image per camera, taken at the same instant"
            )
        moments.append(Moment(name, files))
    return PairedImages(moments, layout)
