"""Fixtures: rendered calibration input, shared by the calibration tests and cached on disk.

See calibration_frames.py for what is rendered and how the cache is keyed.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from calibration_frames import (
    CHECK_POSES,
    INTRINSICS_BOARD,
    INTRINSICS_VIEWS,
    POINTING_PLACES,
    PSF_PX,
    STEREO_BOARD,
    STEREO_PAIRS,
    FrameSet,
    _cached,
    _sources_digest,
    _write,
    register,
)

from trackerd.config.models import RigConfig

FrameSetRecipe = tuple[str, str, Callable[[Path], dict]]
"""A frame set's kind, cache key and builder (which renders it into a folder and returns its truth)."""


def _intrinsics_recipe(renderer, simulated_rig: RigConfig) -> FrameSetRecipe:
    """INTRINSICS_VIEWS board views per camera, chosen to cover each image; names '<camera>-NN'."""
    from trackerd.sim.board import BoardRenderer, poses_for_camera

    def build(folder: Path) -> dict:
        rng = np.random.default_rng(61)
        board = BoardRenderer(renderer, INTRINSICS_BOARD)
        names, corners = [], {}
        for index, cam in enumerate(simulated_rig.cameras):
            for k, pose in enumerate(poses_for_camera(renderer, INTRINSICS_BOARD, index, INTRINSICS_VIEWS, rng)):
                view = board.render(index, pose, rng, blur_px=PSF_PX)
                name = f"{cam.id}-{k:02d}"
                _write(folder, f"{name}-{cam.id}", view.image)
                names.append(name)
                corners[name] = view.corners_px.tolist()
        return {"names": names, "corners_px": corners}

    return "intrinsics", _sources_digest(INTRINSICS_VIEWS, str(INTRINSICS_BOARD), 61), build


def _stereo_recipe(renderer, simulated_rig: RigConfig) -> FrameSetRecipe:
    """STEREO_PAIRS pairs of the large board seen by both cameras; names 'NN'."""
    from trackerd.sim.board import BoardRenderer, poses_for_pair

    def build(folder: Path) -> dict:
        rng = np.random.default_rng(62)
        board = BoardRenderer(renderer, STEREO_BOARD)
        names = []
        for k, pose in enumerate(poses_for_pair(renderer, STEREO_BOARD, STEREO_PAIRS, rng)):
            for index, cam in enumerate(simulated_rig.cameras):
                _write(folder, f"{k:02d}-{cam.id}", board.render(index, pose, rng, blur_px=PSF_PX).image)
            names.append(f"{k:02d}")
        return {"names": names}

    return "stereo", _sources_digest(STEREO_PAIRS, str(STEREO_BOARD), 62), build


def _pointing_recipe(renderer, simulated_rig: RigConfig) -> FrameSetRecipe:
    """The pointer aimed at the 3 x 3 wall targets from POINTING_PLACES places each; names '<label>-<n>'."""
    from trackerd.bench.calibration import aimed_poses, wall_targets

    def build(folder: Path) -> dict:
        rng = np.random.default_rng(63)
        wall = renderer.wall
        names = []
        for target in wall_targets(wall.width_m, wall.height_m):
            for n, pose in enumerate(aimed_poses(renderer, wall.from_wall_m(target.wall_xy_m), POINTING_PLACES, rng)):
                name = f"{target.label}-{n + 1}"
                for index, cam in enumerate(simulated_rig.cameras):
                    _write(folder, f"{name}-{cam.id}", renderer.render(index, pose, rng).image)
                names.append(name)
        return {"names": names}

    return "pointing", _sources_digest(POINTING_PLACES, 63), build


def _pointer_recipe(renderer, simulated_rig: RigConfig) -> FrameSetRecipe:
    """CHECK_POSES random pointer poses (the pointer waved around); names 'NN'."""
    from trackerd.sim.scene import random_pose, true_wall_hit

    def build(folder: Path) -> dict:
        rng = np.random.default_rng(64)
        names, hits = [], {}
        for k in range(CHECK_POSES):
            pose = random_pose(simulated_rig, rng, renderer.cameras, renderer.wall)
            for index, cam in enumerate(simulated_rig.cameras):
                _write(folder, f"{k:02d}-{cam.id}", renderer.render(index, pose, rng).image)
            names.append(f"{k:02d}")
            truth = true_wall_hit(pose, renderer.wall)
            hits[f"{k:02d}"] = None if truth.wall_xy_m is None else truth.wall_xy_m.tolist()
        return {"names": names, "wall_xy_m": hits}

    return "pointer", _sources_digest(CHECK_POSES, 64), build


