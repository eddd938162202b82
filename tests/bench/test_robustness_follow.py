"""`trackerd bench robustness --follow N` (trackerd/bench/robustness_follow.py): consecutive frames located
with tracking kept, beside the same frames from scratch, without changing the bench's other frames."""

from __future__ import annotations

import itertools

import numpy as np

from trackerd.bench.robustness import draw_installation, run_rig
from trackerd.bench.robustness_follow import MAX_STEP_M, follow_figures, followed_poses, format_follow
from trackerd.config.rig_geometry import wall_frame


def _without_time(record: dict) -> dict:
    return {key: value for key, value in record.items() if key != "seconds"}


def test_followed_frames_are_tracked_and_leave_the_other_frames_as_they_were() -> None:
    # Installation 0 of seed 7: two independent frames, then five consecutive ones.
    plain = run_rig((7, 0, 2, None, 0, 0))
    with_follow = run_rig((7, 0, 2, None, 0, 5))
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
