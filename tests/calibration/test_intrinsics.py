"""Intrinsics from rendered chessboard views of cameras whose lenses are known exactly."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from trackerd.calibration import CalibrationError
from trackerd.calibration.intrinsics import calibrate_intrinsics, lens_model_difference_px, outlier_views


def test_each_camera_is_recovered_within_the_issues_limits(calibrated_lenses: dict, renderer) -> None:
    """Focal lengths within 0.5 %, principal point within 2 px (issue 6); in practice far better."""
    for camera in renderer.cameras:
        result = calibrated_lenses[camera.camera_id]
        truth = camera.matrix
        fx, fy = result.focal_px
        assert abs(fx / truth[0, 0] - 1) < 0.005 and abs(fy / truth[1, 1] - 1) < 0.005
        assert np.hypot(*(np.array(result.principal_point_px) - truth[:2, 2])) < 2.0
        # The figures the result reports are the ones a good calibration gives.
        assert result.rms_px < 0.15
        assert result.coverage.fraction > 0.8
        assert result.outliers == ()
        # The whole lens (up to a rotation the extrinsics absorb) agrees with the truth.
        rms_px, max_px = lens_model_difference_px(
            truth, camera.distortion, result.matrix, result.distortion, (camera.width_px, camera.height_px)
        )
        assert rms_px < 0.3 and max_px < 1.0, (rms_px, max_px)
        # OpenCV's own standard errors are consistent with the actual errors.
        assert abs(fx - truth[0, 0]) < 4 * result.std_matrix_px[0] + 0.5


def test_a_spoiled_view_is_named_as_an_outlier_and_can_be_dropped(intrinsics_views: dict, renderer) -> None:
    views = list(intrinsics_views["left"])
    spoiled = views[3]
    rng = np.random.default_rng(0)
    shifted = spoiled.image_points_px + rng.normal(0.0, 1.5, spoiled.image_points_px.shape)
    views[3] = dataclasses.replace(spoiled, image_points_px=shifted)
    kept = calibrate_intrinsics(views)
    assert kept.outliers == (3,)
    assert kept.per_view_rms_px[3] > 1.0
    dropped = calibrate_intrinsics(views, drop_outliers=True)
    assert dropped.dropped == (spoiled.name,)
    assert spoiled.name not in dropped.view_names
    assert dropped.rms_px < 0.15 < kept.rms_px
    truth = renderer.cameras[0].matrix
    assert abs(dropped.focal_px[0] / truth[0, 0] - 1) < 0.002


def test_outlier_rule_leaves_the_normal_spread_alone() -> None:
    assert outlier_views(np.array([0.05, 0.08, 0.11, 0.07, 0.14, 0.06])) == ()
    assert outlier_views(np.array([0.05, 0.08, 0.11, 0.07, 0.45, 0.06])) == (4,)
    assert outlier_views(np.array([0.5, 0.8, 0.6])) == ()  # too few views to judge


def test_too_few_views_and_mixed_sizes_are_clear_errors(intrinsics_views: dict) -> None:
    views = intrinsics_views["right"]
    with pytest.raises(CalibrationError, match="too few usable views: 5, need at least 8"):
        calibrate_intrinsics(views[:5])
    other = dataclasses.replace(views[4], image_size=(1280, 720), name="small.png")
    with pytest.raises(CalibrationError, match=r"small.png: image is 1280x720, but right-00 is 1920x1080"):
        calibrate_intrinsics([*views[:4], other, *views[5:]])


def test_fewer_distortion_terms_are_written_as_such(intrinsics_views: dict) -> None:
    result = calibrate_intrinsics(intrinsics_views["left"], distortion_terms=4)
    assert len(result.distortion) == 4
    assert result.to_config().distortion == tuple(result.distortion)
