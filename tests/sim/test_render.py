"""The renderer's images and ground truth are geometrically faithful (trackerd/sim/render.py)."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.pixelformat import from_rgb
from trackerd.sim.render import SceneRenderer
from trackerd.sim.scene import PointerPose, random_pose


def _image_line_distance(point: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    along = (b - a) / np.linalg.norm(b - a)
    rel = point - a
    return float(abs(rel[0] * along[1] - rel[1] * along[0]))


def _lens_jacobian(cam, point_cam: np.ndarray, step: float = 1e-5) -> np.ndarray:
    """d(pixel) / d(normalised image coordinates) at a camera-frame point, by central differences."""
    x, y = point_cam[:2] / point_cam[2]
    samples = np.array([[x + step, y, 1], [x - step, y, 1], [x, y + step, 1], [x, y - step, 1]])
    world = (samples - cam.translation_m) @ cam.rotation  # camera frame -> world
    px = cam.project(world)
    return np.column_stack([(px[0] - px[1]) / (2 * step), (px[2] - px[3]) / (2 * step)])


def test_ray_map_matches_the_camera_model(renderer: SceneRenderer) -> None:
    """Interpolating the undistortion map gives the same rays as undistorting each pixel exactly."""
    cam = renderer.cameras[0]
    rng = np.random.default_rng(3)
    px = rng.uniform([0, 0], [cam.width_px - 1, cam.height_px - 1], size=(200, 2))
    expected = cam.pixel_to_ray(px)[1]
    got = renderer.rays(0, px[:, 0], px[:, 1])
    angle_error = np.arccos(np.clip(np.sum(expected * got, axis=1), -1, 1))
    # 1e-7 rad is 0.0002 px at f = 1660 px.
    assert angle_error.max() < 1e-7


def test_ball_area_matches_its_projected_size(renderer: SceneRenderer, simulated_rig) -> None:
    """A ball's image area is that of the cone of rays tangent to it, less what the rod hides.

    Where the rod leaves the ball on its far side (seen from the camera) nothing
    hides the ball, and the rendered area must match the analytic one closely.
    """
    rng = np.random.default_rng(5)
    radius = simulated_rig.pointer.end_diameter_m / 2
    front_colour = simulated_rig.pointer.front_colour
    unoccluded_checked = 0
    for _ in range(6):
        pose = random_pose(simulated_rig, rng)
        for index, cam in enumerate(renderer.cameras):
            view = renderer.render(index, pose, rng, noise=False)
            for colour in ("red", "blue"):
                centre = pose.centre_of(colour, front_colour)
                other = pose.back_m if colour == front_colour else pose.front_m
                distance = np.linalg.norm(centre - cam.centre_m)
                depth = cam.to_camera_frame(centre[None])[0, 2]
                # Solid angle of the tangent cone; normalised-image area is solid angle / cos^3,
                # and the lens (intrinsics and distortion) scales that area by its Jacobian.
                half_angle = np.arcsin(radius / distance)
                solid_angle = 2 * np.pi * (1 - np.cos(half_angle))
                jacobian = _lens_jacobian(cam, cam.to_camera_frame(centre[None])[0])
                expected = solid_angle / (depth / distance) ** 3 * abs(np.linalg.det(jacobian))
                area = view.truth.area_px[colour]
                rod_leaves_far_side = np.dot(other - centre, centre - cam.centre_m) > 0
                if rod_leaves_far_side and colour == front_colour:
                    assert area == pytest.approx(expected, rel=0.015)
                    unoccluded_checked += 1
                else:
                    # The rod (12 mm across a 40 mm ball) can hide up to about a fifth of it.
                    assert 0.7 * expected < area <= expected * 1.01
    assert unoccluded_checked >= 2


def test_visible_centroids_lie_on_the_pointers_image_line(renderer: SceneRenderer, simulated_rig) -> None:
    """The rod hides part of a ball symmetrically about the pointer's axis: centroids move along it only.

    This is what makes the interpretation-plane line estimate unbiased (trackerd/geometry/pointer_line.py).
    """
    rng = np.random.default_rng(8)
    for _ in range(4):
        pose = random_pose(simulated_rig, rng)
        for index, cam in enumerate(renderer.cameras):
            view = renderer.render(index, pose, rng, noise=False)
            norm = cam.normalized_from_pixels(np.array([view.truth.centroid_px["red"], view.truth.centroid_px["blue"]]))
            ends = cam.to_camera_frame(np.array([pose.front_m, pose.back_m]))
            projected = ends[:, :2] / ends[:, 2:3]
            for point in norm:
                # In undistorted normalised coordinates, times the focal length to read as pixels.
                offset_px = _image_line_distance(point, projected[0], projected[1]) * cam.focal_px
                assert offset_px < 0.05


def test_bayer_output_is_the_mosaic_of_the_colour_render(renderer: SceneRenderer, simulated_rig) -> None:
    rng = np.random.default_rng(1)
    pose = random_pose(simulated_rig, rng)
    rgb = renderer.render(0, pose, np.random.default_rng(0), pixel_format="RGB8", noise=False)
    bayer = renderer.render(0, pose, np.random.default_rng(0), pixel_format="BayerRG8", noise=False)
    assert rgb.image.shape == (1080, 1920, 3)
    assert bayer.image.shape == (1080, 1920)
    np.testing.assert_array_equal(bayer.image, from_rgb(rgb.image, "BayerRG8"))
    bgr = renderer.render(0, pose, np.random.default_rng(0), pixel_format="BGR8", noise=False)
    np.testing.assert_array_equal(bgr.image, rgb.image[..., ::-1])


def test_same_seed_same_image_and_noise_has_the_configured_level(renderer: SceneRenderer, simulated_rig) -> None:
    pose = random_pose(simulated_rig, np.random.default_rng(2))
    first = renderer.render(1, pose, np.random.default_rng(42))
    again = renderer.render(1, pose, np.random.default_rng(42))
    np.testing.assert_array_equal(first.image, again.image)
    clean = renderer.render(1, pose, np.random.default_rng(42), noise=False).image.astype(float)
    residual = first.image.astype(float) - clean
    level = clean[::4, ::4].ravel()
    sim = simulated_rig.simulation
    expected = np.sqrt(sim.noise_sigma**2 + sim.shot_noise**2 * level)
    ratio = residual[::4, ::4].ravel().std() / np.sqrt(np.mean(expected**2))
    assert 0.9 < ratio < 1.1


def test_a_pointer_held_still_renders_as_if_cast_afresh_with_new_noise(renderer: SceneRenderer, simulated_rig) -> None:
    """The ray-cast pointer is remembered for a repeated pose (a presenter holding still): the frames are
    those a renderer casting it every time gives, and each has noise of its own."""
    pose = random_pose(simulated_rig, np.random.default_rng(4))
    rng = np.random.default_rng(9)
    first, second = (renderer.render(0, pose, rng) for _ in range(2))
    assert not np.array_equal(first.image, second.image)
    fresh = SceneRenderer(simulated_rig, cache_dir=None)
    again = np.random.default_rng(9)
    np.testing.assert_array_equal(fresh.render(0, pose, again).image, first.image)
    fresh.pointer.forget()  # cast again
    redone = fresh.render(0, pose, again)
    np.testing.assert_array_equal(redone.image, second.image)
    assert redone.truth.area_px == second.truth.area_px


def test_a_skipped_frame_draws_what_rendering_it_draws(simulated_rig) -> None:
    """`SceneRenderer.skip` (`drawn_frames` skipping the frames a test does not look at) leaves the generator
    as rendering the frame does, with fresh noise per frame or a noise field per camera (drawn by the first
    frame, skipped or not): the frames rendered after it are those of a run that rendered it, bit for bit."""
    pose = random_pose(simulated_rig, np.random.default_rng(5))
    for noise_field in (False, True):
        rendering, skipping = (SceneRenderer(simulated_rig, noise_field=noise_field) for _ in range(2))
        rendered, skipped = np.random.default_rng(3), np.random.default_rng(3)
        for camera in (0, 1, 0):
            rendering.render(camera, pose, rendered)
            skipping.skip(camera, skipped)
        assert rendered.bit_generator.state == skipped.bit_generator.state, noise_field
        np.testing.assert_array_equal(
            rendering.render(1, pose, rendered).image, skipping.render(1, pose, skipped).image
        )


def test_empty_room_has_no_pointer_truth(renderer: SceneRenderer) -> None:
    view = renderer.render(0, None, np.random.default_rng(0))
    assert np.all(np.isnan(view.truth.centroid_px["red"]))
    assert view.truth.area_px == {"red": 0.0, "blue": 0.0}


def test_motion_blur_spreads_the_ball_between_its_end_positions(renderer: SceneRenderer, simulated_rig) -> None:
    rng = np.random.default_rng(4)
    start = random_pose(simulated_rig, rng)
    shift = np.array([0.05, 0.0, 0.0])
    end = PointerPose(start.front_m + shift, start.back_m + shift)
    sharp_start = renderer.render(0, start, rng, noise=False).truth
    sharp_end = renderer.render(0, end, rng, noise=False).truth
    blurred = renderer.render(0, start, rng, motion_to=end, noise=False).truth
    for colour in ("red", "blue"):
        lo = np.minimum(sharp_start.centroid_px[colour], sharp_end.centroid_px[colour]) - 0.5
        hi = np.maximum(sharp_start.centroid_px[colour], sharp_end.centroid_px[colour]) + 0.5
        assert np.all(blurred.centroid_px[colour] >= lo) and np.all(blurred.centroid_px[colour] <= hi)
        # The area of the visible ball is preserved on average through the exposure.
        mean_area = (sharp_start.area_px[colour] + sharp_end.area_px[colour]) / 2
        assert blurred.area_px[colour] == pytest.approx(mean_area, rel=0.05)


def test_background_cache_round_trip(tmp_path, simulated_rig) -> None:
    """A second renderer reads the cached room instead of rendering it, and gets the same image."""
    rig = simulated_rig.model_copy(
        update={"simulation": simulated_rig.simulation.model_copy(update={"background_supersampling": 1})}
    )
    first = SceneRenderer(rig, cache_dir=tmp_path)
    background = first.background_rgb(0)
    files = list(tmp_path.glob("bg-*.npy"))
    assert len(files) == 1
    second = SceneRenderer(rig, cache_dir=tmp_path)
    # float16 on disk, and the fresh render is rounded to it as well: a scene renders the same
    # whether its room came from the cache or not (benchmark figures depended on it).
    assert np.array_equal(second.background_rgb(0), background)
    uncached = SceneRenderer(rig, cache_dir=None)
    assert np.array_equal(uncached.background_rgb(0), background)
