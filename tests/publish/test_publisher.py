"""The ZeroMQ publisher with real sockets: round trips, slow subscribers, late joiners, errors, shutdown."""

from __future__ import annotations

import json
import socket
import threading
import time
from pathlib import Path

import pytest
import zmq
from pydantic import ValidationError

from tests.publish.conftest import (
    hit_message,
    pointer_message,
    publish_until_received,
    status_message,
    subscriber,
)
from tests.publish.schema_check import SchemaError, validate
from trackerd.config.loader import load_rig
from trackerd.config.models import ZmqOutput
from trackerd.errors import ConfigError
from trackerd.publish import SCHEMA_VERSION, Publisher, PublishError, decode
from trackerd.publish import publisher as publisher_module

pytestmark = pytest.mark.serial  # publishes on real sockets at rates it measures


def _endpoint(kind: str, tmp_path: Path) -> str:
    return "tcp://127.0.0.1:*" if kind == "tcp" else f"ipc://{tmp_path}/trackerd.sock"


@pytest.mark.parametrize("kind", ["tcp", "ipc"])
def test_every_topic_round_trips_and_matches_its_schema(kind, tmp_path, context, schemas):
    stamps = iter(range(1_000_000_000, 2_000_000_000, 1000))
    config = ZmqOutput(endpoints=(_endpoint(kind, tmp_path),))
    with Publisher(config, clock=lambda: next(stamps)) as publisher:
        for original in (hit_message(41), pointer_message(42), status_message(43)):
            sub = subscriber(context, publisher.endpoints[0], original.topic.encode())
            if original.topic == "status":
                publisher.publish_status(original)
                # The last value reaches this new subscriber without another publish.
                assert sub.poll(5000)
                topic, payload = sub.recv_multipart()
            else:
                topic, payload = publish_until_received(publisher, sub, original)
            sub.close()
            assert topic == original.topic.encode()
            data = json.loads(payload)
            validate(data, schemas[original.topic])
            assert data["schema_version"] == SCHEMA_VERSION
            assert 1_000_000_000 <= data["publish_ns"] < 2_000_000_000  # stamped with the given clock
            received = decode(topic, payload)
            expected = original.model_dump(exclude={"publish_ns", "messages", "dropped_messages"})
            assert received.model_dump(exclude={"publish_ns", "messages", "dropped_messages"}) == expected
        assert publisher.counts["hit"] >= 1 and publisher.counts["status"] == 1


def test_the_schema_check_rejects_broken_payloads(schemas):
    """The validation above can fail."""
    good = json.loads(hit_message().model_dump_json())
    validate(good, schemas["hit"])
    for broken in (
        {**good, "on_wall": "yes"},
        {k: v for k, v in good.items() if k != "wall_x_m"},
        {**good, "front_m": [1.0, 2.0]},
        {**good, "sequence": -1},
    ):
        with pytest.raises(SchemaError):
            validate(broken, schemas["hit"])
    validate({**good, "smoothed_x_m": 1.0}, schemas["hit"])  # unknown fields are allowed (a newer MINOR)


def _publish_burst(publisher: Publisher, count: int) -> tuple[float, float, int]:
    """Publish ``count`` hits as fast as possible: (mean us per call, worst us, calls that returned True)."""
    message = hit_message()
    worst = 0
    sent = 0
    start = time.perf_counter_ns()
    for _ in range(count):
        before = time.perf_counter_ns()
        sent += publisher.publish(message)
        worst = max(worst, time.perf_counter_ns() - before)
    total = time.perf_counter_ns() - start
    return total / count / 1000, worst / 1000, sent


def test_a_stalled_subscriber_never_blocks_or_slows_publish(context):
    """Measure, side by side: publishing with only a reading subscriber, then with a stalled one too."""
    count = 20_000
    config = ZmqOutput(endpoints=("tcp://127.0.0.1:*",), send_hwm_messages=100)
    with Publisher(config) as publisher:
        endpoint = publisher.endpoints[0]
        reader = subscriber(context, endpoint, b"hit")
        publish_until_received(publisher, reader, hit_message())
        received = []
        stop = threading.Event()

        def read() -> None:
            while not stop.is_set():
                if reader.poll(50):
                    received.append(reader.recv_multipart())

        thread = threading.Thread(target=read)
        thread.start()
        baseline_us, baseline_worst_us, _ = _publish_burst(publisher, count)

        # A subscriber that never reads, with tiny buffers so its queues fill at once.
        stalled = subscriber(context, endpoint, b"hit", RCVHWM=10, RCVBUF=4096)
        publish_until_received(publisher, stalled, hit_message())
        mean_us, worst_us, sent = _publish_burst(publisher, count)
        time.sleep(0.2)
        # The reading subscriber is still served after the burst: a marker message arrives.
        marker = hit_message(sequence=999_999)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and not any(b'"sequence":999999' in m[1] for m in received):
            publisher.publish(marker)
            time.sleep(0.05)
        stop.set()
        thread.join()
        waiting = 0
        while stalled.poll(0):
            stalled.recv_multipart()
            waiting += 1
        print(
            f"\npublish(): {baseline_us:.1f} us/message ({1e6 / baseline_us:,.0f}/s, worst {baseline_worst_us:.0f} us)"
            f" with a reading subscriber; {mean_us:.1f} us/message ({1e6 / mean_us:,.0f}/s, worst {worst_us:.0f} us)"
            f" with a stalled one too. {sent}/{count} accepted, {publisher.dropped} dropped at hand-over;"
            f" reader got {len(received)}, the stalled subscriber had {waiting} queued of {2 * count}"
        )
    assert any(b'"sequence":999999' in m[1] for m in received)
    assert waiting < count  # its queue overflowed and ZeroMQ dropped its messages instead of waiting


