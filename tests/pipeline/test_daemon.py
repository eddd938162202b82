"""The pipeline end to end on rendered frames: source -> locator -> ZeroMQ, with real sockets."""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import threading
import time

import numpy as np
import pytest
import zmq

from tests.gated import GatedPairSource, wait_for_status
from trackerd.acquisition.memory import MemoryPairSource
from trackerd.bench.pairtrace import TraceObserver
from trackerd.pipeline.daemon import Pipeline
from trackerd.pipeline.processing import HEALTH_EVERY
from trackerd.publish import Publisher
from trackerd.sdnotify import SdNotify

pytestmark = pytest.mark.serial  # runs daemons and times their reloads and stops


def _rig_on(rig, endpoint: str, status_ms: float = 200.0):
    zmq_cfg = rig.outputs.zmq.model_copy(update={"endpoints": (endpoint,), "status_interval_ms": status_ms})
    return rig.model_copy(update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg})})


def _subscribe(endpoint: str, topics=(b"",)) -> tuple[zmq.Context, zmq.Socket]:
    ctx = zmq.Context()
    sub = ctx.socket(zmq.SUB)
    for topic in topics:
        sub.setsockopt(zmq.SUBSCRIBE, topic)
    sub.connect(endpoint)
    return ctx, sub


def _collect(sub: zmq.Socket, seconds: float) -> list[tuple[str, dict]]:
    out = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if sub.poll(50):
            topic, payload = sub.recv_multipart()
            out.append((topic.decode(), json.loads(payload)))
    return out


def _wait_published(pipeline: Pipeline, count: int, timeout_s: float = 30.0) -> None:
    """Until ``count`` pairs are published, the pipeline fails, or the timeout passes."""
    deadline = time.monotonic() + timeout_s
    while pipeline.pairs_published < count and time.monotonic() < deadline and pipeline.failure is None:
        time.sleep(0.02)


def test_hits_match_the_truth_and_sequences_have_no_unexplained_gaps(simulated_rig, rendered_sweep, tmp_path):
    image_sets, truths = rendered_sweep
    endpoint = f"ipc://{tmp_path}/pub.sock"
    rig = _rig_on(simulated_rig, endpoint)
    count = 3 * len(image_sets)
    sources: list[GatedPairSource] = []

    def source_for(r):
        sources.append(GatedPairSource(r, image_sets, rate_hz=20.0, count=count))
        return sources[-1]

    pipeline = Pipeline(rig, source_for, lambda r: Publisher(r.outputs.zmq))
    ctx, sub = _subscribe(endpoint)
    try:
        pipeline.start()
        messages = wait_for_status(sub)  # the subscriber is connected: it must see every pair
        sources[0].open()
        messages += _collect(sub, count / 20.0 + 1.0)
    finally:
        pipeline.stop()
        sub.close(0)
        ctx.term()
    hits = [m for t, m in messages if t == "hit"]
    pointers = [m for t, m in messages if t == "pointer"]
    statuses = [m for t, m in messages if t == "status"]
    errors = []
    for hit in hits:
        truth = truths[hit["sequence"] % len(image_sets)]
        errors.append(np.hypot(hit["wall_x_m"] - truth.wall_xy_m[0], hit["wall_y_m"] - truth.wall_xy_m[1]))
        assert hit["capture_ns"] <= hit["publish_ns"]
    assert np.median(errors) < 0.005
    # Every pair is accounted for: processed and published, or dropped by the source and counted
    # (paced like a camera, it drops a pair the pipeline did not take before the next was due; a
    # loaded CI machine once stalled the processing thread that long). Nothing vanishes in between.
    pairing = sources[0].status()
    assert pairing.delivered + pairing.dropped_pairs == count
    assert pipeline.pairs_processed == pairing.delivered
    assert pipeline.pairs_published == pipeline.pairs_processed
    assert statuses[-1]["pairing"]["dropped_pairs"] == pairing.dropped_pairs
    sequences = {p["sequence"] for p in pointers}
    unexplained = set(range(count)) - sequences
    assert len(unexplained) == pairing.dropped_pairs, sorted(unexplained)
    # Drops come from stalls of the machine, not from a pipeline too slow for 20 pairs a second.
    assert np.median(pipeline.figures.processing_cpu.snapshot()) < 25e6
    assert pairing.dropped_pairs < count // 2, pairing
    assert statuses and statuses[-1]["cameras"][0]["state"] in ("streaming", "stopped")
    last_running = [s for s in statuses if s["state"] == "running"][-1]
    assert last_running["fixes"].get("hit", 0) + last_running["fixes"].get("off_wall", 0) > 0
    assert set(last_running["stages"]) == {"detect", "triangulate", "publish"}
    # The calibration is the one the frames were rendered with: the cameras agree.
    health = statuses[-1]["calibration"]
    assert health["total_fixes"] > 0 and health["ray_gap_mm"]["p50"] < 4.0
    captures = [m["capture_ns"] for _, m in messages if _ != "status"]
    assert captures == sorted(captures)  # published timestamps never go backwards
    # The sweep's tracked ends are measured again as they move: between pairs, once each pair is sent.
    assert pipeline.locator.measured_between_pairs > 0


