"""Calibration input from files: images of one camera, folders of pairs, wall targets and measured walls.

Naming in a folder of pairs (``--pairs DIR``): one image per camera and moment,
``<name>-<camera id>.<ext>``, for example ``07-left.png`` and ``07-right.png``
(the convention of tests/data/pairs and of the snapshots the --live modes
save), or ``<camera id><name>.<ext>`` (``left07.png``), or a subfolder per
camera (``left/07.png``); :func:`pair_files` says which it used. For the wall,
``<name>`` is the target's label, optionally followed by ``-<n>`` for the n-th
place it was pointed at from: ``tl-left.png``, ``centre-2-right.png``.

Images are read as camera frames by :func:`trackerd.images.read_frame`: a
single-channel image is the camera's raw Bayer mosaic (for a board, a grey image
from a camera of any other format), a colour image is BGR, ``.npy`` holds the
raw frame; the size must be the camera's.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from trackerd.calibration import CalibrationError
from trackerd.calibration.collect import Frame
from trackerd.calibration.wall import CORNER_LABELS, Target
from trackerd.config.loader import describe_validation_error, read_toml
from trackerd.config.models import CameraConfig, WallConfig
from trackerd.errors import ConfigError, ImageError
from trackerd.image_pairs import IMAGE_SUFFIXES, PairedImages, camera_named_in, images_in, pair_images
from trackerd.images import read_frame

GRID_LABELS = {"bottom": (0.5, 0.0), "top": (0.5, 1.0), "left": (0.0, 0.5), "right": (1.0, 0.5), "centre": (0.5, 0.5)}
"""With the corners, a 3 x 3 grid of display-defined targets, as fractions of the display."""


def _read_input_toml(path: Path) -> dict:
    """A TOML input file the user named (--points, --targets). Like images and pairs, a missing or
    unreadable one is a bad input (exit 1), not a configuration problem (exit 2, the rig file's)."""
    try:
        return read_toml(path)
    except ConfigError as err:
        raise CalibrationError(str(err)) from err


def camera_frames(paths: Sequence[str | Path], camera: CameraConfig) -> Iterator[Frame]:
    """Frames of one camera from image files, in the order given (ImageError names a bad file)."""
    for path in paths:
        frame, fmt = read_frame(path, camera, grey_ok=True)
        yield Path(path).name, frame, fmt


def pair_files(directory: str | Path, camera_ids: Sequence[str]) -> PairedImages:
    """A folder's images grouped by moment (:func:`trackerd.image_pairs.pair_images`); a folder that
    cannot be paired is a bad input (CalibrationError)."""
    try:
        return pair_images(directory, camera_ids)
    except ImageError as err:
        raise CalibrationError(str(err)) from err


def image_files(paths: Sequence[str | Path], camera_id: str, camera_ids: Sequence[str]) -> tuple[list[Path], list[str]]:
    """The image files named, with each folder among them replaced by its images (natural order).

    From a folder whose images are named for the rig's cameras (``left01.jpg``, ``07-left.png``), only
    this camera's are taken; a folder none of whose images is named for a camera is taken whole, and
    the line said for it says so. Returns the files and a line for each folder saying what was taken.
    """
    out: list[Path] = []
    said: list[str] = []
    ids = sorted(camera_ids, key=len, reverse=True)  # 'left2' is tried before 'left'
    for given in paths:
        path = Path(given)
        if not path.is_dir():
            out.append(path)
            continue
        images = images_in(path)
        if not images:
            inner = sorted(p.name for p in path.iterdir() if p.is_dir())
            within = f"; it holds the folder(s) {', '.join(inner)}: name the camera's own" if inner else ""
            raise CalibrationError(f"{path}: a folder without images ({', '.join(IMAGE_SUFFIXES)}){within}")
        owner = {image: camera_named_in(image.stem, ids) for image in images}
        mine = [image for image in images if owner[image] == camera_id]
        if any(owner.values()):
            if not mine:
                raise CalibrationError(
                    f"{path}: no image named for camera {camera_id} (its images are named for"
                    f" {', '.join(sorted({c for c in owner.values() if c}))})"
                )
            said.append(f"{path}: the {len(mine)} named for camera {camera_id} of its {len(images)} image(s)")
            out.extend(mine)
        else:
            said.append(
                f"{path}: all {len(images)} image(s) (none is named for a camera; all are taken as {camera_id}'s)"
            )
            out.extend(images)
    return out, said


def read_pair(files: dict[str, Path], cameras: Sequence[CameraConfig], grey_ok: bool = False) -> list[Frame]:
    """One frame per camera (rig order) of one moment; grey images from any camera with ``grey_ok``
    (a board's pairs), else as :func:`trackerd.images.read_frame` reads them for the pointer."""
    frames = []
    for cam in cameras:
        frame, fmt = read_frame(files[cam.id], cam, grey_ok=grey_ok)
        frames.append((files[cam.id].name, frame, fmt))
    return frames


def split_label(name: str) -> str:
    """A wall image's target label: ``centre-2`` -> ``centre``, ``tl`` -> ``tl``."""
    match = re.match(r"^(.*?)-(\d+)$", name)
    return match.group(1) if match else name


# --------------------------------------------------------------------------- wall targets


def default_targets(width_m: float, height_m: float) -> dict[str, Target]:
    """Corners (bl, br, tr, tl) and the 3 x 3 grid's other points (bottom, top, left, right, centre)."""
    out = {}
    for label, (fx, fy) in (*CORNER_LABELS.items(), *GRID_LABELS.items()):
        out[label] = Target(label, np.array([fx * width_m, fy * height_m]), True)
    return out


def read_targets(
    path: str | Path, width_m: float, height_m: float, display_px: tuple[int, int] | None
) -> dict[str, Target]:
    """Targets from a TOML file's ``[targets]`` table, added to the default ones.

    Each entry is one of::

        mark1 = { x_m = 1.60, y_m = 0.10 }       # measured on the wall (metres from bottom-left)
        cross = { x_px = 3840, y_px = 960 }      # a display pixel (top-left origin, y down)
        third = { x = 0.33, y = 0.5 }            # fractions of the display's width and height

    Display pixels and fractions move with the display's size when it is solved
    for; measured marks do not.
    """
    path = Path(path)
    data = _read_input_toml(path)
    table = data.get("targets")
    if not isinstance(table, dict) or not table:
        raise CalibrationError(f"{path}: needs a [targets] table, e.g. mark1 = {{ x_m = 1.6, y_m = 0.1 }}")
    extra = sorted(set(data) - {"targets"})
    if extra:
        raise CalibrationError(f"{path}: unknown key '{extra[0]}'; the file holds a [targets] table")
    out = default_targets(width_m, height_m)
    for label, entry in table.items():
        where = f"{path}: targets.{label}"
        if not isinstance(entry, dict):
            raise CalibrationError(f"{where}: expected {{ x_m = ..., y_m = ... }} (or x_px/y_px, or x/y)")
        keys = set(entry)
        try:
            if keys == {"x_m", "y_m"}:
                out[label] = Target(label, np.array([float(entry["x_m"]), float(entry["y_m"])]), False)
            elif keys == {"x_px", "y_px"}:
                if display_px is None:
                    raise CalibrationError(
                        f"{where}: display pixels need the wall's display_width_px and display_height_px"
                    )
                x = float(entry["x_px"]) / display_px[0] * width_m
                y = (1.0 - float(entry["y_px"]) / display_px[1]) * height_m
                out[label] = Target(label, np.array([x, y]), True)
            elif keys == {"x", "y"}:
                out[label] = Target(label, np.array([float(entry["x"]) * width_m, float(entry["y"]) * height_m]), True)
            else:
                raise CalibrationError(
                    f"{where}: give x_m and y_m (metres), x_px and y_px (display pixels), or x and y"
                    f" (fractions); got {', '.join(sorted(keys)) or 'nothing'}"
                )
        except (TypeError, ValueError) as err:
            raise CalibrationError(f"{where}: not a number ({err})") from err
        xy_m = out[label].wall_xy_m
        if xy_m is None or not np.all(np.isfinite(xy_m)):
            raise CalibrationError(f"{where}: not a finite number")
    return out


def read_measured_wall(path: str | Path) -> WallConfig:
    """A [wall] table (the rig file's form) holding measured points or corners, in the cameras' frame."""
    from pydantic import ValidationError

    path = Path(path)
    data = _read_input_toml(path)
    if "wall" not in data:
        raise CalibrationError(
            f"{path}: needs a [wall] table: corners_m = [...] or points_m = [...] with origin_m, x_direction,"
            " y_direction, width_m and height_m, measured in the cameras' frame"
        )
    extra = sorted(set(data) - {"wall"})
    if extra:
        raise CalibrationError(f"{path}: unknown key '{extra[0]}'; the file holds a [wall] table")
    try:
        return WallConfig.model_validate(data["wall"])
    except ValidationError as err:
        detail = describe_validation_error(err, WallConfig)
        if detail.startswith("(top level): "):
            raise CalibrationError(f"{path}: wall: {detail.removeprefix('(top level): ')}") from err
        raise CalibrationError(f"{path}: wall.{detail}") from err
