"""The simulator's lens maps (trackerd/sim/lens_rays.py): the ray drawn through a pixel is the ray
the camera model gives that pixel, out to the corners of strongly distorted lenses."""

from __future__ import annotations

import numpy as np

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import world_from_camera_ypr
from trackerd.sim.lens_rays import LensRays

# A draw of the randomized installations (seed 7, installation 29, its fourth camera): strong
# barrel distortion that does not fold. Rendered with OpenCV's default 5-iteration inverse, its
# scene was drawn up to 31 px from where the camera model (and trackerd) put it.
STRONG_BARREL = (
    2448,
    2048,
    [[1465.27, 0.0, 1260.15], [0.0, 1466.73, 989.72], [0.0, 0.0, 1.0]],
    [-0.22937, 0.029873, 0.00022368, 0.00045098, 0.0],
)


def test_every_pixels_ray_projects_back_onto_it_up_to_the_corners() -> None:
    width_px, height_px, matrix, distortion = STRONG_BARREL
    cam = CameraModel.from_pose(
        "barrel",
        width_px,
        height_px,
        np.array(matrix),
        np.array(distortion),
        np.array([0.0, 2.5, 3.0]),
        world_from_camera_ypr(0.0, -20.0, 0.0),
    )
    lens = LensRays([cam])
    rng = np.random.default_rng(1)
    # Sub-pixel positions anywhere (interpolated in the map) and the four outermost pixel centres.
    px = np.concatenate([rng.uniform(0.0, width_px - 1.0, 4000), [0.0, width_px - 1.0, 0.0, width_px - 1.0]])
    py = np.concatenate([rng.uniform(0.0, height_px - 1.0, 4000), [0.0, 0.0, height_px - 1.0, height_px - 1.0]])
    rays = lens.rays(0, px, py)
    back = cam.project(cam.centre_m + rays)
    miss_px = np.linalg.norm(back - np.column_stack([px, py]), axis=1)
    # The map is float32 and interpolated: a thousandth of a pixel is its resolution.
    assert np.max(miss_px) < 2e-3
    # And the same through trackerd's own inverse (the rays the locator would use).
    _, dirs = cam.pixel_to_ray(np.column_stack([px, py]))
    assert np.max(np.degrees(np.arccos(np.clip(np.sum(dirs * rays, axis=1), -1.0, 1.0)))) < 1e-4
