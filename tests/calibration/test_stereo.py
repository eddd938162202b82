"""Stereo extrinsics from rendered pairs, with intrinsics from the intrinsics step held fixed."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from trackerd.calibration import CalibrationError
from trackerd.calibration.stereo import Lens, calibrate_stereo, check_sync, epipolar_distances_px
from trackerd.calibration.update import relative_pose
from trackerd.geometry.rotation import rotation_about_x, rotation_angle_deg

SIZE = (1920, 1080)


def lenses(calibrated_lenses: dict) -> tuple[Lens, Lens]:
    return tuple(Lens(calibrated_lenses[c].matrix, calibrated_lenses[c].distortion) for c in ("left", "right"))


def truth(renderer) -> tuple[np.ndarray, np.ndarray]:
    left, right = renderer.cameras[:2]
    return relative_pose(left.rotation, left.translation_m, right.rotation, right.translation_m)


def test_baseline_and_rotation_are_recovered_within_the_issues_limits(
    stereo_pairs: list, calibrated_lenses: dict, renderer
) -> None:
    """Baseline within 1 mm and rotation within 0.1 degree (issue 6), on calibrated intrinsics."""
    result = calibrate_stereo(stereo_pairs, *lenses(calibrated_lenses), SIZE)
    rotation, translation = truth(renderer)
    assert abs(result.baseline_m - np.linalg.norm(translation)) < 0.001
    assert rotation_angle_deg(result.rotation @ rotation.T) < 0.1
    assert result.rejected == ()
    assert result.rms_px < 0.15
    assert result.epipolar_rms_px < 0.2
    assert len(result.pair_names) == len(stereo_pairs)
    # The reported angles describe the same rotation.
    assert result.rotation_deg == pytest.approx(rotation_angle_deg(rotation), abs=0.1)


def test_epipolar_error_measures_a_wrong_relative_pose(stereo_pairs: list, renderer) -> None:
    left, right = renderer.cameras[:2]
    lens1, lens2 = Lens(left.matrix, left.distortion), Lens(right.matrix, right.distortion)
    rotation, translation = truth(renderer)
    pair = stereo_pairs[0]
    good = epipolar_distances_px(pair.points1_px, pair.points2_px, lens1, lens2, rotation, translation)
    assert np.sqrt(np.mean(good**2)) < 0.2
    turned = rotation_about_x(np.radians(0.2)) @ rotation  # camera 2 tilted by 0.2 degree
    bumped = epipolar_distances_px(pair.points1_px, pair.points2_px, lens1, lens2, turned, translation)
    assert np.sqrt(np.mean(bumped**2)) > 1.0


def test_a_pair_out_of_sync_is_left_out_with_the_reason(stereo_pairs: list, calibrated_lenses: dict) -> None:
    pairs = list(stereo_pairs)
    # Pair 4's right image is really pair 5's: the board moved between the two exposures.
    pairs[4] = dataclasses.replace(pairs[4], points2_px=stereo_pairs[5].points2_px)
    result = calibrate_stereo(pairs, *lenses(calibrated_lenses), SIZE)
    assert [name for name, _ in result.rejected] == [stereo_pairs[4].name]
    assert "out of sync" in result.rejected[0][1]
    assert stereo_pairs[4].name not in result.pair_names


def test_pairs_that_do_not_belong_together_are_a_clear_error(stereo_pairs: list, calibrated_lenses: dict) -> None:
    shuffled = [
        dataclasses.replace(p, points2_px=stereo_pairs[(k + 1) % len(stereo_pairs)].points2_px)
        for k, p in enumerate(stereo_pairs)
    ]
    with pytest.raises(CalibrationError, match=r"pairs out of sync: the pairs disagree .* same instant"):
        check_sync(shuffled, *lenses(calibrated_lenses))
    with pytest.raises(CalibrationError, match="pairs out of sync"):
        calibrate_stereo(shuffled, *lenses(calibrated_lenses), SIZE)


def test_too_few_pairs_is_a_clear_error(stereo_pairs: list, calibrated_lenses: dict) -> None:
    with pytest.raises(CalibrationError, match="too few pairs with the board seen by both cameras: 3, need at least 5"):
        calibrate_stereo(stereo_pairs[:3], *lenses(calibrated_lenses), SIZE)
