"""Scripted pointer motions (trackerd/sim/motion.py) stay where they say, on config/simulated.toml."""

from __future__ import annotations

import numpy as np
import pytest

from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import camera_model, wall_frame
from trackerd.geometry.camera import CameraModel
from trackerd.sim.motion import MOTIONS, make_motion
from trackerd.sim.scene import pose_visible, true_wall_hit

TIMES = np.linspace(0.0, 4.0, 161)


@pytest.fixture(scope="module")
def cameras(simulated_rig: RigConfig) -> list[CameraModel]:
    return [camera_model(c) for c in simulated_rig.cameras]


@pytest.mark.parametrize("name", MOTIONS)
def test_every_motion_is_periodic_and_keeps_the_pointer_length(simulated_rig: RigConfig, name: str) -> None:
    motion = make_motion(name, simulated_rig, period_s=4.0)
    for t in TIMES[:40]:
        a, b = motion(t), motion(t + motion.period_s)
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(a.front_m, b.front_m, atol=1e-9)
            np.testing.assert_allclose(a.back_m, b.back_m, atol=1e-9)
            assert a.length_m == pytest.approx(simulated_rig.pointer.length_m)


@pytest.mark.parametrize("name", ["sweep", "figure8", "away", "still"])
def test_motions_stay_in_every_cameras_view(simulated_rig: RigConfig, cameras, name: str) -> None:
    motion = make_motion(name, simulated_rig)
    assert all(pose_visible(motion(t), cameras, margin_px=40.0) for t in TIMES)


@pytest.mark.parametrize("name", ["sweep", "figure8", "still"])
def test_aiming_motions_hit_the_display(simulated_rig: RigConfig, name: str) -> None:
    wall = wall_frame(simulated_rig.wall)
    motion = make_motion(name, simulated_rig)
    assert all(true_wall_hit(motion(t), wall).on_wall for t in TIMES)


def test_sweep_covers_most_of_the_display_width(simulated_rig: RigConfig) -> None:
    wall = wall_frame(simulated_rig.wall)
    motion = make_motion("sweep", simulated_rig)
    xs = [true_wall_hit(motion(t), wall).wall_xy_m[0] for t in TIMES]
    assert min(xs) < 0.15 * wall.width_m and max(xs) > 0.85 * wall.width_m


def test_away_points_into_the_room(simulated_rig: RigConfig) -> None:
    wall = wall_frame(simulated_rig.wall)
    motion = make_motion("away", simulated_rig)
    for t in TIMES:
        pose = motion(t)
        assert pose.direction @ wall.normal > 0.5
        assert true_wall_hit(pose, wall).wall_xy_m is None


def test_leave_goes_out_of_view_and_comes_back(simulated_rig: RigConfig, cameras) -> None:
    motion = make_motion("leave", simulated_rig)
    poses = [motion(t) for t in TIMES]
    gone = [p is None for p in poses]
    out_of_view = [p is not None and not pose_visible(p, cameras, 0.0) for p in poses]
    visible = [p is not None and pose_visible(p, cameras, 40.0) for p in poses]
    assert any(gone) and any(out_of_view) and any(visible)
    assert visible[0] and visible[-1]


def test_still_does_not_move(simulated_rig: RigConfig) -> None:
    motion = make_motion("still", simulated_rig)
    np.testing.assert_array_equal(motion(0.0).front_m, motion(2.7).front_m)


def test_an_unknown_motion_names_the_choices(simulated_rig: RigConfig) -> None:
    with pytest.raises(ValueError, match="sweep, figure8, away, leave, still"):
        make_motion("zigzag", simulated_rig)
