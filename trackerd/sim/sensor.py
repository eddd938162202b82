"""The simulated sensor: RGB light to the camera's raw values (its Bayer mosaic), read and shot noise,
8-bit quantisation.

Every renderer of the simulator (the scene, the calibration board, the hand) goes through
:func:`raw_values` and :func:`sensor_output`, so their frames share one sensor model. Noise is
added after mosaicing, as a camera adds it to the raw values.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.pixelformat import BAYER_LAYOUTS, from_rgb

NOISE_FIELD_MARGIN_PX = 64
"""How much larger than its frame a camera's noise field is: the range of a frame's random offset in it."""


def raw_values(rgb: NDArray[np.float32], fmt: str, x0: int, y0: int) -> NDArray[np.float32]:
    """RGB floats (h, w, 3) -> the camera's raw values for a region starting at (x0, y0)."""
    layout = BAYER_LAYOUTS.get(fmt)
    if layout is None:
        if fmt == "RGB8":
            return rgb
        if fmt == "BGR8":
            return np.ascontiguousarray(rgb[..., ::-1])
        # Mono8, the one other format from_rgb knows: it is typed for 8-bit frames but only
        # converts the colour, so the floats pass through.
        return from_rgb(rgb, fmt).astype(np.float32)  # type: ignore[arg-type]  # pragma: no cover
    h, w = rgb.shape[:2]
    out = np.empty((h, w), dtype=np.float32)
    for (row, col), channel in ((layout.red, 0), (layout.green_a, 1), (layout.green_b, 1), (layout.blue, 2)):
        # The Bayer cell is anchored at the image origin, not the region's.
        r0 = (row - y0) % 2
        c0 = (col - x0) % 2
        out[r0::2, c0::2] = rgb[r0::2, c0::2, channel]
    return out


def sensor_output(
    values: NDArray[np.float32],
    rng: np.random.Generator,
    read_sigma: float,
    shot: float,
    noise: bool,
    draws: NDArray[np.float32] | None = None,
    *,
    scratch: NDArray[np.float32] | None = None,
) -> NDArray[np.uint8]:
    """[0, 1] values -> 8-bit sensor output with read and shot noise (``draws``: the standard normal
    draws to use, fresh ones from ``rng`` when None).

    ``scratch``: an array of ``values``' shape and type the work may be done in, ``values`` itself
    included: a renderer that makes many frames reuses its buffers (a new 100 MB array for a 4K RGB
    frame costs more in page faults than the arithmetic in it)."""
    if scratch is None:
        grey = values * np.float32(255.0)
        sigma = None
    else:
        grey = values
        grey *= np.float32(255.0)
        sigma = scratch
    if noise and (read_sigma > 0 or shot > 0):
        # In place (a 1080p frame is 2 M values): the same arithmetic as
        # grey + sqrt(read^2 + shot^2 * max(grey, 0)) * N(0, 1), bit for bit.
        sigma = np.maximum(grey, np.float32(0.0), out=sigma)
        sigma *= np.float32(shot**2)
        sigma += np.float32(read_sigma**2)
        np.sqrt(sigma, out=sigma)
        if draws is None:
            draws = rng.standard_normal(grey.shape, dtype=np.float32)
        sigma *= draws
        # OpenCV adds and rounds to 8 bits in one pass: its saturating cast rounds half to even and clips
        # as np.rint and np.clip do, so the frame is the same bit for bit, in half the time.
        return np.asarray(cv2.add(grey, sigma, dtype=cv2.CV_8U), dtype=np.uint8)
    np.rint(grey, out=grey)
    np.clip(grey, 0, 255, out=grey)
    return grey.astype(np.uint8)


class NoiseFields:
    """Each camera's sensor noise drawn once, a little larger than its frame; each frame gets a window
    of it at a random offset (white noise within a frame, a fraction of the cost of drawing millions
    of values a frame; for benchmarks that render thousands of frames)."""

    def __init__(self) -> None:
        self._fields: dict[int, NDArray[np.float32]] = {}

    def window(self, index: int, shape: tuple[int, ...], rng: np.random.Generator) -> NDArray[np.float32]:
        """A frame's standard normal draws: a window at a random offset in camera ``index``'s field
        (drawn from ``rng`` the first time)."""
        margin = NOISE_FIELD_MARGIN_PX
        field = self._fields.get(index)
        if field is None:
            field = rng.standard_normal((shape[0] + margin, shape[1] + margin, *shape[2:]), dtype=np.float32)
            self._fields[index] = field
        dy, dx = (int(v) for v in rng.integers(0, margin, size=2))
        return field[dy : dy + shape[0], dx : dx + shape[1]]
