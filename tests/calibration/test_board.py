"""Boards: the spec, the rendered pattern against OpenCV's, and corners found where they truly are."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from calibration_frames import INTRINSICS_BOARD, STEREO_BOARD, FrameSet

from trackerd.calibration.board import BoardSpec, grey_for_calibration
from trackerd.calibration.detection import detect_board
from trackerd.pixelformat import from_rgb
from trackerd.sim.board import BoardRenderer, board_black, poses_for_camera, poses_for_pair


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("chessboard:10x7:60", BoardSpec("chessboard", 10, 7, 0.06)),
        ("chess:9x6:25.5", BoardSpec("chessboard", 9, 6, 0.0255)),
        ("charuco:10x7:60:45", BoardSpec("charuco", 10, 7, 0.06, 0.045, "5X5_100")),
        ("charuco:8x6:100:75:DICT_6X6_250", BoardSpec("charuco", 8, 6, 0.1, 0.075, "6X6_250")),
    ],
)
def test_board_specs_parse_and_print_back(text: str, expected: BoardSpec) -> None:
    spec = BoardSpec.parse(text)
    assert spec == expected
    assert BoardSpec.parse(str(spec)) == spec


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("chessboard:10x7", "expected chessboard:COLSxROWS:SQUARE_MM"),
        ("chessboard:8x8:30", "a square chessboard has no orientation"),
        ("chessboard:10x7:60:45", "a chessboard has no markers"),
        ("charuco:10x7:60", "needs the marker size"),
        ("charuco:10x7:60:70", "marker must be smaller than its square"),
        ("charuco:10x7:60:45:7X7_1", "unknown ArUco dictionary"),
        ("charuco:20x20:60:45:4X4_50", "the board needs 200 markers; 4X4_50 has 50"),
        ("chessboard:2x7:60", "at least 3 x 3 squares"),
    ],
)
def test_bad_board_specs_say_what_is_wrong(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        BoardSpec.parse(text)


def test_object_points_follow_opencvs_charuco_corner_numbering() -> None:
    spec = BoardSpec.parse("charuco:10x7:60:45")
    assert np.allclose(spec.object_points_m, np.asarray(spec.cv_board.getChessboardCorners()), atol=1e-7)
    assert spec.corner_count == 54


@pytest.mark.parametrize("text", ["charuco:10x7:60:45", "charuco:7x5:40:30:4X4_50", "charuco:6x6:50:35"])
def test_the_rendered_charuco_pattern_is_opencvs(text: str) -> None:
    """board_black, sampled at pixel centres, matches cv2's own board image except on edges."""
    spec = BoardSpec.parse(text)
    px_per_square = 70
    width, height = spec.squares_x * px_per_square, spec.squares_y * px_per_square
    reference = spec.cv_board.generateImage((width, height), marginSize=0, borderBits=1)
    ys, xs = np.mgrid[0:height, 0:width]
    scale = spec.square_m / px_per_square
    black = board_black(spec, (xs.ravel() + 0.5) * scale, (ys.ravel() + 0.5) * scale).reshape(height, width)
    ours = np.where(black, 0, 255).astype(np.uint8)
    differ = ours != reference
    # Only pixels straddling an edge may differ (OpenCV rounds marker cells to whole pixels).
    edges = cv2.dilate(cv2.Canny(reference, 50, 150), np.ones((3, 3), np.uint8)) > 0
    assert np.count_nonzero(differ & ~edges) == 0
    assert np.count_nonzero(differ) < 0.04 * differ.size


def test_bayer_gains_are_equalised_without_demosaicing() -> None:
    rng = np.random.default_rng(1)
    # Flat patches like a board's squares, so each Bayer site sees the same bright level.
    grey = np.kron(rng.choice([0.1, 0.5, 0.9], size=(8, 12)), np.ones((8, 8))).astype(np.float32)
    rgb = np.stack([grey * 0.6, grey * 0.9, grey * 0.75], axis=2)  # unbalanced channels
    mosaic = from_rgb(np.clip(np.rint(rgb * 255), 0, 255).astype(np.uint8), "BayerRG8")
    out = grey_for_calibration(mosaic, "BayerRG8").astype(np.float64)
    expected = grey * 255 * out.mean() / (grey * 255).mean()
    assert np.abs(out - expected).max() < 1.5  # rounding of both the mosaic and the gains


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def test_chessboard_corners_are_found_within_a_tenth_of_a_pixel(intrinsics_frames: FrameSet, simulated_rig) -> None:
    errors = []
    for name in intrinsics_frames.names()[::4]:
        camera = name.split("-")[0]
        image = intrinsics_frames.frame(name, camera)
        detection = detect_board(grey_for_calibration(image, "BayerRG8"), INTRINSICS_BOARD, name)
        assert detection.view is not None, detection.reason
        truth = np.array(intrinsics_frames.truth["corners_px"][name])
        errors.append(_rms(detection.view.image_points_px, truth[detection.view.ids]))
    assert max(errors) < 0.12, errors


def test_both_cameras_number_a_chessboards_corners_alike(renderer) -> None:
    """The stereo board seen from either side of the room: corner id k is the same physical corner."""
    board = BoardRenderer(renderer, STEREO_BOARD)
    rng = np.random.default_rng(62)
    poses = poses_for_pair(renderer, STEREO_BOARD, 3, rng)
    for pose in poses:
        for index in (0, 1):
            view = board.render(index, pose, rng, blur_px=0.5)
            detection = detect_board(grey_for_calibration(view.image, view.pixel_format), STEREO_BOARD)
            assert detection.view is not None, detection.reason
            assert _rms(detection.view.image_points_px, view.corners_px[detection.view.ids]) < 0.2


def test_charuco_partial_blurred_and_missing_boards_are_judged(renderer) -> None:
    spec = BoardSpec.parse("charuco:10x7:60:45")
    board = BoardRenderer(renderer, spec)
    rng = np.random.default_rng(8)
    pose = poses_for_camera(renderer, spec, 0, 1, rng)[0]
    sharp = board.render(0, pose, rng, blur_px=0.5)
    detection = detect_board(grey_for_calibration(sharp.image, sharp.pixel_format), spec, "sharp")
    assert detection.view is not None and detection.view.complete
    assert _rms(detection.view.image_points_px, sharp.corners_px[detection.view.ids]) < 0.15
    assert detection.view.sharpness_px < 2.5

    blurred = board.render(0, pose, rng, blur_px=2.5)
    detection = detect_board(grey_for_calibration(blurred.image, blurred.pixel_format), spec, "blurred")
    assert detection.view is None and detection.reason.startswith("blurred: edges rise over")
    assert detection.found is not None and detection.found.sharpness_px > 3.0

    # Slide the board mostly out of the image: ChArUco still finds what is left, and calls it partial.
    shift = renderer.cameras[0].world_from_camera[:, 0] * 0.55
    from trackerd.sim.board import BoardPose

    aside = BoardPose(pose.origin_m + shift, pose.rotation)
    partial = board.render(0, aside, rng, blur_px=0.5)
    detection = detect_board(grey_for_calibration(partial.image, partial.pixel_format), spec, "aside")
    assert detection.view is None
    assert detection.reason.startswith("partial:") or detection.reason == "no board found by any detector"

    empty = grey_for_calibration(renderer.render(0, None, rng).image, "BayerRG8")
    assert detect_board(empty, spec).reason == "no board found by any detector"
    assert detect_board(empty, INTRINSICS_BOARD).reason == "no whole board found by any detector"
