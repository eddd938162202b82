"""Replay of the bundled recording through `trackerd replay`: deterministic, accurate, paced, overridable.

Every replay here is the real command in its own process, publishing over
ZeroMQ to a subscriber in this one.
"""

from __future__ import annotations

import csv
import itertools
import json
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from rec_helpers import (
    interaction_events,
    one_line_error,
    replay_and_listen,
    trackerd,
    unsmoothed_xy,
    without_publish_time,
)

from trackerd.recording.reader import Recording
from trackerd.recording.replay import ReplayPairSource

SIMULATED = Path(__file__).resolve().parents[2] / "config" / "simulated.toml"
STILLS = Path(__file__).resolve().parents[1] / "data" / "pairs"


@pytest.fixture(scope="module")
def first_replay(bundle, tmp_path_factory):
    endpoint = f"ipc://{tmp_path_factory.mktemp('replay')}/pub.sock"
    return replay_and_listen(bundle, "--speed", "max", "--json", endpoint=endpoint)


def test_replaying_twice_gives_the_same_messages_bit_for_bit(bundle, first_replay, tmp_path) -> None:
    run1, messages1 = first_replay
    run2, messages2 = replay_and_listen(bundle, "--speed", "max", "--json", endpoint=f"ipc://{tmp_path}/pub.sock")
    assert run1.returncode == 0 and run2.returncode == 0, run2.stderr
    one, two = without_publish_time(messages1), without_publish_time(messages2)
    # Pairs 11 and 12 have no pointer; every other pair gives a pointer and a hit.
    assert sum(m.startswith("hit ") for m in one) == 14
    assert one == two
    summary = json.loads(run1.stdout)
    assert summary["pairs"] == 16 and summary["hits"] == 14 and summary["finished"]


def test_capture_times_are_the_recorded_ones(bundle, first_replay) -> None:
    _, messages = first_replay
    with Recording.open(bundle) as recording:
        offset = recording.metadata.clock_offset_ns
        recorded = {e.sequence: e.timestamp_ns + offset for e in recording.entries}
    hits = [m for t, m in messages if t == "hit"]
    assert hits and all(m["capture_ns"] == recorded[m["sequence"]] for m in hits)


def test_hits_lie_on_the_true_hits(bundle_truth, first_replay) -> None:
    _, messages = first_replay
    truth = {t["sequence"]: t for t in bundle_truth}
    errors_mm = [
        1000 * np.hypot(*np.subtract(unsmoothed_xy(m), truth[m["sequence"]]["wall_xy_m"]))
        for t, m in messages
        if t == "hit"
    ]
    assert len(errors_mm) == sum(t["present"] for t in bundle_truth)
    assert np.median(errors_mm) < 5.0 and max(errors_mm) < 15.0, errors_mm