def test_a_late_joiner_gets_the_current_status_before_the_next_periodic_one(context):
    period_s = 2.0
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as publisher:
        publisher.publish_status(status_message(sequence=7))
        # Joining only once status 7 has gone through the proxy: joining while it is on its way,
        # a subscriber may get it twice (docs/protocol.md), which is not what this test is about.
        publisher._lvc.wait_for_statuses(1, timeout_s=5.0)
        early = subscriber(context, publisher.endpoints[0], b"status")
        hits_only = subscriber(context, publisher.endpoints[0], b"hit")
        start = time.perf_counter()
        sequence = 7
        first = None
        while first is None:
            if early.poll(int(period_s * 1000)):
                first = json.loads(early.recv_multipart()[1])
            else:  # the periodic status the late joiner would otherwise have waited for
                sequence += 1
                publisher.publish_status(status_message(sequence=sequence))
        latency_ms = (time.perf_counter() - start) * 1000
        print(f"\nlate joiner: current status after {latency_ms:.2f} ms (status period {period_s} s)")
        assert first["sequence"] == 7

        # A newer status is what the next joiner gets; the earlier joiner sees it again (documented).
        publisher.publish_status(status_message(sequence=8))
        assert early.poll(5000) and json.loads(early.recv_multipart()[1])["sequence"] == 8
        everything = subscriber(context, publisher.endpoints[0])
        assert everything.poll(5000)
        assert json.loads(everything.recv_multipart()[1])["sequence"] == 8
        assert early.poll(5000) and json.loads(early.recv_multipart()[1])["sequence"] == 8
        assert not hits_only.poll(200)


def _proxy_started_late(monkeypatch, delay_s: float) -> None:
    """Make the proxy thread begin ``delay_s`` late, as it does on a starved machine."""
    run_proxy = publisher_module._run_proxy

    def late(*sockets):
        time.sleep(delay_s)
        run_proxy(*sockets)

    monkeypatch.setattr(publisher_module, "_run_proxy", late)


def test_a_status_published_at_once_is_kept_even_when_the_proxy_thread_starts_late(monkeypatch, context):
    """A CI run lost this status: the inlet was a PUB that had not yet heard the proxy's
    subscription, so it dropped the message, and a late joiner got no status at all."""
    _proxy_started_late(monkeypatch, 0.2)
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as publisher:
        publisher.publish_status(status_message(sequence=3))
        late_joiner = subscriber(context, publisher.endpoints[0], b"status")
        assert late_joiner.poll(5000), "the late joiner got no status"
        assert json.loads(late_joiner.recv_multipart()[1])["sequence"] == 3


def test_a_proxy_that_never_starts_is_one_line_and_leaves_nothing_running(monkeypatch):
    threads_before = set(threading.enumerate())
    monkeypatch.setattr(publisher_module, "_WIRING_TIMEOUT_MS", 200)
    _proxy_started_late(monkeypatch, 1.0)
    refused = r"^the publisher's inlet got no subscription from the ZeroMQ proxy within 200 ms$"
    with pytest.raises(PublishError, match=refused):
        Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",)))
    assert set(threading.enumerate()) <= threads_before


def test_bind_errors_are_one_line_and_leave_nothing_running(tmp_path):
    threads_before = set(threading.enumerate())
    holder = socket.socket()
    holder.bind(("127.0.0.1", 0))
    holder.listen()
    port = holder.getsockname()[1]
    with pytest.raises(PublishError, match=rf"cannot bind tcp://127.0.0.1:{port}: Address already in use"):
        Publisher(ZmqOutput(endpoints=(f"tcp://127.0.0.1:{port}",)))
    holder.close()
    with pytest.raises(PublishError, match=r"cannot bind ipc://.*No such file or directory"):
        Publisher(ZmqOutput(endpoints=(f"ipc://{tmp_path}/missing/trackerd.sock",)))
    time.sleep(0.1)
    assert set(threading.enumerate()) <= threads_before