def test_an_observed_pipeline_takes_each_pairs_latency_apart(simulated_rig, rendered_sweep, tmp_path):
    image_sets, _ = rendered_sweep
    rig = _rig_on(simulated_rig, f"ipc://{tmp_path}/pub.sock")
    count = 2 * len(image_sets)
    sources: list[GatedPairSource] = []

    def source_for(r):
        sources.append(GatedPairSource(r, image_sets, rate_hz=30.0, count=count, drop_late=False))
        return sources[-1]

    observer = TraceObserver()
    pipeline = Pipeline(rig, source_for, lambda r: Publisher(r.outputs.zmq), observer=observer)
    try:
        pipeline.start()
        observer.start()
        pipeline.figures.processing.record()
        sources[0].open()
        _wait_published(pipeline, count)
    finally:
        pipeline.stop()
    assert pipeline.failure is None and pipeline.pairs_published == count
    trace = observer.trace()
    # One trace per pair published, whose latency is the one the figures report.
    assert len(trace) == count
    assert [t.latency_ns for t in trace] == pipeline.figures.processing.recorded().tolist()
    assert [t.received_ns for t in trace] == sorted(t.received_ns for t in trace)
    for t in trace:
        assert t.waiting_ns >= 0 and t.handoff_ns >= 0
        assert t.waiting_ns + t.processing.wall_ns + t.handoff_ns <= t.latency_ns + 1_000_000
        for part in (t.processing, t.publishing):
            assert 0 <= part.runqueue_ns <= part.off_cpu_ns <= part.wall_ns
        # Locating is real work: the processing thread ran for most of it.
        assert t.processing.wall_ns - t.processing.off_cpu_ns > 100_000


def test_a_bumped_camera_shows_in_the_status_calibration_health(simulated_rig, rendered_sweep, tmp_path):
    """Fixes the locator rejects for their ray gap are what a bumped camera makes: they must reach
    the status's calibration health, or it would stay 'fine' exactly when it is not."""
    image_sets, _ = rendered_sweep
    # The frames were rendered with the rig's calibration; the daemon believes camera 2 turned 1.5 degrees.
    turned = simulated_rig.cameras[1]
    turned = turned.model_copy(
        update={"extrinsics": turned.extrinsics.model_copy(update={"yaw_deg": turned.extrinsics.yaw_deg + 1.5})}
    )
    bumped = simulated_rig.model_copy(update={"cameras": (simulated_rig.cameras[0], turned)})
    rig = _rig_on(bumped, f"ipc://{tmp_path}/pub.sock")
    count = 8 * len(image_sets)  # health judges from 20 fixes; it measures every fourth pair
    pipeline = Pipeline(
        rig, lambda r: MemoryPairSource(r, image_sets, rate_hz=None, count=count), lambda r: Publisher(r.outputs.zmq)
    )
    try:
        pipeline.start()
        _wait_published(pipeline, count)
    finally:
        pipeline.stop()
    assert pipeline.failure is None and pipeline.pairs_published == count
    status = pipeline.build_status(None)
    assert status.fixes.get("rejected", 0) > count // 2, status.fixes
    assert status.calibration is not None, "the rejected fixes never reached the health record"
    assert status.calibration.total_fixes >= status.fixes["rejected"] // HEALTH_EVERY - 1
    assert status.calibration.ray_gap_mm.p50 > 1000 * rig.locator.max_ray_gap_m
    assert status.calibration.suspect


