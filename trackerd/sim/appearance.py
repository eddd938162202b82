"""How a rendered scene looks beyond its geometry: paints, light, occluders and what the wall shows.

The simulator's default look (:data:`DEFAULT_LOOK`) is the one every existing
bench and test was rendered with: a matte red and blue ball, a dark rod, one
point light, a plain exposure. Randomized scenes (:mod:`trackerd.sim.randomized`)
draw each of these from wide distributions instead, so that the detector and
locator are measured on scenes they were not tuned on:

* :class:`Look`: the pointer's paints and gloss, the light's strength and colour,
  an image-space illumination map (vignetting, a gradient, a spotlight);
* :class:`Occluder`: spheres and upright cylinders in front of the pointer (a
  hand over part of a ball, the presenter's body between a camera and an end);
* :func:`wall_content`: what the display shows in one frame (a colourful photo,
  a slide with red text, saturated blocks), as an RGB texture over the display.

Values are linear display values in [0, 1] before the exposure's gain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from trackerd.sim.scene import BLUE_BALL_RGB, RED_BALL_RGB, ROD_RGB, SKIN_RGB

Array = NDArray[np.float64]
RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Look:
    """The pointer's paint and the scene's lighting, as the renderer applies them."""

    red_rgb: RGB = RED_BALL_RGB
    blue_rgb: RGB = BLUE_BALL_RGB
    rod_rgb: RGB = ROD_RGB
    skin_rgb: RGB = SKIN_RGB
    ambient: float = 0.62
    diffuse: float = 0.38
    specular: float = 0.0
    """Strength of a white Phong highlight on the balls (0: matte paint)."""
    shininess: float = 40.0
    gain: float = 1.0
    """Exposure times gain: every value is multiplied by it before quantisation."""
    white_balance: RGB = (1.0, 1.0, 1.0)
    """Per-channel factors of the light's colour as the camera records it (warm: red up, blue down)."""
    vignetting: float = 0.0
    """Fraction of brightness lost at the image corners (cos^4-like falloff)."""
    gradient: tuple[float, float] = (0.0, 0.0)
    """Brightness change across the image, left to right and top to bottom (0.3: +-15 %)."""
    spot: tuple[float, float, float, float] | None = None
    """A spotlight on the image: (x, y) centre as fractions of the width and height, radius as a
    fraction of the diagonal, and its peak extra brightness."""

    def illumination(self, width_px: int, height_px: int) -> NDArray[np.float32] | None:
        """The image-space light (H, W, 3) the scene is multiplied by, or None when it is uniform 1."""
        uniform = (
            self.gain == 1.0
            and self.white_balance == (1.0, 1.0, 1.0)
            and self.vignetting == 0.0
            and self.gradient == (0.0, 0.0)
            and self.spot is None
        )
        if uniform:
            return None
        xs = (np.arange(width_px, dtype=np.float32) + 0.5) / width_px - 0.5
        ys = (np.arange(height_px, dtype=np.float32) + 0.5) / height_px - 0.5
        level = np.ones((height_px, width_px), dtype=np.float32)
        if self.vignetting:
            # r is 1 at the corners.
            r2 = (xs[None, :] ** 2 + ys[:, None] ** 2) / 0.5
            level *= np.float32(1.0) - np.float32(self.vignetting) * r2
        if self.gradient != (0.0, 0.0):
            gx, gy = (np.float32(g) for g in self.gradient)
            level *= np.float32(1.0) + gx * xs[None, :] + gy * ys[:, None]
        if self.spot is not None:
            sx, sy, radius, peak = self.spot
            diagonal = math.hypot(width_px, height_px)
            dx = (xs[None, :] + 0.5 - sx) * width_px
            dy = (ys[:, None] + 0.5 - sy) * height_px
            level *= np.float32(1.0) + np.float32(peak) * np.exp(
                -(dx * dx + dy * dy) / np.float32(2.0 * (radius * diagonal) ** 2)
            )
        wb = np.asarray(self.white_balance, dtype=np.float32) * np.float32(self.gain)
        return level[..., None] * wb[None, None, :]


DEFAULT_LOOK = Look()


@dataclass(frozen=True)
class Occluder:
    """Something in front of the pointer: a sphere, or an upright (world y) capped cylinder."""

    kind: str
    """'sphere' or 'cylinder'."""
    centre_m: tuple[float, float, float]
    """Sphere centre, or the centre of the cylinder's axis."""
    radius_m: float
    rgb: RGB
    height_m: float = 0.0
    """Cylinder length along world y."""
    label: str = field(default="", compare=False)
    """'hand', 'body': what it stands for, for the bench's tables."""


# ----------------------------------------------------------------------------- wall content

CONTENT_KINDS = ("dark slide", "photo", "red text", "saturated blocks", "blank")
"""What the display can show in a randomized scene."""

# Saturated colours a display shows that lie near the pointer's paints: the hard cases.
_NEAR_PAINT: tuple[RGB, ...] = (
    (0.92, 0.10, 0.12),
    (0.85, 0.15, 0.55),
    (0.95, 0.45, 0.08),
    (0.60, 0.12, 0.70),
    (0.12, 0.22, 0.90),
    (0.30, 0.20, 0.85),
    (0.75, 0.05, 0.05),
    (0.05, 0.30, 0.75),
    (0.90, 0.20, 0.35),
    (0.15, 0.55, 0.90),
)
_OTHER: tuple[RGB, ...] = (
    (0.95, 0.95, 0.92),
    (0.15, 0.70, 0.25),
    (0.95, 0.85, 0.15),
    (0.10, 0.10, 0.12),
    (0.55, 0.55, 0.58),
    (0.20, 0.75, 0.70),
    (0.80, 0.65, 0.45),
)