def test_export_writes_the_hits_replay_publishes_and_draws_the_detections(bundle, first_replay, tmp_path) -> None:
    _, messages = first_replay
    run = trackerd("recording", "export", bundle, tmp_path / "out", "--every", "5")
    assert run.returncode == 0, run.stderr
    with (tmp_path / "out" / "hits.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 16 and [r["status"] for r in rows].count("not_found") == 2
    published = {m["sequence"]: m for t, m in messages if t == "hit"}
    for row in rows:
        hit = published.get(int(row["sequence"]))
        if hit is None:
            assert row["wall_x_m"] == ""
            continue
        assert int(row["capture_ns"]) == hit["capture_ns"]
        for key in ("wall_x_m", "wall_y_m", "distance_m", "ray_gap_mm"):
            assert float(row[key]) == hit[key]  # the same float, to the last bit
    images = sorted((tmp_path / "out").glob("*.png"))
    assert [p.name for p in images] == [f"{i:06d}-{c}.png" for i in (0, 5, 10, 15) for c in ("left", "right")]
    drawn = cv2.imread(str(images[0]))
    assert drawn.shape == (1080, 1920, 3)
    x, y = float(rows[0]["left_red_x_px"]), float(rows[0]["left_red_y_px"])
    with Recording.open(bundle) as recording:
        plain = cv2.cvtColor(np.ascontiguousarray(recording.images(0)[0]), cv2.COLOR_BayerRGGB2BGR)
    around = (slice(int(y) - 40, int(y) + 40), slice(int(x) - 40, int(x) + 40))
    assert np.count_nonzero(np.any(drawn[around] != plain[around], axis=2)) > 100  # a circle and a cross


def test_a_config_override_is_applied_and_stated(bundle, first_replay, tmp_path) -> None:
    _, recorded = first_replay
    same = replay_and_listen(bundle, "--speed", "max", "--config", SIMULATED, endpoint=f"ipc://{tmp_path}/a.sock")
    assert "configuration: OVERRIDDEN by" in same[0].stderr
    assert without_publish_time(same[1]) == without_publish_time(recorded)  # the recorded rig was this file
    moved = tmp_path / "moved.toml"
    moved.write_text(SIMULATED.read_text().replace("position_m = [-1.3, 1.4, 3.0]", "position_m = [-1.29, 1.4, 3.0]"))
    other = replay_and_listen(bundle, "--speed", "max", "--config", moved, endpoint=f"ipc://{tmp_path}/b.sock")
    assert other[0].returncode == 0 and f"OVERRIDDEN by {moved}" in other[0].stderr
    hits_recorded = [m["wall_x_m"] for t, m in recorded if t == "hit"]
    hits_other = [m["wall_x_m"] for t, m in other[1] if t == "hit"]
    assert len(hits_other) == len(hits_recorded) and hits_other != hits_recorded


@pytest.mark.parametrize(
    ("endpoint", "reason"),
    [
        ("tcp://0.0.0.0:5599", "tcp://0.0.0.0:5599 is reachable from the network; set"),
        ("bogus", "endpoints: 'bogus' is not a tcp://HOST:PORT or ipc:///path endpoint"),
    ],
)
def test_a_replay_endpoint_is_checked_as_the_rig_files_are(bundle, endpoint, reason) -> None:
    # Regression: the refusal was pydantic's report, four lines and a URL.
    run = trackerd("replay", bundle, "--endpoint", endpoint)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.startswith(f"trackerd replay: --endpoint: {reason}") and len(run.stderr.splitlines()) == 1


@pytest.mark.parametrize(
    ("option", "value", "reason"),
    [("--count", "0", "must be at least 1, not 0"), ("--first", "-2", "pairs are numbered from 0, not -2")],
)
def test_a_count_or_first_pair_out_of_range_is_refused_as_an_argument(bundle, option, value, reason) -> None:
    # --count 0 said "no intact pairs to replay" of an intact recording; --first -2 was taken as 0.
    run = trackerd("replay", bundle, option, value)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.strip().endswith(f"argument {option}: {reason}") and "Traceback" not in run.stderr


def test_paced_replay_keeps_the_recorded_intervals_and_loops_on(bundle) -> None:
    with Recording.open(bundle) as recording:
        recorded_ns = [e.timestamp_ns for e in recording.entries]
        before_start = time.monotonic_ns()  # the pace counts from the source's making (its first pair's time)
        source = ReplayPairSource(recording, speed=2.0, loop=True)
        delivered, pairs = [], []
        with source:
            while len(pairs) < 20:
                pair = source.next_pair(1.0)
                if pair is not None:
                    delivered.append(time.monotonic_ns())
                    pairs.append(pair)
    # Never ahead of the recorded pace (here twice the recorded rate), counted from the start.
    for k in range(16):
        assert delivered[k] - before_start >= (recorded_ns[k] - recorded_ns[0]) / 2.0
    # Looping: the second pass continues the first, in sequence and in time.
    sequences = [p.sequence for p in pairs]
    assert sequences[:16] == list(range(1, 17)) and sequences[16:] == [18, 19, 20, 21]
    assert all(b.timestamp_ns > a.timestamp_ns for a, b in itertools.pairwise(pairs))
    assert np.array_equal(pairs[16].frames[0].image, pairs[0].frames[0].image)


def test_a_paced_replay_delivers_each_pair_when_the_time_it_carries_says(bundle) -> None:
    """The pipeline's latency counts from a pair's timestamp. A replay is made, then the daemon starts up (a
    publisher bound, a locator made), then the replay starts: its pairs must be due at the times they
    carry, not that start-up later (`trackerd replay --speed 1` showed 135-220 ms of latency where the
    pipeline took 2 ms)."""
    with Recording.open(bundle) as recording:
        source = ReplayPairSource(recording, speed=1.0, start_delay_s=1.5)
        time.sleep(0.3)  # the start-up between making the source and starting it
        with source:
            pairs = [source.next_pair(5.0) for _ in range(3)]
            due_ns = [source._due_ns(source.first + k, 0) for k in range(3)]
    assert all(pair is not None for pair in pairs)
    assert [pair.timestamp_ns for pair in pairs if pair is not None] == due_ns
    # A start-up longer than the delay: the first pair is overdue by at least that, and the lag says so (it
    # read 0 while every latency carried the start-up).
    with Recording.open(bundle) as recording:
        source = ReplayPairSource(recording, speed=1.0, start_delay_s=0.0)
        time.sleep(0.3)
        with source:
            first = source.next_pair(5.0)
    assert first is not None and source.max_lag_ms >= 300.0


def test_each_pass_of_a_looped_replay_publishes_what_the_first_did(bundle, first_replay, tmp_path) -> None:
    """The jump from the last pair back to the first is no motion: every stage starts afresh at a
    wrap, so it makes no gesture (it made a circle_cw at each wrap) and each pass repeats the first."""
    run, messages = replay_and_listen(bundle, "--speed", "max", "--passes", "5", endpoint=f"ipc://{tmp_path}/loop.sock")
    assert run.returncode == 0, run.stderr
    with Recording.open(bundle) as recording:
        per_pass = max(e.sequence for e in recording.entries) + 1

    first = [(t, m) for t, m in first_replay[1] if t != "status"]
    first_events = interaction_events(first)
    passes = {}
    for topic, m in messages:
        if topic != "status":
            passes.setdefault(m["sequence"] // per_pass, []).append((topic, m))
    assert sorted(passes) == [0, 1, 2, 3, 4]
    complete = sorted(passes)[1:-1]  # the last pass's final leave comes from the stop, as the first run's
    for k in complete:
        # The first pass's final leave (the replay stopped) comes here from the next pass's reset.
        assert interaction_events(passes[k], k * per_pass) == first_events, k
    assert not any(t == "gesture" for t, _ in messages)


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Path:
    """The bundled still pairs (the report's style of static test images), imported twice: as the
    Bayer PNGs they are, with a timestamp file, and demosaiced to colour PNGs as another tool saves them."""
    folder = tmp_path_factory.mktemp("imported")
    stamps = folder / "times.csv"
    stamps.write_text("name,timestamp_ms\n01,1000\n02,1100\n03,1250\n")
    run = trackerd("recording", "import", STILLS, folder / "bayer.trec", "--config", SIMULATED, "--timestamps", stamps)
    assert run.returncode == 0, run.stderr
    assert "3 pairs imported" in run.stdout
    colour = folder / "colour"
    colour.mkdir()
    for path in STILLS.glob("*.png"):
        name, camera = path.stem.split("-")
        bayer = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(colour / f"{camera}_{name}.png"), cv2.cvtColor(bayer, cv2.COLOR_BayerRGGB2BGR))
    run = trackerd(
        "recording", "import", colour, folder / "colour.trec", "--config", SIMULATED, "--compression", "deflate"
    )
    assert run.returncode == 0, run.stderr
    return folder


def test_image_pairs_from_elsewhere_import_losslessly_with_their_timestamps(imported) -> None:
    with Recording.open(imported / "bayer.trec") as recording:
        assert [e.timestamp_ns for e in recording.entries] == [0, 100_000_000, 250_000_000]
        assert recording.cameras[0].pixel_format == "BayerRG8"
        assert np.array_equal(recording.images(1)[1], cv2.imread(str(STILLS / "02-right.png"), cv2.IMREAD_UNCHANGED))
    with Recording.open(imported / "colour.trec") as recording:
        assert len(recording) == 3 and recording.cameras[1].pixel_format == "BGR8"
        assert recording.images(2)[0].shape == (1080, 1920, 3)


@pytest.mark.parametrize("name", ["bayer", "colour"])
def test_each_imported_still_replays_to_its_true_hit(imported, name: str) -> None:
    for index, still in enumerate(("01", "02", "03")):
        run, messages = replay_and_listen(
            imported / f"{name}.trec",
            "--speed",
            "max",
            "--first",
            str(index),
            "--count",
            "1",
            "--delay",
            "0.5",
            endpoint=f"ipc://{imported}/{name}.sock",
        )
        assert run.returncode == 0, run.stderr
        (hit,) = [m for t, m in messages if t == "hit"]
        truth = json.loads((STILLS / f"{still}-truth.json").read_text())["wall_xy_m"]
        assert np.hypot(*np.subtract(unsmoothed_xy(hit), truth)) < 0.02
    if name == "colour":
        assert "frames are BGR8 (the rig says BayerRG8)" in run.stderr


def test_unrelated_stills_in_a_row_replay_without_crashing_the_pipeline(imported) -> None:
    run, messages = replay_and_listen(imported / "bayer.trec", "--speed", "max", endpoint=f"ipc://{imported}/row.sock")
    assert run.returncode == 0, run.stderr
    assert len([m for t, m in messages if t == "hit"]) == 3


def test_stills_without_timestamps_are_spaced_so_each_is_smoothed_on_its_own(imported, tmp_path) -> None:
    """The colour import has no timestamps: 1 s apart, past the interaction's reset_after_ms, so the
    published (smoothed) hit of each still is its own raw hit, not a blend with the still before."""
    with Recording.open(imported / "colour.trec") as recording:
        times = [e.timestamp_ns for e in recording.entries]
    assert times == [0, 1_000_000_000, 2_000_000_000]
    run = trackerd("recording", "export", imported / "colour.trec", tmp_path / "out", "--no-images")
    assert run.returncode == 0, run.stderr
    rows = [r for r in csv.DictReader((tmp_path / "out" / "hits.csv").open()) if r["status"] == "hit"]
    assert len(rows) >= 2
    for row in rows:
        assert (row["wall_x_m"], row["wall_y_m"]) == (row["raw_wall_x_m"], row["raw_wall_y_m"]), row
    # --rate keeps a real sequence's spacing.
    run = trackerd("recording", "import", STILLS, tmp_path / "rate.trec", "--config", SIMULATED, "--rate", "50")
    assert run.returncode == 0, run.stderr
    with Recording.open(tmp_path / "rate.trec") as recording:
        assert [e.timestamp_ns for e in recording.entries] == [0, 20_000_000, 40_000_000]


def test_timestamps_that_go_backwards_are_refused_naming_the_row(tmp_path) -> None:
    stamps = tmp_path / "times.csv"
    stamps.write_text("name,timestamp_ms\n01,5\n02,2\n03,9\n")
    run = trackerd("recording", "import", STILLS, tmp_path / "back.trec", "--config", SIMULATED, "--timestamps", stamps)
    one_line_error(run, "recording", f"{stamps}:3:", "'02'", "is not after '01'", "must increase")
    assert not (tmp_path / "back.trec").exists()
    stamps.write_text(
        "name,camera,timestamp_us\n01,left,10\n01,right,11\n02,left,20\n02,right,11\n03,left,30\n03,right,31\n"
    )
    run = trackerd("recording", "import", STILLS, tmp_path / "back.trec", "--config", SIMULATED, "--timestamps", stamps)
    one_line_error(run, "recording", f"{stamps}:5:", "'02' (right)")
