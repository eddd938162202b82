"""`trackerd bench robustness --follow N` (trackerd/bench/robustness_follow.py): consecutive frames located
with tracking kept, beside the same frames from scratch, without changing the bench's other frames."""

from __future__ import annotations

import itertools

import numpy as np

from trackerd.bench.robustness import draw_installation, run_rig
from trackerd.bench.robustness_follow import (
    MAX_STEP_M,
    FingerOnBall,
    follow_figures,
    followed_occluders,
    followed_poses,
    format_follow,
)
from trackerd.config.rig_geometry import wall_frame
from trackerd.sim.randomized import RandomRig, clear_of_pointer
from trackerd.sim.scene import PointerPose, scene_pointer


def _without_time(record: dict) -> dict:
    return {key: value for key, value in record.items() if key != "seconds"}


def test_followed_frames_are_tracked_and_leave_the_other_frames_as_they_were() -> None:
    # Installation 9 of seed 7 (nothing in front of the pointer): two independent frames, then five
    # consecutive ones.
    plain = run_rig((7, 9, 2, None, 0, 0))
    with_follow = run_rig((7, 9, 2, None, 0, 5))
    independent = [r for r in with_follow if not r.get("sequence")]
    followed = [r for r in with_follow if r.get("sequence")]
    assert [_without_time(r) for r in independent] == [_without_time(r) for r in plain]
    assert [r["frame"] for r in followed] == [0, 1, 2, 3, 4]
    # The tracking locator keeps its state: after the first sighting, cameras are answered by the
    # detector's window search; the scratch locator's frames are all first sightings.
    assert sum(r["tracking"]["window_searches"] for r in followed[1:]) > 0
    assert all(r["scratch"]["window_searches"] == 0 for r in followed)
    figures = follow_figures(followed)
    assert figures["frames"] == 5
    assert figures["tracking"]["found_percent"] is not None and figures["scratch"]["found_percent"] is not None
    lines = format_follow(figures, 5)
    assert lines[0].startswith("Followed (--follow 5") and "tracking" in lines[2] and "scratch" in lines[3]


def test_the_followed_pointer_moves_at_a_hands_pace() -> None:
    drawn, _ = draw_installation(7, 3)
    assert drawn.rig.wall is not None and drawn.rig.pointer is not None
    poses = followed_poses(drawn, wall_frame(drawn.rig.wall), np.random.default_rng(1), 120)
    steps = [
        max(np.linalg.norm(b.front_m - a.front_m), np.linalg.norm(b.back_m - a.back_m))
        for a, b in itertools.pairwise(poses)
    ]
    assert len(poses) == 120
    assert max(steps) <= MAX_STEP_M * 1.5  # a sweep's turn onto the next one adds a little
    assert np.median(steps) > 0.3 * MAX_STEP_M  # it moves
    lengths = [np.linalg.norm(p.front_m - p.back_m) for p in poses]
    np.testing.assert_allclose(lengths, drawn.rig.pointer.length_m, rtol=1e-9)


def _sequence_poses(seed: int, index: int, count: int) -> tuple[RandomRig, list[PointerPose]]:
    drawn, _ = draw_installation(seed, index)
    assert drawn.rig.wall is not None
    return drawn, followed_poses(drawn, wall_frame(drawn.rig.wall), np.random.default_rng([seed, index, 3]), count)


def test_a_finger_on_a_ball_stays_on_it_as_the_pointer_moves() -> None:
    drawn, poses = _sequence_poses(7, 1, 20)
    assert drawn.rig.pointer is not None
    ball_r = drawn.rig.pointer.end_diameter_m / 2.0
    finger = FingerOnBall("back", 1.0, 0.6 * ball_r, 0.5, (0.8, 0.6, 0.5))
    placed = [finger.at(pose, ball_r) for pose in poses]
    gaps = [np.linalg.norm(np.array(o.centre_m) - pose.back_m) for o, pose in zip(placed, poses, strict=True)]
    np.testing.assert_allclose(gaps, ball_r + 0.3 * ball_r, rtol=1e-9)
    # Beside the ball, not along the rod, and on the same side of the pointer all along.
    sides = [(np.array(o.centre_m) - pose.back_m) / gap for o, pose, gap in zip(placed, poses, gaps, strict=True)]
    assert all(abs(float(side @ pose.direction)) < 1e-9 for side, pose in zip(sides, poses, strict=True))
    assert min(float(a @ b) for a, b in itertools.pairwise(sides)) > 0.9
    assert np.linalg.norm(np.array(placed[-1].centre_m) - np.array(placed[0].centre_m)) > 0.05  # it moved along


def test_the_followed_sequences_have_a_finger_or_the_body_in_front_as_often_as_the_shots() -> None:
    levels = []
    for index in range(12):
        drawn, poses = _sequence_poses(7, index, 20)
        occlusion, occluders = followed_occluders(drawn, poses, np.random.default_rng([7, index, 4]))
        levels.append(occlusion)
        assert len(occluders) == len(poses)
        if occlusion == "body":
            # The presenter stands still, clear of the pointer in every pose.
            assert all(o == occluders[0] for o in occluders) and occluders[0][0].label == "body"
            ball_r = scene_pointer(drawn.rig).end_diameter_m / 2.0
            body = occluders[0][0]
            assert all(
                clear_of_pointer(np.array(body.centre_m), body.radius_m, body.height_m, pose, ball_r) for pose in poses
            )
        elif occlusion == "hand":
            assert all(o[0].label == "hand" for o in occluders)
        else:
            assert all(o == () for o in occluders)
    assert set(levels) == {"none", "hand", "body"}


def test_followed_records_carry_their_occlusion_and_the_figures_break_it_down() -> None:
    # Installation 0 of seed 7 is followed with the presenter's body in front (drawn above).
    records = [r for r in run_rig((7, 0, 0, None, 0, 3)) if r.get("sequence")]
    assert {r["factors"]["occlusion"] for r in records} == {"body"}
    figures = follow_figures(records)
    assert list(figures["tracking_by_occlusion"]) == ["body"]
    assert figures["tracking_by_occlusion"]["body"]["frames"] == 3
    assert any(line.lstrip().startswith("body") for line in format_follow(figures, 3))
