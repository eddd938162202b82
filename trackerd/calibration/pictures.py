"""Pictures of a calibration, for an operator who would rather look than read (`--report DIR`).

For a camera's lens: each view with its detected corners and their reprojection residuals drawn
RESIDUAL_GAIN times longer than they are, a map of where the corners fell across the image, and the
per-view RMS as bars (outliers in red). For the stereo pair: a pair rectified side by side with
horizontal epipolar lines (a corner lies on the same line in both images when the pose is right),
and the per-pair RMS as bars. ``index.html`` ties them together with the figures.

Drawn with OpenCV (already a dependency): the pictures are diagnostic, not charts to publish.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.calibration import CalibrationError
from trackerd.calibration.board import BoardView
from trackerd.calibration.intrinsics import IntrinsicsResult
from trackerd.calibration.stereo import StereoPair, StereoResult

RESIDUAL_GAIN = 20.0
"""Residual arrows are drawn this many times their length (a 0.2 px residual becomes 4 px)."""
MAX_WIDTH_PX = 1280
"""Pictures wider than this are scaled down."""

DETECTED_BGR = (0, 200, 0)
RESIDUAL_BGR = (0, 0, 255)
COVERED_BGR = (60, 160, 60)
UNCOVERED_BGR = (40, 40, 40)
BAR_BGR = (200, 140, 40)
OUTLIER_BGR = (0, 0, 230)


@dataclass(frozen=True)
class Picture:
    file: str
    caption: str


def _bgr(grey: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return np.asarray(cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR), dtype=np.uint8) if grey.ndim == 2 else grey.copy()


def _fit_width(image: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], float]:
    scale = min(1.0, MAX_WIDTH_PX / image.shape[1])
    if scale < 1.0:
        image = np.asarray(cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA), dtype=np.uint8)
    return image, scale


def _write(folder: Path, name: str, image: NDArray[np.uint8]) -> str:
    if not cv2.imwrite(str(folder / name), image):
        raise CalibrationError(f"--report: {folder / name}: could not be written")
    return name


def _remove_old(folder: Path, pattern: str) -> None:
    """A step run again: its earlier run's single-view pictures go (it may have had other views)."""
    for old in folder.glob(pattern):
        old.unlink(missing_ok=True)


def _report_folder(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise CalibrationError(f"--report: {folder}: cannot make the folder ({err.strerror or err})") from err


def _label(image: NDArray[np.uint8], text: str) -> None:
    """The title on a dark band across the top (legible over any image)."""
    cv2.rectangle(image, (0, 0), (image.shape[1] - 1, 30), (0, 0, 0), -1)
    cv2.putText(image, text, (8, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)


def view_picture(
    grey: NDArray[np.uint8], detected_px: NDArray[np.float64], reprojected_px: NDArray[np.float64], title: str
) -> NDArray[np.uint8]:
    """The image with each detected corner circled and an arrow to where the lens model puts it,
    RESIDUAL_GAIN times longer than the residual."""
    image, scale = _fit_width(_bgr(grey))
    for found, model in zip(detected_px * scale, reprojected_px * scale, strict=True):
        start = (float(found[0]), float(found[1]))
        end = found + RESIDUAL_GAIN * (model - found)
        cv2.circle(image, (round(start[0]), round(start[1])), 4, DETECTED_BGR, 1, cv2.LINE_8)
        cv2.arrowedLine(
            image,
            (round(start[0]), round(start[1])),
            (round(end[0]), round(end[1])),
            RESIDUAL_BGR,
            1,
            cv2.LINE_AA,
            tipLength=0.3,
        )
    _label(image, f"{title}  (residuals x{RESIDUAL_GAIN:g})")
    return image


def coverage_picture(result: IntrinsicsResult, views: Sequence[BoardView]) -> NDArray[np.uint8]:
    """The image's area as the coverage grid: cells where corners fell filled, the corners dotted."""
    width, height = result.image_size
    scale = min(1.0, MAX_WIDTH_PX / width)
    w, h = round(width * scale), round(height * scale)
    image = np.zeros((h, w, 3), np.uint8)
    grid = result.coverage
    for row in range(grid.rows):
        for col in range(grid.cols):
            x0, x1 = round(col * w / grid.cols), round((col + 1) * w / grid.cols)
            y0, y1 = round(row * h / grid.rows), round((row + 1) * h / grid.rows)
            colour = COVERED_BGR if grid.covered[row, col] else UNCOVERED_BGR
            cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), colour, -1)
            cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), (90, 90, 90), 1)
    for view in views:
        for x, y in view.image_points_px * scale:
            cv2.circle(image, (round(x), round(y)), 1, (255, 255, 255), -1)
    _label(image, f"corners of {len(views)} views cover {grid.fraction * 100:.0f} % of the image")
    return image