def test_an_ipv6_loopback_endpoint_binds_and_delivers(context):
    # Regression: 'cannot bind tcp://[::1]:...: No such device' (the socket lacked zmq.IPV6).
    with Publisher(ZmqOutput(endpoints=("tcp://[::1]:*", "tcp://127.0.0.1:*"))) as publisher:
        assert publisher.endpoints[0].startswith("tcp://[::1]:")
        sub = subscriber(context, publisher.endpoints[0], b"hit", IPV6=1)
        topic, payload = publish_until_received(publisher, sub, hit_message(3))
        assert topic == b"hit" and json.loads(payload)["sequence"] == 3
        sub.close()


@pytest.mark.parametrize(
    "endpoint",
    [
        "tcp://0.0.0.0:5560",
        "tcp://10.20.30.40:5560",
        "tcp://*:5560",
        "tcp://eth0:5560",
        "tcp://[::]:5560",
        "tcp://wall-host:5560",
    ],
)
def test_network_endpoints_are_refused_without_curve_or_permission(endpoint):
    with pytest.raises(ValidationError, match="reachable from the network"):
        ZmqOutput(endpoints=(endpoint,))
    ZmqOutput(endpoints=(endpoint,), allow_insecure_network=True)
    # The publisher checks again, before binding anything (a config built without validation).
    with pytest.raises(ConfigError, match="reachable from the network"):
        Publisher(ZmqOutput.model_construct(**{**ZmqOutput().__dict__, "endpoints": (endpoint,)}))


@pytest.mark.parametrize(
    "endpoint",
    [
        "tcp://127.0.0.1:5560",
        "tcp://127.8.9.10:1",
        "tcp://localhost:5560",
        "tcp://[::1]:5560",
        "ipc:///run/trackerd/trackerd.sock",
        "tcp://127.0.0.1:*",
    ],
)
def test_local_endpoints_need_nothing(endpoint):
    ZmqOutput(endpoints=(endpoint,))


@pytest.mark.parametrize(
    ("endpoint", "message"),
    [
        ("udp://127.0.0.1:5560", "not a tcp://HOST:PORT"),
        ("tcp://127.0.0.1", "needs HOST:PORT"),
        ("tcp://127.0.0.1:70000", "not a number from 1 to 65535"),
        ("ipc://", "names no path"),
    ],
)
def test_malformed_endpoints(endpoint, message):
    with pytest.raises(ValidationError, match=message):
        ZmqOutput(endpoints=(endpoint,))


def test_a_rig_file_with_an_exposed_endpoint_fails_its_check(tmp_path):
    rig = (Path(__file__).resolve().parents[2] / "config" / "datawall.toml").read_text()
    exposed = rig.replace('endpoints = ["tcp://127.0.0.1:5560"]', 'endpoints = ["tcp://0.0.0.0:5560"]')
    assert exposed != rig
    path = tmp_path / "rig.toml"
    path.write_text(exposed)
    with pytest.raises(ConfigError, match=r"outputs.zmq: tcp://0.0.0.0:5560 is reachable from the network"):
        load_rig(path)


def test_close_is_idempotent_and_stops_every_thread(context):
    threads_before = set(threading.enumerate())
    publisher = Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",)))
    endpoint = publisher.endpoints[0]
    sub = subscriber(context, endpoint, b"status")
    # Once the running status has arrived (the last-value answer, or sent after the subscription
    # got through), the subscriber is connected: the final status must reach it.
    publisher.publish_status(status_message(sequence=1, state="running"))
    assert sub.poll(10_000)
    assert json.loads(sub.recv_multipart()[1])["state"] == "running"
    publisher.publish_status(status_message(sequence=2, state="stopping"))
    publisher.close()
    publisher.close()
    # The final status went out before the socket closed. The running status may come once more
    # before it: the last-value thread answers the subscription with it (docs/protocol.md, "Late
    # joiners": the same status can arrive a second time).
    states = []
    while sub.poll(2000):
        states.append(json.loads(sub.recv_multipart()[1])["state"])
        if states[-1] == "stopping":
            break
    assert states[-1:] == ["stopping"], states
    assert states[:-1] in ([], ["running"]), states
    with pytest.raises(PublishError, match="closed"):
        publisher.publish(hit_message())
    assert set(threading.enumerate()) <= threads_before
    # The port is free again: a restarted daemon binds it at once.
    with Publisher(ZmqOutput(endpoints=(endpoint,))) as again:
        assert again.endpoints == [endpoint]