def test_a_room_without_the_pointer_is_searched_at_the_cadence_not_on_every_pair(
    simulated_rig, rendered_sweep, tmp_path, searches
):
    """The pointer found, then thirteen pairs without it: the search over every camera's candidates (tens of
    milliseconds to a second a pair) runs on the first of them and then on every search_every_pairs-th
    (config/pointer.py's promise: a room without the pointer does not keep a core busy). The processing stage
    used to reset the whole locator on each such pair, which made every one of them a first sighting,
    searched."""
    image_sets, truths = rendered_sweep
    with_pointer = next(images for images, truth in zip(image_sets, truths, strict=True) if truth is not None)
    empty = [np.zeros_like(image) for image in with_pointer]
    pairs = [with_pointer] + [empty] * 13
    rig = _rig_on(simulated_rig, f"ipc://{tmp_path}/pub.sock")
    every = rig.locator.search_every_pairs
    pipeline = Pipeline(
        rig,
        lambda r: MemoryPairSource(r, pairs, rate_hz=None, count=len(pairs), drop_late=False),
        lambda r: Publisher(r.outputs.zmq),
    )
    try:
        pipeline.start()
        _wait_published(pipeline, len(pairs))
    finally:
        pipeline.stop()
    assert pipeline.failure is None and pipeline.pairs_published == len(pairs)
    status = pipeline.build_status(None)
    assert status.fixes.get("not_found", 0) == 13, status.fixes
    # The first pair's pointer is found by its detectors (no search); then pairs 1, 1 + every, 1 + 2 every...
    assert len(searches) == len(range(0, 13, every)), (len(searches), every)


def test_a_subscriber_that_never_reads_does_not_slow_the_pipeline(simulated_rig, rendered_sweep, tmp_path):
    image_sets, _ = rendered_sweep
    endpoint = f"ipc://{tmp_path}/pub.sock"
    rig = _rig_on(simulated_rig, endpoint)
    ctx = zmq.Context()
    stalled = ctx.socket(zmq.SUB)
    stalled.setsockopt(zmq.SUBSCRIBE, b"")
    stalled.setsockopt(zmq.RCVHWM, 10)
    stalled.connect(endpoint)
    # As fast as it can, 300 pairs: the publisher must never block on the stalled subscriber.
    pipeline = Pipeline(
        rig, lambda r: MemoryPairSource(r, image_sets, rate_hz=None, count=300), lambda r: Publisher(r.outputs.zmq)
    )
    try:
        pipeline.start()
        deadline = time.monotonic() + 60
        while pipeline.pairs_processed < 50 and time.monotonic() < deadline:
            time.sleep(0.01)
        rss_start = _rss_bytes()
        while pipeline.pairs_processed < 300 and time.monotonic() < deadline and pipeline.failure is None:
            time.sleep(0.05)
        rss_growth = _rss_bytes() - rss_start
    finally:
        pipeline.stop()
        stalled.close(0)
        ctx.term()
    assert pipeline.failure is None
    assert pipeline.pairs_processed == 300
    # Messages for the stalled subscriber are dropped at its high-water mark, not queued forever.
    assert rss_growth < 30e6, f"memory grew by {rss_growth / 1e6:.0f} MB"


def _rss_bytes() -> int:
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


class _FailingSource(MemoryPairSource):
    """A source with a bug: it raises after a few pairs, as any broken stage might."""

    def next_pair(self, timeout_s):
        pair = super().next_pair(timeout_s)
        if pair is not None and pair.sequence >= 5:
            raise RuntimeError("simulated bug in a pair source")
        return pair


def test_a_crashed_thread_stops_the_daemon_with_a_non_zero_exit(simulated_rig, rendered_sweep, tmp_path):
    from trackerd.cli.run import serve

    image_sets, _ = rendered_sweep
    rig = _rig_on(simulated_rig, f"ipc://{tmp_path}/pub.sock")
    started = time.monotonic()
    code = serve(rig, None, lambda r: _FailingSource(r, image_sets, rate_hz=50.0), seconds=20)
    assert code == 1
    assert time.monotonic() - started < 5


