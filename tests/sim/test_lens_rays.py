"""The simulator's lens maps (trackerd/sim/lens_rays.py): the ray drawn through a pixel is the ray
the camera model gives that pixel, out to the corners of strongly distorted lenses."""

from __future__ import annotations

import numpy as np

from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import world_from_camera_ypr
from trackerd.sim.lens_rays import LensRays
from trackerd.sim.shared_maps import SharedMaps, lens_key

# A draw of the randomized installations (seed 7, installation 29, its fourth camera): strong
# barrel distortion that does not fold. Rendered with OpenCV's default 5-iteration inverse, its
# scene was drawn up to 31 px from where the camera model (and trackerd) put it.
STRONG_BARREL = (
    2448,
    2048,
    [[1465.27, 0.0, 1260.15], [0.0, 1466.73, 989.72], [0.0, 0.0, 1.0]],
    [-0.22937, 0.029873, 0.00022368, 0.00045098, 0.0],
)


def _barrel(position_m: tuple[float, float, float], pitch_deg: float, k1: float = -0.22937) -> CameraModel:
    width_px, height_px, matrix, distortion = STRONG_BARREL
    return CameraModel.from_pose(
        "barrel",
        width_px,
        height_px,
        np.array(matrix),
        np.array([k1, *distortion[1:]]),
        np.array(position_m),
        world_from_camera_ypr(0.0, pitch_deg, 0.0),
    )


def _miss_px(lens: LensRays, cam: CameraModel, rng: np.random.Generator, count: int) -> float:
    """The largest distance between random sub-pixel positions and where their rays project back."""
    px = rng.uniform(0.0, cam.width_px - 1.0, count)
    py = rng.uniform(0.0, cam.height_px - 1.0, count)
    back = cam.project(cam.centre_m + lens.rays(0, px, py))
    return float(np.max(np.linalg.norm(back - np.column_stack([px, py]), axis=1)))


def test_every_pixels_ray_projects_back_onto_it_up_to_the_corners() -> None:
    cam = _barrel((0.0, 2.5, 3.0), -20.0)
    width_px, height_px = cam.width_px, cam.height_px
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


def test_renderers_of_the_same_lens_share_its_map_and_each_keeps_its_own_pose() -> None:
    """The map depends on the lens alone (size, K, distortion); a second renderer of the same camera, or of
    one with the same lens elsewhere in the room, takes the first one's map instead of solving it again."""
    first, moved = _barrel((0.0, 2.5, 3.0), -20.0), _barrel((1.5, 1.0, 4.0), 10.0)
    other_lens = _barrel((0.0, 2.5, 3.0), -20.0, k1=-0.1)
    shared = LensRays([first]).normalized_map(0)
    assert LensRays([first]).normalized_map(0) is shared
    moved_rays = LensRays([moved])
    assert moved_rays.normalized_map(0) is shared
    other = LensRays([other_lens])
    assert other.normalized_map(0) is not shared and not np.array_equal(other.normalized_map(0), shared)
    # The pose is applied per renderer: rays of the moved camera project back onto its own pixels, and
    # the other lens's onto its.
    rng = np.random.default_rng(2)
    assert _miss_px(moved_rays, moved, rng, 2000) < 2e-3
    assert _miss_px(other, other_lens, rng, 2000) < 2e-3
    assert not shared.flags.writeable


def test_the_shared_maps_keep_the_newest_within_their_memory() -> None:
    small = np.array([[200.0, 0.0, 160.0], [0.0, 200.0, 120.0], [0.0, 0.0, 1.0]])
    cams = [
        CameraModel.from_pose(f"small{k1}", 320, 240, small, np.array([k1, 0.0, 0.0, 0.0, 0.0]), np.zeros(3), np.eye(3))
        for k1 in (-0.2, -0.1, -0.05)
    ]
    one_map_bytes = 2 * (cams[0].width_px + 2) * (cams[0].height_px + 2) * 4
    maps: SharedMaps[np.ndarray] = SharedMaps(2 * one_map_bytes, lambda planes: planes.nbytes)

    def get(cam: CameraModel) -> np.ndarray:
        return maps.get(lens_key(cam), lambda: LensRays([cam]).normalized_map(0).copy())

    built = [get(cam) for cam in cams]
    # The first was evicted (rebuilt equal, as a new array); the two newest are kept.
    assert get(cams[2]) is built[2] and get(cams[1]) is built[1]
    again = get(cams[0])
    assert again is not built[0] and np.array_equal(again, built[0])
    # Used last, cams[1] outlived cams[2] when cams[0] came back.
    assert get(cams[1]) is built[1] and get(cams[2]) is not built[2]