@pytest.fixture(scope="session")
def frame_set_recipes(renderer, simulated_rig: RigConfig) -> dict[str, FrameSetRecipe]:
    """Every rendered set, made known to calibration_frames at once: a worker that waits for a set
    another worker renders renders one nobody has started meanwhile (calibration_frames._cached)."""
    recipes = {
        kind: recipe(renderer, simulated_rig)
        for kind, recipe in (
            ("intrinsics", _intrinsics_recipe),
            ("stereo", _stereo_recipe),
            ("pointing", _pointing_recipe),
            ("pointer", _pointer_recipe),
        )
    }
    for recipe in recipes.values():
        register(*recipe)
    return recipes


@pytest.fixture(scope="session")
def intrinsics_frames(frame_set_recipes: dict[str, FrameSetRecipe]) -> FrameSet:
    """INTRINSICS_VIEWS board views per camera, chosen to cover each image; names '<camera>-NN'."""
    return _cached(*frame_set_recipes["intrinsics"])


@pytest.fixture(scope="session")
def stereo_frames(frame_set_recipes: dict[str, FrameSetRecipe]) -> FrameSet:
    """STEREO_PAIRS pairs of the large board seen by both cameras; names 'NN'."""
    return _cached(*frame_set_recipes["stereo"])


@pytest.fixture(scope="session")
def pointing_frames(frame_set_recipes: dict[str, FrameSetRecipe]) -> FrameSet:
    """The pointer aimed at the 3 x 3 wall targets from POINTING_PLACES places each; names '<label>-<n>'."""
    return _cached(*frame_set_recipes["pointing"])


@pytest.fixture(scope="session")
def pointer_frames(frame_set_recipes: dict[str, FrameSetRecipe]) -> FrameSet:
    """CHECK_POSES random pointer poses (the pointer waved around); names 'NN'."""
    return _cached(*frame_set_recipes["pointer"])


@pytest.fixture(scope="session")
def intrinsics_views(intrinsics_frames: FrameSet, simulated_rig: RigConfig) -> dict:
    """The board views detected in intrinsics_frames, per camera id."""
    from trackerd.calibration.board import grey_for_calibration
    from trackerd.calibration.detection import detect_board

    out: dict[str, list] = {cam.id: [] for cam in simulated_rig.cameras}
    for name in intrinsics_frames.names():
        cam_id = name.split("-")[0]
        image = intrinsics_frames.frame(name, cam_id)
        detection = detect_board(grey_for_calibration(image, "BayerRG8"), INTRINSICS_BOARD, name)
        assert detection.view is not None, f"{name}: {detection.reason}"
        out[cam_id].append(detection.view)
    return out


@pytest.fixture(scope="session")
def calibrated_lenses(intrinsics_views: dict) -> dict:
    """Each camera's IntrinsicsResult from its views."""
    from trackerd.calibration.intrinsics import calibrate_intrinsics

    return {cam_id: calibrate_intrinsics(views) for cam_id, views in intrinsics_views.items()}


@pytest.fixture(scope="session")
def stereo_pairs(stereo_frames: FrameSet, simulated_rig: RigConfig) -> list:
    """Matched StereoPairs detected in stereo_frames."""
    from trackerd.calibration.board import grey_for_calibration
    from trackerd.calibration.detection import detect_board
    from trackerd.calibration.stereo import match_views

    ids = [cam.id for cam in simulated_rig.cameras]
    pairs = []
    for name in stereo_frames.names():
        views = []
        for cam_id in ids:
            detection = detect_board(
                grey_for_calibration(stereo_frames.frame(name, cam_id), "BayerRG8"), STEREO_BOARD, f"{name}-{cam_id}"
            )
            assert detection.view is not None, f"{name}-{cam_id}: {detection.reason}"
            views.append(detection.view)
        pair = match_views(views[0], views[1], name)
        assert pair is not None
        pairs.append(pair)
    return pairs