def bars_picture(
    names: Sequence[str], values: Sequence[float], outliers: Sequence[int], title: str
) -> NDArray[np.uint8]:
    """One bar per view (outliers red) with the median as a line, in pixels of RMS."""
    count = len(values)
    bar, gap, left, top, height = 18, 6, 50, 40, 240
    width = left + count * (bar + gap) + gap + 10
    image = np.full((top + height + 110, max(width, 420), 3), 255, np.uint8)
    top_value = max(max(values, default=0.0) * 1.15, 1e-3)

    def y_of(value: float) -> int:
        return top + height - round(value / top_value * height)

    cv2.line(image, (left, top + height), (width - 10, top + height), (0, 0, 0), 1)
    for k, (name, value) in enumerate(zip(names, values, strict=True)):
        x0 = left + gap + k * (bar + gap)
        colour = OUTLIER_BGR if k in outliers else BAR_BGR
        cv2.rectangle(image, (x0, y_of(value)), (x0 + bar - 1, top + height - 1), colour, -1)
        label = np.full((14, 90, 3), 255, np.uint8)
        cv2.putText(label, name[:14], (0, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
        turned = cv2.rotate(label, cv2.ROTATE_90_CLOCKWISE)
        ys, xs = top + height + 4, x0 + 2
        image[ys : ys + turned.shape[0], xs : xs + turned.shape[1]] = np.minimum(
            image[ys : ys + turned.shape[0], xs : xs + turned.shape[1]], turned
        )
    median = float(np.median(values)) if count else 0.0
    cv2.line(image, (left, y_of(median)), (width - 10, y_of(median)), (0, 150, 0), 1)
    cv2.putText(image, f"{top_value:.2f}", (4, top + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(image, "0", (30, top + height + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(
        image,
        f"{title} (px); median {median:.3f} (green); outliers red",
        (8, 22),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (0, 0, 0),
        1,
        cv2.LINE_AA,
    )
    return image


def intrinsics_pictures(
    folder: Path,
    camera_id: str,
    result: IntrinsicsResult,
    views: Sequence[BoardView],
    images: Mapping[str, NDArray[np.uint8]],
) -> list[Picture]:
    """Write a lens's pictures into ``folder``; ``images`` are the grey images by view name (views without
    one get no picture of their own)."""
    _report_folder(folder)
    _remove_old(folder, f"{camera_id}-view-*.png")
    by_name = {view.name: view for view in views}
    used = [by_name[name] for name in result.view_names if name in by_name]
    pictures = [
        Picture(
            _write(folder, f"{camera_id}-coverage.png", coverage_picture(result, used)),
            f"{camera_id}: where the corners fell (8 x 6 cells; dark cells have none)",
        ),
        Picture(
            _write(
                folder,
                f"{camera_id}-rms.png",
                bars_picture(
                    result.view_names, list(result.per_view_rms_px), result.outliers, f"{camera_id}: RMS of each view"
                ),
            ),
            f"{camera_id}: RMS of each view",
        ),
    ]
    for k, name in enumerate(result.view_names):
        view, grey = by_name.get(name), images.get(name)
        if view is None or grey is None:
            continue
        reprojected, _ = cv2.projectPoints(
            view.object_points_m.astype(np.float64),
            result.rvecs[k],
            result.tvecs_m[k],
            result.matrix,
            result.distortion,
        )
        title = f"{camera_id} {name}: RMS {result.per_view_rms_px[k]:.3f} px"
        projected_px = np.asarray(reprojected, dtype=np.float64).reshape(-1, 2)
        picture = view_picture(grey, view.image_points_px, projected_px, title)
        stem = Path(name).stem
        pictures.append(Picture(_write(folder, f"{camera_id}-view-{stem}.png", picture), title))
    return pictures


def rectified_picture(
    result: StereoResult, pair: StereoPair, grey1: NDArray[np.uint8], grey2: NDArray[np.uint8], ids: tuple[str, str]
) -> NDArray[np.uint8]:
    """Both images rectified side by side, horizontal lines every 32 px, each shared corner dotted:
    with a right pose a corner sits on the same line in both images."""
    size = (grey1.shape[1], grey1.shape[0])
    r1, r2, p1, p2, *_ = cv2.stereoRectify(
        result.lens1.matrix,
        result.lens1.distortion,
        result.lens2.matrix,
        result.lens2.distortion,
        size,
        np.ascontiguousarray(result.rotation, dtype=np.float64),
        np.asarray(result.translation_m, dtype=np.float64).reshape(3, 1),
        alpha=0,
    )
    halves = []
    for grey, lens, rect, proj, points in (
        (grey1, result.lens1, r1, p1, pair.points1_px),
        (grey2, result.lens2, r2, p2, pair.points2_px),
    ):
        map_x, map_y = cv2.initUndistortRectifyMap(lens.matrix, lens.distortion, rect, proj, size, cv2.CV_32FC1)
        image = _bgr(np.asarray(cv2.remap(grey, map_x, map_y, cv2.INTER_LINEAR), dtype=np.uint8))
        moved = cv2.undistortPoints(
            points.reshape(-1, 1, 2).astype(np.float64), lens.matrix, lens.distortion, R=rect, P=proj
        ).reshape(-1, 2)
        for x, y in moved:
            cv2.circle(image, (round(x), round(y)), 3, DETECTED_BGR, -1, cv2.LINE_AA)
        halves.append(image)
    both = np.hstack(halves)
    for y in range(16, both.shape[0], 32):
        cv2.line(both, (0, y), (both.shape[1] - 1, y), (0, 200, 255), 1)
    both, _ = _fit_width(both)
    k = result.pair_names.index(pair.name)
    epipolar = result.per_pair_epipolar_px[k]
    _label(both, f"{ids[0]} | {ids[1]} rectified, pair {pair.name}: epipolar RMS {epipolar:.3f} px")
    return both


def stereo_pictures(
    folder: Path,
    ids: tuple[str, str],
    result: StereoResult,
    pairs: Sequence[StereoPair],
    images: Mapping[str, tuple[NDArray[np.uint8], NDArray[np.uint8]]],
) -> list[Picture]:
    """Write the pair's pictures: per-pair RMS bars and each pair (with images) rectified."""
    _report_folder(folder)
    _remove_old(folder, "stereo-rectified-*.png")
    pictures = [
        Picture(
            _write(
                folder,
                "stereo-rms.png",
                bars_picture(
                    result.pair_names, list(result.per_pair_rms_px), result.outliers, "stereo: RMS of each pair"
                ),
            ),
            "stereo: RMS of each pair (both cameras)",
        ),
    ]
    by_name = {pair.name: pair for pair in pairs}
    for name in result.pair_names:
        pair, grey = by_name.get(name), images.get(name)
        if pair is None or grey is None:
            continue
        picture = rectified_picture(result, pair, grey[0], grey[1], ids)
        pictures.append(
            Picture(
                _write(folder, f"stereo-rectified-{Path(name).stem}.png", picture),
                f"pair {name} rectified: a corner lies on the same horizontal line in both images",
            )
        )
    return pictures


def write_index(folder: Path, title: str, figures: Sequence[str], pictures: Sequence[Picture]) -> Path:
    """``index.html``: for each step, its figures and every picture with its caption. A step run again
    replaces its own section (its pictures were written over), the other steps' stay."""
    index = folder / "index.html"
    sections: list[tuple[str, str]] = []
    if index.is_file():
        text = index.read_text()
        for block in text.split("<!-- section ")[1:]:
            name, _, rest = block.partition(" -->")
            kept, _, _ = rest.partition("<!-- /section -->")
            if name != html.escape(title):
                sections.append((name, kept))
    body = [f"<h2>{html.escape(title)}</h2>", "<ul>"]
    body += [f"<li>{html.escape(line.strip())}</li>" for line in figures]
    body.append("</ul>")
    for picture in pictures:
        body.append(
            f'<figure><img src="{html.escape(picture.file)}" alt="{html.escape(picture.caption)}">'
            f"<figcaption>{html.escape(picture.caption)}</figcaption></figure>"
        )
    sections.append((html.escape(title), "\n" + "\n".join(body) + "\n"))
    text = (
        '<!doctype html>\n<html><head><meta charset="utf-8"><title>trackerd calibration report</title>\n'
        "<style>body{font-family:sans-serif;margin:2em} img{max-width:100%;border:1px solid #ccc}"
        " figure{margin:1em 0}</style></head><body>\n<h1>trackerd calibration report</h1>\n"
        + "".join(f"<!-- section {name} -->{body}<!-- /section -->\n" for name, body in sections)
        + "</body></html>\n"
    )
    try:
        index.write_text(text)
    except OSError as err:
        raise CalibrationError(f"--report: {index}: cannot be written ({err.strerror or err})") from err
    return index