def test_watchdog_and_ready_reach_systemd_only_when_pairs_flow(simulated_rig, rendered_sweep, tmp_path):
    """READY once the cameras stream, WATCHDOG=1 from processed pairs, STOPPING on stop."""
    import socket

    image_sets, _ = rendered_sweep
    path = tmp_path / "notify.sock"
    server = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    server.bind(str(path))
    server.settimeout(0.1)
    notifier = SdNotify({"NOTIFY_SOCKET": str(path), "WATCHDOG_USEC": "400000"})
    rig = _rig_on(simulated_rig, f"ipc://{tmp_path}/pub.sock")
    received: list[str] = []

    def listen(stop: threading.Event) -> None:
        while not stop.is_set():
            with contextlib.suppress(TimeoutError):
                received.append(server.recv(4096).decode())

    stop = threading.Event()
    listener = threading.Thread(target=listen, args=(stop,))
    listener.start()
    pipeline = Pipeline(
        rig,
        lambda r: MemoryPairSource(r, image_sets, rate_hz=20.0, count=20, drop_late=False),
        lambda r: Publisher(r.outputs.zmq),
        notifier,
    )

    def read_so_far() -> list[str]:
        """Every notification sent until now (a marker of our own, sent last, is read last)."""
        marker = f"TEST_MARKER={time.monotonic_ns()}"
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as client:
            client.sendto(marker.encode(), str(path))
        deadline = time.monotonic() + 10.0
        while marker not in received and time.monotonic() < deadline:
            time.sleep(0.01)
        assert marker in received
        return [m for m in received if not m.startswith("TEST_MARKER")]

    try:
        pipeline.start()
        deadline = time.monotonic() + 20.0  # the 20 pairs take one second; then nothing flows
        while (pipeline.pairs_processed < 20 or pipeline.backlog) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert pipeline.pairs_processed == 20
        watchdogs_while_flowing = sum("WATCHDOG=1" in m for m in read_so_far())
        time.sleep(0.6)
        watchdogs_after = sum("WATCHDOG=1" in m for m in read_so_far())
    finally:
        pipeline.stop()
        try:
            notifications = read_so_far()
        finally:
            stop.set()
            listener.join()
            server.close()
    assert any("READY=1" in m for m in notifications)
    first_ready = next(i for i, m in enumerate(notifications) if "READY=1" in m)
    assert all("STOPPING=1" not in m for m in notifications[:first_ready])
    assert watchdogs_while_flowing >= 2
    # The source stopped delivering (count reached): nothing feeds the watchdog any more.
    assert watchdogs_after == watchdogs_while_flowing
    # STOPPING is sent once, at stop; only the last status lines may follow it.
    stopping = [i for i, m in enumerate(notifications) if "STOPPING=1" in m]
    assert len(stopping) == 1 and stopping[0] > first_ready
    assert all(m.startswith("STATUS=") for m in notifications[stopping[0] + 1 :]), notifications


