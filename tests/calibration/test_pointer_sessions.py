"""The --live sessions that watch the pointer (trackerd.calibration.pointer_sessions): wall targets
captured when the pointer is held still, retried and skipped, never filed under another target.

Frames are the cached rendered pointing scenes of conftest.py, served by the same source as
test_live.py's board sessions.
"""

from __future__ import annotations

import numpy as np
from calibration_frames import FrameSet

from tests.calibration.test_live import IDS, source_of
from trackerd.calibration.live import run_session
from trackerd.calibration.pointer_sessions import Steadiness, WallSession
from trackerd.calibration.wall import fit_wall
from trackerd.locator import Locator


def test_wall_session_captures_each_target_when_the_pointer_is_held_still(
    pointing_frames: FrameSet, simulated_rig, renderer
) -> None:
    from trackerd.bench.calibration import wall_targets

    wall = renderer.wall
    targets = {t.label: t for t in wall_targets(wall.width_m, wall.height_m)}
    plan = ["br", "tr", "centre"]  # targets whose rendered frames the detector gets right
    steadiness = Steadiness(frames=3, tolerance_m=0.002)
    pairs = []
    for label in plan:
        for place in (1, 2):
            frames = [pointing_frames.frame(f"{label}-{place}", c) for c in IDS]
            pairs += [frames] * 4  # held still for four frames
    session = WallSession(
        Locator(simulated_rig), [targets[label] for label in plan], "point", places=2, steadiness=steadiness
    )
    assert session.prompt() == "aim at 'br' from place 1 of 2 and hold still"
    lines: list[str] = []
    with source_of(pairs) as source:
        run_session(source, session, IDS, say=lines.append, newest=False)
    captured = [line for line in lines if "captured" in line]
    assert len(captured) == len(session.pointings) == 6 and session.done
    assert captured[0].startswith("[ 1/6] captured 'br'")
    assert "next: aim at 'br' from place 2 of 2 (move to a new place first)" in captured[0]
    assert captured[-1].endswith("next: all targets done")
    # Three targets from two places each are enough for a first wall.
    fit = fit_wall([], session.pointings, (wall.width_m, wall.height_m), 0.02, fit_size=False)
    assert np.degrees(np.arccos(fit.rotation[:, 2] @ wall.normal)) < 1.0


def _misses_mm(session: WallSession, wall) -> dict[str, float]:
    """How far each captured pointing's line passes from the true place of the target it was filed under."""
    out = {}
    for k, p in enumerate(session.pointings):
        rel = wall.from_wall_m(p.target.wall_xy_m) - p.tip_m
        out[f"{k}:{p.target.label}"] = float(np.linalg.norm(rel - (rel @ p.direction) * p.direction)) * 1000
    return out


def test_wall_session_retries_a_target_it_cannot_locate_and_never_files_a_capture_under_another(
    pointing_frames: FrameSet, stereo_frames: FrameSet, simulated_rig, renderer
) -> None:
    """Frames without the pointer (the board scenes) keep the session on the same target; the
    pointer still held where the last capture was is not captured again for the next target;
    a target never located is skipped after skip_after frames, and named as skipped."""
    from trackerd.bench.calibration import wall_targets

    wall = renderer.wall
    targets = {t.label: t for t in wall_targets(wall.width_m, wall.height_m)}
    nothing = [stereo_frames.frame(stereo_frames.names()[0], c) for c in IDS]  # no pointer in view

    def held(label: str, place: int, frames: int = 4) -> list:
        return [[pointing_frames.frame(f"{label}-{place}", c) for c in IDS]] * frames

    pairs = (
        [nothing] * 6  # br asked for, the pointer not in view yet
        + held("br", 1)  # captured on the third frame held still
        + held("br", 1, 5)  # still held there after the capture: not br from place 2
        + [nothing]
        + held("br", 2)
        + [nothing] * 25  # tr is never located: both its places skipped after 12 frames each
        + held("centre", 1)
        + held("centre", 2)
    )
    session = WallSession(
        Locator(simulated_rig),
        [targets[label] for label in ("br", "tr", "centre")],
        "point",
        places=2,
        steadiness=Steadiness(frames=3, tolerance_m=0.002),
        skip_after=12,
    )
    lines: list[str] = []
    with source_of(pairs) as source:
        run_session(source, session, IDS, say=lines.append, newest=False)
    text = "\n".join(lines)
    captured = [line for line in lines if "captured" in line]
    assert [line.split("'")[1] for line in captured] == ["br", "br", "centre", "centre"], text
    assert lines[0].startswith("  'br': pointer not located ("), text
    assert "  still where the last capture was: aim at 'br' from place 2 of 2" in text
    assert session.skipped == ["tr from place 1", "tr from place 2"], text
    assert "  skipped 'tr from place 1': no capture in 12 frames (the pointer was located in 1 of them;" in text
    assert session.done
    # Every capture is filed under the target it was aimed at: its line passes within millimetres of it.
    misses = _misses_mm(session, wall)
    assert max(misses.values()) < 10.0, misses


def test_steadiness_waits_for_the_pointer_to_stop() -> None:
    steady = Steadiness(frames=3, tolerance_m=0.002)
    front, back = np.zeros(3), np.array([0.0, 0.0, 0.45])
    assert steady.add(front, back) is None
    assert steady.add(front + np.array([0.01, 0.0, 0.0]), back) is None  # still moving
    assert steady.add(front, back) is None
    assert steady.add(front, back) is None
    got = steady.add(front, back)
    assert got is not None and np.allclose(got[0], front)
