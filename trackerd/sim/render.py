"""Ray-cast rendering of the room and the pointer through each camera of a rig (report section 4).

Every pixel's colour comes from casting rays through the camera's real lens
model (intrinsics and distortion, :class:`~trackerd.geometry.camera.CameraModel`;
:mod:`trackerd.sim.lens_rays`) into the scene of :mod:`trackerd.sim.scene`, so
the ground truth is exact. :class:`SceneRenderer` composes a frame from parts
that each own one thing:

* the static room (:mod:`trackerd.sim.room_shading`), rendered once per camera
  and cached in memory and on disk (:mod:`trackerd.sim.backgrounds`);
* what the wall's display shows in this frame (:mod:`trackerd.sim.display`);
* the pointer, its hand and any occluders (:mod:`trackerd.sim.pointer_shading`),
  rendered per frame only in tiles near its image and composited over the room
  by coverage (:mod:`trackerd.sim.pointer_render`); the same sub-pixel samples
  give the truth: the visible area of each ball and the centroid of that area,
  besides the projection of each ball's centre;
* the sensor (:mod:`trackerd.sim.sensor`): the Bayer mosaic, read and shot noise
  added to the raw values as a camera adds them, 8-bit quantisation.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dataclass_field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.geometry.camera import CameraModel
from trackerd.sim.appearance import DEFAULT_LOOK, Look, Occluder
from trackerd.sim.backgrounds import RENDER_VERSION, RoomBackgrounds, default_cache_dir
from trackerd.sim.display import DisplayScreen, ShownDisplay, overlay
from trackerd.sim.lens_rays import LensRays
from trackerd.sim.pointer_render import TILE_PX, PointerRenderer
from trackerd.sim.pointer_shading import PointerLook, silhouette_area_px
from trackerd.sim.room_shading import AMBIENT, DIFFUSE
from trackerd.sim.scene import PointerPose, Room, build_room, scene_pointer, scene_wall
from trackerd.sim.sensor import NoiseFields, raw_values, sensor_output

__all__ = [
    "AMBIENT",
    "DIFFUSE",
    "RENDER_VERSION",
    "TILE_PX",
    "RenderedView",
    "SceneRenderer",
    "ViewTruth",
    "default_cache_dir",
    "raw_values",
    "sensor_output",
    "silhouette_area_px",
]
"""The renderer, and (for the board and hand renderers and older importers) the names this module
held before it was split: the room's light terms, the sensor model, the cache's location."""

Array = NDArray[np.float64]
FloatImage = NDArray[np.float32]


@dataclass(frozen=True)
class ViewTruth:
    """Ground truth of one rendered view, per colour ('red', 'blue')."""

    centre_px: dict[str, Array]
    """Projection of each ball's centre (NaN if behind the camera)."""
    centroid_px: dict[str, Array]
    """Centroid of the ball's visible image region (NaN if fully hidden or off-image)."""
    area_px: dict[str, float]
    """Visible area of the ball's image, in pixels."""
    full_area_px: dict[str, float] = dataclass_field(default_factory=dict)
    """Area the ball's image would have with nothing in front of it and no frame edge (its
    silhouette, projected through the lens), in pixels."""

    def visible_fraction(self, colour: str) -> float:
        """Share of the ball's silhouette that is visible in the frame (0 when hidden or off-image)."""
        full = self.full_area_px.get(colour, 0.0)
        return float(min(1.0, self.area_px[colour] / full)) if full > 0 else 0.0


@dataclass(frozen=True)
class RenderedView:
    image: NDArray[np.uint8]
    """The frame as the camera would deliver it, in ``pixel_format``."""
    pixel_format: str
    truth: ViewTruth


