"""Reading still images as camera frames, for `trackerd locate` and recording import.

A file becomes a frame in one of the pixel formats the detector understands:

* a single-channel PNG/TIFF/PGM (or JPEG) is the camera's raw Bayer mosaic, in
  the pixel format the rig configures for that camera;
* a three-channel PNG/JPEG is a colour image (BGR8 as OpenCV reads it);
* a ``.npy`` file holds the raw frame exactly as the camera delivers it
  (shape (H, W) for Bayer, (H, W, 3) for RGB8/BGR8, dtype uint8).

The image size must match the camera's configured resolution, since the
calibration is only valid at that size.

A file can hold something else than what the camera delivers and still be read:
a demosaiced or annotated picture (a `trackerd snap` ``-view.png``) from a Bayer
camera, or a grey picture saved as one channel. :func:`raw_format_doubt` says why
such a frame is suspect, for the commands to warn.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path
from typing import cast

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import CameraConfig
from trackerd.errors import ImageError
from trackerd.files import NotRegularFile, TooLarge, read_bounded
from trackerd.pixelformat import frame_shape, is_bayer


def read_frame(path: str | Path, camera: CameraConfig, grey_ok: bool = False) -> tuple[NDArray[np.uint8], str]:
    """Read an image file as a frame from ``camera``: (frame, pixel format of the frame).

    A single-channel image is the raw mosaic of a Bayer camera and a Mono8 camera's frame; from a
    camera of another format it is refused unless ``grey_ok`` (calibration: a board is grey anyway),
    and then read as Mono8.
    """
    path = Path(path)
    data = _file_bytes(path)
    if path.suffix.lower() == ".npy":
        if not data.startswith(b"\x93NUMPY"):
            # np.load takes anything else for a pickle, and says so: that is not what is wrong.
            raise ImageError(f"{path}: not a NumPy .npy file (it does not begin with \\x93NUMPY)")
        try:
            frame = np.load(io.BytesIO(data), allow_pickle=False)
        except (OSError, ValueError, EOFError) as err:
            raise ImageError(f"{path}: not a readable NumPy file ({err})") from err
        expected = frame_shape(camera.pixel_format, camera.width_px, camera.height_px)
        if frame.dtype != np.uint8 or frame.shape != expected:
            raise ImageError(
                f"{path}: holds a {frame.dtype} array of shape {frame.shape}; camera '{camera.id}'"
                f" delivers {camera.pixel_format} frames of shape {expected} (uint8)"
            )
        return frame, camera.pixel_format
    # Decoded from the bytes read here: OpenCV's imread crashed (a segmentation fault) on a file name that
    # is not UTF-8, and its size limit (a PNG header claiming 100000x100000) raises its own error.
    # OpenCV's own warnings about a damaged file ("PNG input buffer is incomplete") are silenced while it
    # decodes: the line below says what is wrong, once.
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        decoded = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED) if data else None
    except cv2.error as err:
        raise ImageError(f"{path}: not an image OpenCV can read ({_opencv_reason(err)})") from None
    finally:
        cv2.utils.logging.setLogLevel(level)
    if decoded is None:
        raise ImageError(f"{path}: not an image OpenCV can read (PNG, JPEG, TIFF, PGM, or .npy)")
    if decoded.dtype != np.uint8:
        raise ImageError(f"{path}: {decoded.dtype} pixels; only 8-bit images are supported")
    # OpenCV's stubs type every image as an array of any number type; the dtype was checked just above.
    frame = cast(NDArray[np.uint8], decoded)
    height, width = frame.shape[:2]
    if (width, height) != (camera.width_px, camera.height_px):
        raise ImageError(
            f"{path}: image is {width}x{height} but camera '{camera.id}' is configured for"
            f" {camera.width_px}x{camera.height_px} (its calibration only holds at that size)"
        )
    if frame.ndim == 2:
        if camera.pixel_format == "Mono8" or (grey_ok and not is_bayer(camera.pixel_format)):
            return frame, "Mono8"
        if not is_bayer(camera.pixel_format):
            raise ImageError(
                f"{path}: single-channel image, but camera '{camera.id}' delivers {camera.pixel_format};"
                " a single channel is only read as a Bayer mosaic"
            )
        return frame, camera.pixel_format
    if frame.ndim == 3 and frame.shape[2] == 4:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    if frame.ndim == 3 and frame.shape[2] == 3:
        return np.ascontiguousarray(frame), "BGR8"
    raise ImageError(f"{path}: unsupported image layout {frame.shape}")


MAX_IMAGE_BYTES = 1 << 30
"""No still of a camera frame is larger (an uncompressed 8K RGB TIFF is 100 MB)."""


def write_png(path: Path, image: NDArray[np.uint8]) -> None:
    """``image`` as a PNG at ``path``; ImageError saying why not. Encoded in memory and written here, so that
    a full disk says so (cv2.imwrite says only that libpng failed, on a line of its own), and a file cut
    short is removed: every PNG left is whole."""
    encoded, data = cv2.imencode(".png", image)
    if not encoded:
        raise ImageError(f"{path}: cannot encode the image as PNG")
    try:
        path.write_bytes(data.tobytes())
    except OSError as err:
        with contextlib.suppress(OSError):  # a read-only file system refuses that too
            path.unlink()
        raise ImageError(f"{path}: cannot write the image: {err.strerror or err}") from err


def _file_bytes(path: Path) -> bytes:
    """The file's bytes, or ImageError saying in one line why there are none."""
    try:
        return read_bounded(path, MAX_IMAGE_BYTES)
    except FileNotFoundError:
        raise ImageError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ImageError(f"{path}: a directory, not an image") from None
    except (NotRegularFile, TooLarge) as err:
        raise ImageError(f"{err}; not an image") from None
    except OSError as err:
        raise ImageError(f"{path}: cannot read ({err.strerror or err})") from None


