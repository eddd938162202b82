"""End to end through GigE Vision: the virtual rig serves rendered frames, trackerd acquires and pairs them.

Two simulated cameras, each in its own network namespace, serve a rendered
sweep; AravisPairSource acquires over real GVCP/GVSP, pairs, and the locator
triangulates every pair. The simulated cameras stamp each frame with its loop
index and capture instant (trackerd.sim.gvcamera.read_tag), which gives each
pair's ground truth and its true skew.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from acq_helpers import TEST_PREFIX, TEST_SUBNET, needs_aravis, needs_netns, quick_rig

from trackerd.config.models import RigConfig

pytestmark = [pytest.mark.aravis, pytest.mark.root, needs_aravis, needs_netns]

REPO = Path(__file__).resolve().parents[2]
ACQUIRE_S = 3.0
LOOP_FPS = 8.0


@pytest.fixture(scope="module")
def virtual(simulated_rig: RigConfig, tmp_path_factory: pytest.TempPathFactory):
    from trackerd.sim.rig import VirtualRig

    rig = quick_rig(simulated_rig, trigger="software")
    with VirtualRig(
        rig,
        motion="sweep",
        period_s=1.0,
        content_fps=LOOP_FPS,
        network="netns",
        prefix=TEST_PREFIX,
        subnet=TEST_SUBNET,
        mtu=9000,
        out_dir=tmp_path_factory.mktemp("simrig"),
        cache_dir=REPO / ".cache" / "simrig",
    ) as rig_:
        yield rig_


def acquire(virtual, trigger: str, seconds: float = ACQUIRE_S):
    """Pairs acquired for ``seconds`` with the given trigger mode, and the final status."""
    import time

    from trackerd.acquisition.live import AravisPairSource

    daemon = virtual.daemon_rig
    daemon = daemon.model_copy(update={"acquisition": daemon.acquisition.model_copy(update={"trigger": trigger})})
    pairs = []
    with AravisPairSource(daemon) as source:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            pair = source.next_pair(0.5)
            if pair is not None:
                pairs.append(pair)
        status = source.status()
    return pairs, status


def tags_of(pair):
    from trackerd.sim.gvcamera import read_tag

    tags = [read_tag(frame.image) for frame in pair.frames]
    assert all(tag is not None for tag in tags)
    return tags


def report(label: str, pairs, status, true_skews_us) -> None:
    print(
        f"\n{label}: {len(pairs)} pairs ({status.pair_rate_hz:g}/s), frames {[c.frames for c in status.cameras]},"
        f" dropped {status.dropped_frames}, skew estimated p50 {status.skew_p50_us:.0f} us"
        f" p99 {status.skew_p99_us:.0f} us, true p50 {np.median(true_skews_us):.0f} us"
        f" p99 {np.percentile(true_skews_us, 99):.0f} us"
    )


def _runs(values: list[int]) -> list[tuple[int, list[int]]]:
    """Consecutive equal values: (value, indices) per run, in order."""
    runs: list[tuple[int, list[int]]] = []
    for index, value in enumerate(values):
        if runs and runs[-1][0] == value:
            runs[-1][1].append(index)
        else:
            runs.append((value, [index]))
    return runs


def test_software_trigger_pairs_answer_one_trigger_and_triangulate(virtual) -> None:
    from trackerd.locator import Locator

    pairs, status = acquire(virtual, "software")
    assert len(pairs) >= 30, status
    assert status.pairing == "trigger count"
    # Zero frame-id mismatch: every camera's counter advanced once per trigger, in step. A camera's
    # counter restarts when it reconnects (on a loaded machine the quick rig's 300 ms loss timeout
    # can pass), so this holds connection by connection: one run of one difference each.
    runs = _runs([p.frames[0].frame_id - p.frames[1].frame_id for p in pairs])
    reconnects = sum(c.reconnects for c in status.cameras)
    assert len(runs) <= 1 + reconnects, ([(value, len(run)) for value, run in runs], status)
    true_skews_us = []
    for _, run in runs:
        served = set()
        for pair in (pairs[i] for i in run):
            left, right = tags_of(pair)
            true_skews_us.append(abs(left.capture_ns - right.capture_ns) / 1000)
            served.add(left.served - right.served)
        # ...and so did the simulated cameras' own count of frames served (the ground truth):
        # every pair holds the n-th frame of both cameras, never frames of neighbouring triggers.
        assert len(served) == 1, served
    report("software trigger", pairs, status, true_skews_us)

    truth = virtual.loop.truth()
    locator = Locator(virtual.daemon_rig)
    end_errors_mm, hit_errors_mm, not_located, straddling = [], [], 0, 0
    for pair in pairs[::2]:
        left, right = tags_of(pair)
        if left.loop_index != right.loop_index:
            straddling += 1  # captured either side of a change of scene frame
            continue
        expected = truth[left.loop_index]
        fix = locator.locate(pair.images)
        if fix.line is None or fix.hit is None:
            not_located += 1
            continue
        end_errors_mm.append(1000 * np.linalg.norm(fix.line.front_m - expected["front_m"]))
        end_errors_mm.append(1000 * np.linalg.norm(fix.line.back_m - expected["back_m"]))
        hit_errors_mm.append(1000 * np.linalg.norm(fix.hit.wall_xy_m - expected["wall_xy_m"]))
    print(
        f"triangulated {len(hit_errors_mm)} pairs: ends within {max(end_errors_mm):.2f} mm,"
        f" wall hits within {max(hit_errors_mm):.2f} mm; {not_located} not located,"
        f" {straddling} straddling a scene change"
    )
    assert not_located == 0
    assert straddling <= len(pairs) // 10
    assert max(end_errors_mm) < 10.0
    assert max(hit_errors_mm) < 20.0


def test_free_running_cameras_pair_by_time_across_foreign_clocks(virtual) -> None:
    """The simulated cameras' clocks are seconds apart and drift; pairs still match true capture times."""
    pairs, status = acquire(virtual, "free_running")
    assert len(pairs) >= 30, status
    assert status.pairing == "host time"
    offsets = [c.clock_offset_ns for c in status.cameras]
    assert abs(offsets[0] - offsets[1]) > 1e9  # the device clocks really are different
    true_signed_us = []
    for pair in pairs:
        left, right = tags_of(pair)
        true_signed_us.append((right.capture_ns - left.capture_ns) / 1000)
    estimated_us = np.array([p.skew_ns / 1000 for p in pairs])
    true_us = np.abs(true_signed_us)
    expected_phase_us = virtual.phase_us(1) - virtual.phase_us(0)  # camera 1 exposes this much later
    period_us = virtual.rig.acquisition.frame_period_us
    # Never a frame of the neighbouring period, which would be period - phase away (11.5 ms here).
    assert true_us.max() < period_us - expected_phase_us - 1000
    assert abs(np.median(true_signed_us) - expected_phase_us) < 2000
    # The clock mapping is right to within the cameras' difference in transfer delay (< 1.5 ms here).
    assert np.median(np.abs(estimated_us - true_us)) < 1500
    report("free running", pairs, status, true_us)
