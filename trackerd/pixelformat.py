"""Pixel formats: what the cameras deliver and how to move between raw frames and RGB.

Colour GigE Vision cameras usually send the raw Bayer mosaic (one byte per
pixel, each pixel behind one colour filter). The detector works on the mosaic's
colour planes directly; converting to RGB (demosaicing) is for viewing,
exporting, the OpenCV reference pipeline and the search over a whole frame
(:func:`search_rgb`, trackerd/joint/search.py).

GenICam names the pattern by its top-left 2x2 cell read row by row: BayerRG8 is
    R G
    G B
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import cv2
import numpy as np
from numpy.typing import NDArray

Image = NDArray[np.uint8]


@dataclass(frozen=True)
class BayerLayout:
    """Offsets (row, column) of each colour within the 2x2 Bayer cell."""

    red: tuple[int, int]
    green_a: tuple[int, int]
    green_b: tuple[int, int]
    blue: tuple[int, int]


BAYER_LAYOUTS: dict[str, BayerLayout] = {
    "BayerRG8": BayerLayout(red=(0, 0), green_a=(0, 1), green_b=(1, 0), blue=(1, 1)),
    "BayerGR8": BayerLayout(red=(0, 1), green_a=(0, 0), green_b=(1, 1), blue=(1, 0)),
    "BayerGB8": BayerLayout(red=(1, 0), green_a=(0, 0), green_b=(1, 1), blue=(0, 1)),
    "BayerBG8": BayerLayout(red=(1, 1), green_a=(0, 1), green_b=(1, 0), blue=(0, 0)),
}

# OpenCV 4.10+ and 5.x name Bayer conversions by the full top-left 2x2 pattern
# (BayerRGGB == GenICam BayerRG); the older two-letter names are off by one row.
_DEMOSAIC_TO_RGB = {
    "BayerRG8": cv2.COLOR_BayerRGGB2RGB,
    "BayerGR8": cv2.COLOR_BayerGRBG2RGB,
    "BayerGB8": cv2.COLOR_BayerGBRG2RGB,
    "BayerBG8": cv2.COLOR_BayerBGGR2RGB,
}

_DEMOSAIC_EDGE_AWARE = {
    name: code + (cv2.COLOR_BayerRGGB2RGB_EA - cv2.COLOR_BayerRGGB2RGB) for name, code in _DEMOSAIC_TO_RGB.items()
}

SUPPORTED = ("BayerRG8", "BayerGB8", "BayerGR8", "BayerBG8", "RGB8", "BGR8")

# GenICam Pixel Format Naming Convention (PFNC) codes, as Aravis reports them.
PFNC_CODES = {
    "Mono8": 0x01080001,
    "BayerGR8": 0x01080008,
    "BayerRG8": 0x01080009,
    "BayerGB8": 0x0108000A,
    "BayerBG8": 0x0108000B,
    "RGB8": 0x02180014,
    "BGR8": 0x02180015,
}
PFNC_NAMES = {code: name for name, code in PFNC_CODES.items()}


def is_bayer(pixel_format: str) -> bool:
    return pixel_format in BAYER_LAYOUTS


def bytes_per_pixel(pixel_format: str) -> int:
    """Bytes one pixel takes in a frame of this format."""
    if is_bayer(pixel_format) or pixel_format == "Mono8":
        return 1
    if pixel_format in ("RGB8", "BGR8"):
        return 3
    raise ValueError(f"unsupported pixel format {pixel_format!r}")


def frame_shape(pixel_format: str, width_px: int, height_px: int) -> tuple[int, ...]:
    """NumPy shape of a frame: (H, W) for one byte per pixel, (H, W, 3) for RGB8/BGR8."""
    if bytes_per_pixel(pixel_format) == 1:
        return (height_px, width_px)
    return (height_px, width_px, 3)


def frame_nbytes(pixel_format: str, width_px: int, height_px: int) -> int:
    """Bytes of one frame's pixels (rows not padded)."""
    return width_px * height_px * bytes_per_pixel(pixel_format)