def _opencv_reason(err: cv2.error) -> str:
    """What an OpenCV error says is wrong, without its source file and line."""
    condition = str(getattr(err, "err", "") or "").strip()
    if "CV_IO_MAX_IMAGE_PIXELS" in condition:
        return "its header claims more pixels than any camera frame has: damaged, or not a camera's image"
    return condition or "OpenCV refused it"


MOSAIC_SMOOTHNESS_LIMIT = 0.9
"""Below this :func:`mosaic_smoothness`, a single channel is not a raw Bayer mosaic. Pixel noise alone
gives 1; trackerd's rendered raw mosaics give 2.1-2.4, the same frames demosaiced and made grey 0.72."""


def mosaic_smoothness(frame: NDArray[np.uint8]) -> float | None:
    """How alike neighbouring pixels are against pixels two apart; None for a flat image.

    The mean absolute difference between neighbours over that between pixels two
    apart, along rows and columns, for an (H, W) image. In a raw Bayer mosaic,
    neighbours sit behind different colour filters and pixels two apart behind the
    same one, so anything coloured makes neighbours differ more (a ratio above 1).
    A grey or demosaiced picture is interpolated, so neighbours are more alike than
    pixels two apart (below 1).
    """
    image = frame.astype(np.int16)
    near = np.abs(np.diff(image, axis=1)).mean() + np.abs(np.diff(image, axis=0)).mean()
    far = np.abs(image[:, 2:] - image[:, :-2]).mean() + np.abs(image[2:] - image[:-2]).mean()
    return None if far == 0 else float(near / far)


def raw_format_doubt(frame: NDArray[np.uint8], pixel_format: str, camera: CameraConfig) -> str | None:
    """Why ``frame``, read from a file as ``pixel_format`` for ``camera``, is not what a Bayer camera
    delivers; None when it looks raw (or the camera is not a Bayer camera).

    The detector's centroids, and so the stated uncertainty of a hit, assume the
    raw mosaic: demosaicing, lossy compression or marks drawn on the picture move
    the ends it measures, silently.
    """
    if not is_bayer(camera.pixel_format):
        return None
    raw = "give the raw frame: a single-channel PNG as `trackerd snap` saves it, or .npy"
    if frame.ndim == 3:
        return (
            f"a colour (3-channel) image, but camera '{camera.id}' delivers raw {camera.pixel_format} mosaics:"
            " a demosaiced, compressed or annotated picture can move the ends by more than the stated"
            f" uncertainty, which holds only for raw frames; {raw}"
        )
    smoothness = mosaic_smoothness(frame) if is_bayer(pixel_format) else None
    if smoothness is not None and smoothness < MOSAIC_SMOOTHNESS_LIMIT:
        return (
            f"a single-channel image without the 2x2 structure of camera '{camera.id}'s raw"
            f" {camera.pixel_format} mosaic (neighbouring pixels differ {smoothness:.2f} times as much as"
            f" pixels two apart; a raw mosaic's differ more): a grey or demosaiced picture, whose colours are"
            f" lost; {raw}"
        )
    return None