class SceneRenderer:
    """Renders what each camera of a rig sees, with the pointer at any pose.

    One thread at a time: a renderer keeps its working buffers and the last pointer it cast between
    frames (each process of a benchmark's pool, and each loop worker, has its own)."""

    def __init__(
        self,
        rig: RigConfig,
        cameras: list[CameraModel] | None = None,
        *,
        cache_dir: Path | bool | None = True,
        look: Look = DEFAULT_LOOK,
        background_step: int = 1,
        noise_field: bool = False,
    ) -> None:
        """``look``: paints and light (the default is the look every bench was rendered with);
        ``background_step``: render the static room every this many pixels and interpolate (for
        large sensors in randomized scenes, where the room behind the pointer needs no detail);
        ``noise_field``: draw each camera's sensor noise once, a little larger than its frame, and give
        each frame a window of it at a random offset (see :class:`~trackerd.sim.sensor.NoiseFields`)."""
        self.rig = rig
        self.look = look
        self.noise_field = noise_field
        self.cameras = cameras if cameras is not None else [camera_model(c) for c in rig.cameras]
        self.pixel_formats = [c.pixel_format for c in rig.cameras]
        self.wall = wall_frame(scene_wall(rig))
        self.room: Room = build_room(rig, self.wall)
        self.front_colour = scene_pointer(rig).front_colour
        if cache_dir is True:
            self.cache_dir: Path | None = default_cache_dir()
        elif cache_dir is False or cache_dir is None:
            self.cache_dir = None
        else:
            self.cache_dir = Path(cache_dir)
        self.lens = LensRays(self.cameras)
        self.backgrounds = RoomBackgrounds(
            rig, self.cameras, self.room, self.lens, cache_dir=self.cache_dir, step=background_step
        )
        self.display = DisplayScreen(self.cameras, self.room, self.lens)
        self.pointer = PointerRenderer(
            self.cameras, self.lens, PointerLook.of(rig, self.room, look), rig.simulation.supersampling
        )
        self._noise = NoiseFields()
        self._illumination: dict[int, FloatImage | None] = {}
        self._buffers: dict[tuple[str, tuple[int, ...], str], FloatImage] = {}

    @property
    def background_step(self) -> int:
        return self.backgrounds.step

    def render(
        self,
        camera_index: int,
        pose: PointerPose | None,
        rng: np.random.Generator,
        *,
        motion_to: PointerPose | None = None,
        motion_steps: int = 6,
        pixel_format: str | None = None,
        noise: bool = True,
        occluders: tuple[Occluder, ...] = (),
        content: FloatImage | None = None,
    ) -> RenderedView:
        """Render one camera's view with the pointer at ``pose`` (None: no pointer).

        With ``motion_to``, the pointer moves linearly from ``pose`` to ``motion_to``
        during the exposure, sampled at ``motion_steps`` instants (motion blur);
        the truth is then averaged over the exposure. ``occluders`` stand in front
        of (or behind) the pointer; ``content`` is what the display shows
        (:func:`trackerd.sim.appearance.wall_content`), where the room's own slide is
        shown otherwise.
        """
        fmt = pixel_format or self.pixel_formats[camera_index]
        camera = self.cameras[camera_index]
        # The room, lit and mosaiced, is cached per format; each frame changes only the display's region
        # (its content) and the pointer's, which are composed in RGB, lit and mosaiced on their own.
        lit = self.backgrounds.lit_in_format(camera_index, fmt, self._illumination_map(camera_index))
        mosaic = self._buffer("frame", lit)
        np.copyto(mosaic, lit)
        display: ShownDisplay | None = None
        if content is not None:
            display = self.display.showing(camera_index, content, self.backgrounds.rgb(camera_index))
            self._put(mosaic, display.rgb, camera_index, fmt, display.c0, display.r0)
        truth_centre = {c: np.full(2, np.nan) for c in ("red", "blue")}
        truth_centroid = {c: np.full(2, np.nan) for c in ("red", "blue")}
        truth_area = {"red": 0.0, "blue": 0.0}
        full_area = {"red": 0.0, "blue": 0.0}
        if pose is not None:
            poses = (
                [pose]
                if motion_to is None
                else [pose.interpolate(motion_to, f) for f in np.linspace(0.0, 1.0, max(motion_steps, 2))]
            )
            patch = self.pointer.patch(camera_index, poses, occluders)
            if patch is not None:
                x0, y0 = patch.x0, patch.y0
                h, w = patch.rgb.shape[:2]
                behind = self.backgrounds.rgb(camera_index)[y0 : y0 + h, x0 : x0 + w]
                if display is not None:
                    behind = overlay(behind, display, x0, y0)
                blended = patch.rgb + (1.0 - patch.coverage[..., None]) * behind
                self._put(mosaic, blended.astype(np.float32), camera_index, fmt, x0, y0)
                for colour, (count, sx, sy) in patch.sums.items():
                    if count > 0:
                        truth_centroid[colour] = np.array([sx / count, sy / count])
                        truth_area[colour] = count
            mid = poses[len(poses) // 2] if len(poses) % 2 else poses[0].interpolate(poses[-1], 0.5)
            radius = self.pointer.scene.end_diameter_m / 2.0
            for colour in ("red", "blue"):
                centre = mid.centre_of(colour, self.front_colour)
                truth_centre[colour] = camera.project(centre[None])[0]
                full_area[colour] = silhouette_area_px(camera, centre, radius)
        draws = self._noise_draws(camera_index, mosaic.shape, rng, noise)
        sim = self.rig.simulation
        image = sensor_output(
            mosaic, rng, sim.noise_sigma, sim.shot_noise, noise, draws, scratch=self._buffer("noise", mosaic)
        )
        return RenderedView(image, fmt, ViewTruth(truth_centre, truth_centroid, truth_area, full_area))

    def skip(
        self, camera_index: int, rng: np.random.Generator, *, pixel_format: str | None = None, noise: bool = True
    ) -> None:
        """Draw from ``rng`` what :meth:`render` draws for one frame of camera ``camera_index``, without
        rendering it: the frames rendered after it are those of a run that rendered it, bit for bit (for
        the frames of a sequence that are not looked at; a camera's room is rendered, as its first frame
        would render it, since its shape is that of the frame)."""
        fmt = pixel_format or self.pixel_formats[camera_index]
        lit = self.backgrounds.lit_in_format(camera_index, fmt, self._illumination_map(camera_index))
        self._noise_draws(camera_index, lit.shape, rng, noise)

    def _noise_draws(
        self, camera_index: int, shape: tuple[int, ...], rng: np.random.Generator, noise: bool
    ) -> NDArray[np.float32] | None:
        """A frame's standard normal sensor noise: a window of the camera's noise field, or fresh draws
        (as :func:`~trackerd.sim.sensor.sensor_output` would draw them), or None for a noiseless frame.
        Everything a frame draws from its generator is drawn here (:meth:`skip` draws the same)."""
        if not noise:
            return None
        if self.noise_field:
            return self._noise.window(camera_index, shape, rng)
        sim = self.rig.simulation
        if sim.noise_sigma > 0 or sim.shot_noise > 0:
            return rng.standard_normal(shape, dtype=np.float32)
        return None

    def background_rgb(self, camera_index: int) -> FloatImage:
        """The empty room as camera ``camera_index`` sees it, (H, W, 3) floats in [0, 1]."""
        return self.backgrounds.rgb(camera_index)

    def rays(self, camera_index: int, px: Array, py: Array) -> Array:
        """World ray directions (N, 3) through sub-pixel positions (N,) of camera ``camera_index``."""
        return self.lens.rays(camera_index, px, py)

    # The calibration board's renderer (trackerd/sim/board.py) casts its rays through this name.
    _rays = rays

    def _put(self, mosaic: FloatImage, rgb: FloatImage, index: int, fmt: str, x0: int, y0: int) -> None:
        """Write an RGB region at (x0, y0) into a frame's raw values, lit as the rest of the frame."""
        h, w = rgb.shape[:2]
        illumination = self._illumination_map(index)
        if illumination is not None:
            rgb = rgb * illumination[y0 : y0 + h, x0 : x0 + w]
        region = raw_values(rgb, fmt, x0, y0)
        if region.ndim == 2:
            mosaic[y0 : y0 + h, x0 : x0 + w] = region
        else:
            mosaic[y0 : y0 + h, x0 : x0 + w, :] = region

    def _buffer(self, use: str, like: FloatImage) -> FloatImage:
        """A working array of ``like``'s shape for one use, kept between frames: the frame's raw values
        are built and turned into the sensor's output in the same memory every frame (new arrays of a
        frame's size cost more in page faults than the arithmetic done in them)."""
        key = (use, like.shape, like.dtype.str)
        buffer = self._buffers.get(key)
        if buffer is None:
            buffer = np.empty_like(like)
            self._buffers[key] = buffer
        return buffer

    def _illumination_map(self, index: int) -> FloatImage | None:
        if index not in self._illumination:
            cam = self.cameras[index]
            self._illumination[index] = self.look.illumination(cam.width_px, cam.height_px)
        return self._illumination[index]