def wall_content(kind: str, rng: np.random.Generator, width_px: int = 768, height_px: int = 256) -> NDArray[np.float32]:
    """One frame of what the display shows: an (H, W, 3) RGB texture in [0, 1], row 0 at the top."""
    if kind not in CONTENT_KINDS:
        raise ValueError(f"unknown wall content {kind!r}; one of {', '.join(CONTENT_KINDS)}")
    h, w = height_px, width_px
    if kind == "blank":
        return np.full((h, w, 3), rng.uniform(0.02, 0.08), dtype=np.float32)
    if kind == "dark slide":
        image = np.zeros((h, w, 3), dtype=np.float32)
        image[:] = (0.10, 0.12, 0.17)
        cv2.rectangle(image, (int(0.03 * w), int(0.05 * h)), (int(0.97 * w), int(0.18 * h)), (0.55, 0.57, 0.60), -1)
        for k in range(5):
            x0 = int((0.05 + 0.18 * k + rng.uniform(0, 0.03)) * w)
            top = int((0.9 - rng.uniform(0.2, 0.6)) * h)
            colour = [(0.55, 0.35, 0.30), (0.30, 0.38, 0.55), (0.40, 0.50, 0.35)][k % 3]
            cv2.rectangle(image, (x0, top), (x0 + int(0.1 * w), int(0.9 * h)), colour, -1)
        return image
    if kind == "red text":
        # Drawn in 8 bits (OpenCV's text needs them), then back to [0, 1].
        paper = int(255 * rng.uniform(0.85, 0.97))
        slide = np.full((h, w, 3), paper, dtype=np.uint8)
        red = tuple(int(255 * c) for c in _NEAR_PAINT[int(rng.integers(0, 3))])
        lines = int(rng.integers(3, 6))
        for k in range(lines):
            y = int((k + 1) * h / (lines + 1)) + int(h / (3 * lines))
            text = "".join(chr(int(c)) for c in rng.integers(65, 91, size=int(rng.integers(8, 20))))
            scale = h / (lines + 1) / 28.0
            cv2.putText(
                slide,
                text,
                (int(0.05 * w), y),
                cv2.FONT_HERSHEY_SIMPLEX,
                scale,
                red,
                max(1, int(scale * 2.5)),
                cv2.LINE_AA,
            )
        if rng.uniform() < 0.6:
            blue = tuple(int(255 * c) for c in _NEAR_PAINT[int(rng.integers(4, 6))])
            cx, cy = int(rng.uniform(0.6, 0.9) * w), int(rng.uniform(0.2, 0.8) * h)
            cv2.circle(slide, (cx, cy), int(rng.uniform(0.05, 0.2) * h), blue, -1, cv2.LINE_AA)
        return slide.astype(np.float32) / np.float32(255.0)
    if kind == "saturated blocks":
        image = np.zeros((h, w, 3), dtype=np.float32)
        image[:] = _OTHER[int(rng.integers(0, len(_OTHER)))]
        for _ in range(int(rng.integers(6, 14))):
            colour = _NEAR_PAINT[int(rng.integers(0, len(_NEAR_PAINT)))]
            x0, y0 = int(rng.uniform(-0.1, 0.95) * w), int(rng.uniform(-0.1, 0.95) * h)
            x1, y1 = x0 + int(rng.uniform(0.05, 0.4) * w), y0 + int(rng.uniform(0.1, 0.6) * h)
            cv2.rectangle(image, (x0, y0), (x1, y1), colour, -1)
        return image
    # A photo: smooth colourful gradients with blobs of every colour, some near the paints.
    corners = rng.uniform(0.05, 0.95, size=(2, 2, 3)).astype(np.float32)
    # np.asarray: OpenCV's stubs type its results loosely; float32 in is float32 out (no copy here).
    image = np.asarray(cv2.resize(corners, (w, h), interpolation=cv2.INTER_LINEAR), dtype=np.float32)
    for _ in range(int(rng.integers(8, 20))):
        palette = _NEAR_PAINT if rng.uniform() < 0.5 else _OTHER
        blob_rgb = np.asarray(palette[int(rng.integers(0, len(palette)))]) * rng.uniform(0.7, 1.05)
        centre = (int(rng.uniform(0, w)), int(rng.uniform(0, h)))
        axes = (int(rng.uniform(0.03, 0.25) * w), int(rng.uniform(0.05, 0.5) * h))
        cv2.ellipse(
            image,
            centre,
            axes,
            float(rng.uniform(0, 180)),
            0,
            360,
            tuple(float(c) for c in np.clip(blob_rgb, 0, 1)),
            -1,
            cv2.LINE_AA,
        )
    image = np.asarray(cv2.GaussianBlur(image, (0, 0), float(rng.uniform(0.5, 3.0))), dtype=np.float32)
    return np.clip(image, 0.0, 1.0)