def test_a_reload_reads_the_curve_client_keys_again_and_applies_the_status_interval(
    simulated_rig, rendered_sweep, tmp_path
):
    """SIGHUP with the same outputs: a client key added is let in and one removed is shut out, on
    their next connection, and a new status_interval_ms takes effect (both were read only at start)."""
    import zmq.auth

    from trackerd.cli.keys import write_key_pair

    image_sets, _ = rendered_sweep
    _, server_secret = write_key_pair(tmp_path, "server", "server")
    server_public, _ = zmq.auth.load_certificate(str(server_secret))
    clients, elsewhere = tmp_path / "clients", tmp_path / "elsewhere"
    clients.mkdir()
    elsewhere.mkdir()
    write_key_pair(clients, "wall-app", "client")
    app_public, app_secret = write_key_pair(elsewhere, "new-app", "client")
    app_keys = zmq.auth.load_certificate(str(app_secret))

    def rig_with(status_ms: float):
        rig = _rig_on(simulated_rig, "tcp://127.0.0.1:5579", status_ms)
        zmq_cfg = rig.outputs.zmq.model_copy(
            update={"curve_secret_key_file": server_secret, "curve_authorized_keys_dir": clients}
        )
        return rig.model_copy(update={"outputs": rig.outputs.model_copy(update={"zmq": zmq_cfg})})

    def reload(status_ms: float) -> None:
        """Request a reload and wait until both threads have taken it (then a moment to apply it)."""
        pipeline.request_reload(rig_with(status_ms))
        deadline = time.monotonic() + 10.0
        while pipeline.reload_pending and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.2)

    def statuses_for(seconds: float) -> list[dict]:
        """What a new connection as new-app, subscribed to status, receives in ``seconds``."""
        ctx = zmq.Context()
        sub = ctx.socket(zmq.SUB)
        sub.curve_serverkey, sub.curve_publickey, sub.curve_secretkey = server_public, *app_keys
        sub.setsockopt(zmq.SUBSCRIBE, b"status")
        sub.connect("tcp://127.0.0.1:5579")
        try:
            return [m for t, m in _collect(sub, seconds) if t == "status"]
        finally:
            sub.close(0)
            ctx.term()

    def statuses_seen(seconds: float) -> int:
        return len(statuses_for(seconds))

    def spacing_s(seconds: float) -> float:
        """Median time between the statuses seen in ``seconds`` (the last-value answer aside), from
        their publish_ns: a stalled machine delays them, not their spacing."""
        times = [m["publish_ns"] for m in statuses_for(seconds)][1:]
        assert len(times) >= 2, times
        return float(np.median(np.diff(times))) / 1e9

    rig = rig_with(1000.0)
    pipeline = Pipeline(
        rig, lambda r: MemoryPairSource(r, image_sets, rate_hz=30.0), lambda r: Publisher(r.outputs.zmq)
    )
    pipeline.start()
    try:
        assert statuses_seen(1.5) == 0  # not authorized
        os.replace(app_public, clients / app_public.name)
        reload(1000.0)
        # Let in: the last-value status at once, then about one a second.
        assert 0.8 < spacing_s(3.5) < 1.4
        reload(200.0)
        assert 0.15 < spacing_s(2.0) < 0.3
        key_text = (clients / app_public.name).read_bytes()
        (clients / app_public.name).unlink()  # revoked
        reload(200.0)
        assert statuses_seen(1.5) == 0
        # Let in again, then every key removed: an empty directory lets nobody in (an empty one
        # is refused at start, which must not keep the last keys standing at a reload).
        (clients / app_public.name).write_bytes(key_text)
        reload(200.0)
        assert statuses_seen(1.5) > 0
        for key in clients.glob("*.key"):
            key.unlink()
        reload(200.0)
        assert statuses_seen(1.5) == 0
    finally:
        pipeline.stop()
    assert pipeline.failure is None


def test_sequences_go_on_across_a_reload_that_reopens_the_cameras(simulated_rig, rendered_sweep, tmp_path):
    """A new source counts its pairs from 0; subscribers must never see a sequence go back (a gap
    detector would take it for a restart), whether the new settings are taken or refused."""
    image_sets, _ = rendered_sweep
    endpoint = f"ipc://{tmp_path}/pub.sock"
    rig = _rig_on(simulated_rig, endpoint)

    def with_exposure(exposure_us: float):
        left = rig.cameras[0]
        acquisition = left.acquisition.model_copy(update={"exposure_us": exposure_us})
        return rig.model_copy(
            update={"cameras": (left.model_copy(update={"acquisition": acquisition}), *rig.cameras[1:])}
        )

    refused = with_exposure(5e7)
    sources: list[MemoryPairSource] = []

    def source_for(r):
        if r == refused:
            raise RuntimeError("the camera refuses exposure_us = 5e7")  # as a real camera would
        sources.append(MemoryPairSource(r, image_sets, rate_hz=50.0, drop_late=False))
        return sources[-1]

    pipeline = Pipeline(rig, source_for, lambda r: Publisher(r.outputs.zmq))
    ctx, sub = _subscribe(endpoint, (b"pointer", b"status"))
    try:
        pipeline.start()
        messages = wait_for_status(sub)
        messages += _collect(sub, 0.6)
        pipeline.request_reload(with_exposure(2000.0))  # taken: the cameras are reopened
        messages += _collect(sub, 0.8)
        pipeline.request_reload(refused)  # refused: the previous settings are reopened
        messages += _collect(sub, 0.8)
    finally:
        pipeline.stop()
        sub.close(0)
        ctx.term()
    assert pipeline.failure is None
    assert len(sources) == 3, "the cameras were not reopened"
    sequences = [m["sequence"] for t, m in messages if t == "pointer"]
    assert len(sequences) > 40 and all(b > a for a, b in itertools.pairwise(sequences)), sequences
    # Each source's pairs are all counted: the status adds up those of the sources replaced.
    delivered = sum(s.status().delivered for s in sources)
    last = [m for t, m in messages if t == "status"][-1]
    assert last["pairing"]["pairs"] <= delivered and last["pairing"]["pairs"] > sources[-1].status().pairs
