"""Calibration health: ray gaps and reprojection errors, and a bumped camera standing out."""

from __future__ import annotations

import json

import numpy as np
import pytest
from calibration_frames import FrameSet

from trackerd.calibration.health import CalibrationHealth, ellipse_centre_px, health_statistics
from trackerd.geometry.camera import CameraModel
from trackerd.geometry.rotation import rotation_about_x, world_from_camera_ypr
from trackerd.locator import Locator


def test_statistics_and_verdict() -> None:
    gaps = np.linspace(0.0005, 0.0025, 41)  # metres; median 1.5 mm
    reproj = np.linspace(0.1, 0.9, 41)
    figures = health_statistics(gaps, reproj)
    assert figures.fixes == 41
    assert figures.gap_p50_mm == pytest.approx(1.5)
    assert figures.gap_max_mm == pytest.approx(2.5)
    assert figures.reprojection_p95_px == pytest.approx(np.percentile(reproj, 95))
    assert not figures.suspect and figures.reason is None
    drifted = health_statistics(gaps * 5, reproj * 4)
    assert drifted.suspect
    assert drifted.reason == (
        "median ray gap 7.50 mm exceeds 4.00 mm; median reprojection error 2.00 px exceeds 1.50 px"
    )
    few = health_statistics(gaps[:5] * 10, reproj[:5])
    assert not few.suspect and few.reason == "only 5 fixes (need 20 to judge)"
    none = health_statistics([], [])
    assert none.fixes == 0 and none.gap_p50_mm is None and json.dumps(none.to_json())


def test_the_streaming_window_keeps_only_recent_fixes() -> None:
    camera = CameraModel.from_pose(
        "c",
        640,
        480,
        np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]]),
        np.zeros(0),
        np.zeros(3),
        world_from_camera_ypr(0, 0, 0),
    )
    health = CalibrationHealth([camera, camera], 0.02, window=10, min_fixes=5)
    for _ in range(20):
        health.add(0.010, 3.0)  # a bad stretch...
    for _ in range(10):
        health.add(0.001, 0.3)  # ...then good fixes fill the window
    assert health.total == 30
    out = health.to_json()
    assert out["fixes"] == 10 and out["total_fixes"] == 30
    assert out["ray_gap_mm"]["p50"] == pytest.approx(1.0) and not out["suspect"]
    health.reset()
    assert health.figures().fixes == 0


def test_ellipse_centre_is_the_perspective_corrected_projection() -> None:
    """A sphere at (X, Y, Z) images around (X, Y) Z / (Z^2 - r^2) on the normalised plane."""
    matrix = np.array([[1000.0, 0, 960], [0, 1000, 540], [0, 0, 1]])
    camera = CameraModel.from_pose("c", 1920, 1080, matrix, np.zeros(0), np.zeros(3), np.diag([1.0, 1.0, 1.0]))
    on_axis = ellipse_centre_px(camera, np.array([0.0, 0.0, 2.0]), 0.02)
    assert on_axis == pytest.approx([960.0, 540.0])
    centre = np.array([0.6, -0.3, 2.0])
    got = ellipse_centre_px(camera, centre, 0.02)
    scale = 2.0 / (4.0 - 0.0004)
    assert got == pytest.approx([960 + 1000 * 0.6 * scale, 540 - 1000 * 0.3 * scale], abs=1e-9)
    assert np.linalg.norm(got - camera.project(centre[None])[0]) > 0.02  # the shift is real
    assert np.all(np.isnan(ellipse_centre_px(camera, np.array([0.0, 0.0, -1.0]), 0.02)))


def _figures(rig, cameras, pointer_frames: FrameSet):
    locator = Locator(rig, cameras=cameras)
    health = CalibrationHealth.for_rig(rig, cameras, min_fixes=8)
    for name in pointer_frames.names():
        locator.reset()
        health.add_fix(locator.locate([pointer_frames.frame(name, c.camera_id) for c in cameras]))
    return health.figures()


def test_a_bumped_camera_shows_as_a_jump_in_gaps_and_reprojection(
    pointer_frames: FrameSet, simulated_rig, renderer
) -> None:
    good = _figures(simulated_rig, renderer.cameras, pointer_frames)
    assert good.fixes >= 10
    assert not good.suspect, good.reason
    assert good.gap_p50_mm < 2.5 and good.reprojection_p50_px < 1.0
    left, right = renderer.cameras
    bumped_right = CameraModel.from_pose(
        right.camera_id,
        right.width_px,
        right.height_px,
        right.matrix,
        right.distortion,
        right.centre_m,
        right.world_from_camera @ rotation_about_x(np.radians(0.3)),
    )
    bumped = _figures(simulated_rig, [left, bumped_right], pointer_frames)
    assert bumped.suspect, bumped
    assert bumped.gap_p50_mm > 3 * good.gap_p50_mm
    assert bumped.reprojection_p50_px > 3 * good.reprojection_p50_px