def image_from_payload(
    payload: bytes | bytearray | memoryview | NDArray[np.uint8], pixel_format: str, width_px: int, height_px: int
) -> Image | None:
    """A buffer's payload as the frame's image: a read-only view, no copy (None if the payload is short).

    The payload is the image's rows top to bottom, each row's pixels left to right, one byte per
    pixel (Bayer, Mono8) or three (RGB8: R, G, B; BGR8: B, G, R), rows not padded. The image is
    (H, W) or (H, W, 3) uint8 (:func:`frame_shape`); bytes past the image are ignored.
    """
    nbytes = frame_nbytes(pixel_format, width_px, height_px)
    # Aravis hands bytes, pylon a bytearray, GenTL a NumPy array: every one is a buffer.
    available = payload.nbytes if isinstance(payload, np.ndarray) else memoryview(payload).nbytes
    if available < nbytes:
        return None
    image = np.frombuffer(payload, dtype=np.uint8, count=nbytes).reshape(frame_shape(pixel_format, width_px, height_px))
    image.flags.writeable = False
    return image


def _uint8(converted: object) -> Image:
    """A colour conversion's result, typed as what it is: OpenCV converts uint8 to uint8, but its stubs
    type every result as an array of any number type."""
    return cast(Image, converted)


def to_rgb(frame: Image, pixel_format: str) -> Image:
    """Any supported frame -> an (H, W, 3) RGB image (Bayer is demosaiced bilinearly by OpenCV)."""
    if is_bayer(pixel_format):
        return _uint8(cv2.cvtColor(frame, _DEMOSAIC_TO_RGB[pixel_format]))
    if pixel_format == "RGB8":
        return frame
    if pixel_format == "BGR8":
        return np.ascontiguousarray(frame[..., ::-1])
    if pixel_format == "Mono8":
        return np.repeat(frame[..., None], 3, axis=2)
    raise ValueError(f"unsupported pixel format {pixel_format!r}")


def search_rgb(frame: Image, pixel_format: str) -> Image:
    """A Bayer mosaic -> (H, W, 3) RGB at full resolution, demosaiced by OpenCV's edge-aware method, for the
    search over a whole frame (trackerd/joint/search.py). Not bilinearly: that gives every sharp edge in the room
    a fringe of false colour (a display's frame, black letters on white), which the search's hue test takes for
    paint; on the independent rooms at 1920x1200 such fringes made a hit 360 mm off at 42 sigma
    (docs/detection.md, "A Bayer frame searched as RGB")."""
    return _uint8(cv2.cvtColor(frame, _DEMOSAIC_EDGE_AWARE[pixel_format]))


def to_bgr(frame: Image, pixel_format: str) -> Image:
    """Any supported frame -> (H, W, 3) BGR, the channel order cv2.imwrite expects."""
    return np.ascontiguousarray(to_rgb(frame, pixel_format)[..., ::-1])


def from_rgb(rgb: Image, pixel_format: str) -> Image:
    """An (H, W, 3) RGB image -> a frame in ``pixel_format`` (Bayer keeps one channel per pixel)."""
    if pixel_format == "RGB8":
        return np.ascontiguousarray(rgb)
    if pixel_format == "BGR8":
        return np.ascontiguousarray(rgb[..., ::-1])
    if pixel_format == "Mono8":
        return _uint8(cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2GRAY))
    layout = BAYER_LAYOUTS.get(pixel_format)
    if layout is None:
        raise ValueError(f"unsupported pixel format {pixel_format!r}")
    height, width = rgb.shape[:2]
    mosaic = np.empty((height, width), dtype=np.uint8)
    for (row, col), channel in ((layout.red, 0), (layout.green_a, 1), (layout.green_b, 1), (layout.blue, 2)):
        mosaic[row::2, col::2] = rgb[row::2, col::2, channel]
    return mosaic
