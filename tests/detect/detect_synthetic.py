"""Synthetic frames for the detector tests: analytic, anti-aliased shapes in any pixel format.

Each shape's coverage of every pixel is computed by supersampling, so the true
centroid of a ball's visible image is known exactly (the coverage-weighted mean
of pixel centres, OpenCV's convention: the top-left pixel's centre is (0, 0)).
The RGB image is mosaiced into the camera's format (a Bayer mosaic keeps one
channel per pixel, as trackerd.pixelformat.from_rgb does) and sensor noise is
added. Imported by the tests as ``detect_synthetic``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

RED = (0.86, 0.10, 0.08)
BLUE = (0.10, 0.20, 0.86)
WALL = (0.62, 0.63, 0.60)
ROD = (0.10, 0.10, 0.11)

SUPERSAMPLE = 8


@dataclass
class Shape:
    """A disc (``radius``) or an axis-aligned rectangle (``half_size``), in pixels."""

    x: float
    y: float
    rgb: tuple[float, float, float]
    radius: float = 0.0
    half_size: tuple[float, float] = (0.0, 0.0)
    shading: float = 0.0
    """Brightness falls linearly by this fraction from the top of the shape to its bottom."""

    def coverage(self, xs: NDArray[np.float64], ys: NDArray[np.float64]) -> NDArray[np.bool_]:
        if self.radius > 0:
            return (xs - self.x) ** 2 + (ys - self.y) ** 2 <= self.radius**2
        return (np.abs(xs - self.x) <= self.half_size[0]) & (np.abs(ys - self.y) <= self.half_size[1])

    def extent(self) -> float:
        return self.radius if self.radius > 0 else max(self.half_size)


@dataclass
class Scene:
    width: int = 200
    height: int = 150
    background: tuple[float, float, float] = WALL
    shapes: list[Shape] = field(default_factory=list)
    rods: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    """Dark lines (x0, y0, x1, y1, half-width) drawn under the shapes."""

    def render(
        self, pixel_format: str, rng: np.random.Generator, noise: float = 2.0
    ) -> tuple[NDArray[np.uint8], list[NDArray[np.float64]]]:
        """The frame, and each shape's true visible centroid (x, y) (NaN if hidden)."""
        rgb = np.empty((self.height, self.width, 3))
        rgb[:] = self.background
        offsets = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5
        for x0, y0, x1, y1, half in self.rods:
            self._paint(
                rgb,
                offsets,
                lambda xs, ys, a=(x0, y0, x1, y1, half): _near_segment(xs, ys, *a),
                (x0, y0, x1, y1),
                half + 1,
                ROD,
                0.0,
                None,
            )
        truths = []
        for shape in self.shapes:
            truths.append(
                self._paint(
                    rgb,
                    offsets,
                    shape.coverage,
                    (shape.x, shape.y, shape.x, shape.y),
                    shape.extent() + 2,
                    shape.rgb,
                    shape.shading,
                    shape,
                )
            )
        frame_rgb = rgb * 255.0
        exact = _mosaic_float(frame_rgb, pixel_format)
        values = np.clip(np.rint(exact + noise * rng.standard_normal(exact.shape)), 0, 255)
        return values.astype(np.uint8), truths

    def _paint(self, rgb, offsets, inside, box, reach, colour, shading, shape):
        """Composite one shape by its coverage; return its coverage centroid."""
        x0 = max(int(np.floor(min(box[0], box[2]) - reach)), 0)
        x1 = min(int(np.ceil(max(box[0], box[2]) + reach)) + 1, self.width)
        y0 = max(int(np.floor(min(box[1], box[3]) - reach)), 0)
        y1 = min(int(np.ceil(max(box[1], box[3]) + reach)) + 1, self.height)
        if x1 <= x0 or y1 <= y0:
            return None  # entirely outside the image
        px, py = np.meshgrid(np.arange(x0, x1, dtype=float), np.arange(y0, y1, dtype=float))
        sx = px[..., None, None] + offsets[None, None, None, :]
        sy = py[..., None, None] + offsets[None, None, :, None]
        cover = inside(sx, sy).mean(axis=(2, 3))
        tone = np.asarray(colour, dtype=float)
        if shading and shape is not None:
            top = shape.y - shape.extent()
            factor = 1.0 - shading * np.clip((py - top) / (2 * shape.extent()), 0, 1)
            paint = tone[None, None, :] * factor[..., None]
        else:
            paint = np.broadcast_to(tone, (*cover.shape, 3))
        region = rgb[y0:y1, x0:x1]
        region[:] = cover[..., None] * paint + (1 - cover[..., None]) * region
        total = cover.sum()
        return np.array([(cover * px).sum() / total, (cover * py).sum() / total]) if total else None


def _near_segment(xs, ys, x0, y0, x1, y1, half):
    dx, dy = x1 - x0, y1 - y0
    t = np.clip(((xs - x0) * dx + (ys - y0) * dy) / (dx * dx + dy * dy), 0, 1)
    return (xs - x0 - t * dx) ** 2 + (ys - y0 - t * dy) ** 2 <= half * half


def _mosaic_float(rgb: NDArray[np.float64], pixel_format: str) -> NDArray[np.float64]:
    """from_rgb for float images (exact values, before noise and rounding)."""
    from trackerd.pixelformat import BAYER_LAYOUTS

    layout = BAYER_LAYOUTS.get(pixel_format)
    if layout is None:
        return rgb if pixel_format == "RGB8" else rgb[..., ::-1].copy()
    out = np.empty(rgb.shape[:2])
    for (row, col), channel in (
        (layout.red, 0),
        (layout.green_a, 1),
        (layout.green_b, 1),
        (layout.blue, 2),
    ):
        out[row::2, col::2] = rgb[row::2, col::2, channel]
    return out


def pointer(x: float, y: float, dx: float, dy: float, radius: float, **kw) -> list[Shape]:
    """A red ball at (x, y) and a blue ball at (x + dx, y + dy)."""
    return [Shape(x, y, RED, radius=radius, **kw), Shape(x + dx, y + dy, BLUE, radius=radius, **kw)]