def test_capture_time_conversion_uses_the_publishers_clock():
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",)), clock=lambda: 5_000_000_000) as publisher:
        converted = publisher.clock_ns_from_monotonic(time.monotonic_ns() - 2_000_000)
    # 2 ms before now, on a clock that says 5 s; the lower bound allows for a slow machine.
    assert 4_500_000_000 < converted <= 4_998_000_000


def test_a_subscriber_of_hits_only_never_sees_status(tcp_publisher, context):
    sub = subscriber(context, tcp_publisher.endpoints[0], b"hit")
    tcp_publisher.publish_status(status_message())
    frames = publish_until_received(tcp_publisher, sub, hit_message())
    assert frames[0] == b"hit"
    for _ in range(20):
        tcp_publisher.publish(hit_message())
    while sub.poll(100):
        assert sub.recv_multipart()[0] == b"hit"
    assert zmq.zmq_version_info() >= (4, 2)


def test_nothing_a_peer_sends_upstream_is_stored_or_published(context):
    """A peer that can connect may send anything upstream: a forged status, a one-frame message.
    Sent on one connection before its own subscription (so that the proxy passes them on in that
    order), none of it becomes the status the late-joiner answer carries, and the publisher goes on."""
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as publisher:
        publisher.publish_status(status_message(sequence=7))
        publisher._lvc.wait_for_statuses(1, timeout_s=5.0)
        listener = subscriber(context, publisher.endpoints[0], b"status")
        assert listener.poll(5000) and json.loads(listener.recv_multipart()[1])["sequence"] == 7
        peer = context.socket(zmq.XSUB)
        peer.setsockopt(zmq.LINGER, 0)
        peer.connect(publisher.endpoints[0])
        forged = json.dumps({**json.loads(status_message(sequence=666).model_dump_json()), "state": "FORGED"})
        peer.send_multipart([b"status", forged.encode()])
        peer.send(b"status")  # one frame, neither a subscription nor a message
        peer.send(b"\x01status")
        assert peer.poll(5000)
        answer = peer.recv_multipart()
        assert len(answer) == 2 and json.loads(answer[1])["sequence"] == 7
        # The subscriber already there got nothing of it (status 7 again at most: the answer to a
        # joiner reaches every status subscriber, docs/protocol.md), and the next real status reaches both.
        publisher.publish_status(status_message(sequence=8))
        for sock in (listener, peer):
            seen = []
            while not seen or seen[-1]["sequence"] != 8:
                assert sock.poll(5000), seen
                parts = sock.recv_multipart()
                assert len(parts) == 2
                seen.append(json.loads(parts[1]))
            assert {status["sequence"] for status in seen} <= {7, 8} and all(s["state"] != "FORGED" for s in seen)
        late = subscriber(context, publisher.endpoints[0], b"status")
        assert late.poll(5000) and json.loads(late.recv_multipart()[1])["sequence"] == 8
        peer.close()


def test_a_subscription_flood_does_not_flood_the_other_subscribers(context):
    """A peer sending status subscriptions in a loop: each used to be answered with the last status,
    which reaches every status subscriber (a PUB cannot address one), so the others received thousands
    of statuses a second. Answers are at most one per ANSWER_INTERVAL_S; joiners are still answered."""
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as publisher:
        publisher.publish_status(status_message(sequence=3))
        publisher._lvc.wait_for_statuses(1, timeout_s=5.0)
        listener = subscriber(context, publisher.endpoints[0], b"status")
        assert listener.poll(5000) and json.loads(listener.recv_multipart()[1])["sequence"] == 3
        flood = context.socket(zmq.XSUB)
        flood.setsockopt(zmq.LINGER, 0)
        flood.setsockopt(zmq.SNDHWM, 0)
        flood.connect(publisher.endpoints[0])
        started = time.monotonic()
        for _ in range(200):
            for _ in range(1000):
                flood.send(b"\x01status")
            # A new subscriber in the middle of the flood is answered all the same.
        joiner = subscriber(context, publisher.endpoints[0], b"status")
        assert joiner.poll(10_000) and json.loads(joiner.recv_multipart()[1])["sequence"] == 3
        # Until the flood has all arrived (the peer's queue is empty once the proxy has taken it).
        publisher.publish_status(status_message(sequence=4))
        seen = []
        while not seen or seen[-1] != 4:
            assert listener.poll(10_000), len(seen)
            seen.append(json.loads(listener.recv_multipart()[1])["sequence"])
        elapsed = time.monotonic() - started
        repeats = seen.count(3)
        # At most one answer per interval while it lasted (a slower machine answers fewer, never more).
        assert repeats <= elapsed / publisher_module.ANSWER_INTERVAL_S + 2, (repeats, elapsed)
        flood.close()
        late = subscriber(context, publisher.endpoints[0], b"status")
        assert late.poll(5000) and json.loads(late.recv_multipart()[1])["sequence"] == 4
