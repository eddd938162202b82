"""`trackerd listen` in a subprocess against a real publisher."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time

import pytest

from tests.publish.conftest import hit_message, pointer_message, status_message
from trackerd.cli.listen import format_message
from trackerd.config.models import ZmqOutput
from trackerd.publish import Publisher


def _listen(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "trackerd", "listen", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _serve_until_done(publisher: Publisher, process: subprocess.Popen, messages, timeout_s: float = 20.0) -> None:
    """Publish the messages in turn every 20 ms until the listener exits."""
    deadline = time.monotonic() + timeout_s
    index = 0
    while process.poll() is None and time.monotonic() < deadline:
        message = messages[index % len(messages)]
        if message.topic == "status":
            publisher.publish_status(message)
        else:
            publisher.publish(message)
        index += 1
        time.sleep(0.02)


@pytest.fixture
def publisher():
    with Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",))) as pub:
        yield pub


def test_listen_count_prints_readable_lines_and_exits_0(publisher):
    process = _listen("--endpoint", publisher.endpoints[0], "--count", "4", "--topic", "hit", "--topic", "status")
    _serve_until_done(publisher, process, [hit_message(1234), pointer_message(1234), status_message(9)])
    out, err = process.communicate(timeout=10)
    assert process.returncode == 0, err
    lines = out.splitlines()
    assert len(lines) == 4
    assert all(line.split()[0] in ("hit", "status") for line in lines)
    hit = next(line for line in lines if line.startswith("hit"))
    assert hit == "hit      #1234  x 1.234 m  y 0.567 m  (2951, 733 px)  on wall  +-1.8 mm  gap 0.9 mm"


def test_listen_json_prints_one_payload_per_line(publisher):
    process = _listen("--endpoint", publisher.endpoints[0], "--count", "3", "--json", "--topic", "pointer")
    _serve_until_done(publisher, process, [hit_message(), pointer_message(77)])
    out, err = process.communicate(timeout=10)
    assert process.returncode == 0, err
    payloads = [json.loads(line) for line in out.splitlines()]
    assert len(payloads) == 3
    assert {p["topic"] for p in payloads} == {"pointer"} and payloads[0]["sequence"] == 77


def test_listen_timeout_exits_1_with_one_clear_line():
    process = _listen("--endpoint", "tcp://127.0.0.1:9", "--timeout", "0.5")
    out, err = process.communicate(timeout=20)
    assert process.returncode == 1
    assert out == ""
    assert err.splitlines() == [
        "trackerd listen: listening to tcp://127.0.0.1:9 for all topics; Ctrl-C to stop",
        "trackerd listen: no message from tcp://127.0.0.1:9 within 0.5 s (is trackerd running"
        " there, publishing these topics, with matching CURVE keys?)",
    ]


def _stderr_lines_until(process: subprocess.Popen, wanted: str, guard_s: float = 60.0) -> list[str]:
    """Lines of the process's stderr up to the first containing ``wanted``. The guard only keeps a
    broken listener from hanging the test: a reader thread waits on the pipe, not on a clock."""
    lines: list[str] = []
    found = threading.Event()

    def read() -> None:
        for line in process.stderr:
            lines.append(line.rstrip("\n"))
            if wanted in line:
                found.set()
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    found.wait(guard_s)
    assert found.is_set(), f"no {wanted!r} on stderr within {guard_s:g} s: {lines}"
    return lines


def test_listen_says_what_it_waits_for_and_what_to_check_when_nothing_comes():
    # Regression (issue 15): with no daemon, `trackerd listen` waited for ever in silence.
    endpoint = "tcp://127.0.0.1:9"  # the discard port: nobody binds it
    process = _listen("--endpoint", endpoint, "--topic", "hit", "--topic", "status")
    try:
        lines = _stderr_lines_until(process, "nothing from")
    finally:
        process.terminate()
        out, rest = process.communicate(timeout=10)
    assert lines[0] == f"trackerd listen: listening to {endpoint} for hit, status; Ctrl-C to stop"
    hint = lines[1]
    assert hint.startswith(
        f"trackerd listen: nothing from {endpoint} in 5 s, though a running trackerd publishes a status every 1 s:"
    ), hint
    assert f"is {endpoint} the endpoint in the rig's [outputs.zmq]?" in hint
    assert "systemctl status trackerd" in hint and "--server-key" in hint
    assert len(lines) == 2 and rest == ""
    assert out == ""


def test_listen_hears_the_heartbeat_of_a_daemon_with_nothing_on_the_topics_asked_for(publisher):
    # Statuses only, and `--topic hit`: the daemon is there (no hint), nobody points (no line).
    process = _listen("--endpoint", publisher.endpoints[0], "--topic", "hit", "--timeout", "6")
    _serve_until_done(publisher, process, [status_message(9)], timeout_s=60)
    exited_while_served = process.poll() is not None  # statuses every 20 ms must not hide --timeout
    out, err = process.communicate(timeout=10)
    assert exited_while_served
    assert process.returncode == 1 and out == ""
    lines = err.splitlines()
    assert lines[0] == f"trackerd listen: listening to {publisher.endpoints[0]} for hit; Ctrl-C to stop"
    assert lines[1].startswith(f"trackerd listen: no message from {publisher.endpoints[0]} within 6 s")
    assert len(lines) == 2, err


def test_listen_refuses_a_topic_trackerd_never_publishes():
    # Regression: --topic hits (for hit) subscribed to nothing and waited in silence.
    process = _listen("--endpoint", "tcp://127.0.0.1:9", "--topic", "hits", "--timeout", "0.5")
    out, err = process.communicate(timeout=20)
    assert process.returncode == 2 and out == ""
    assert err.startswith("trackerd listen: --topic hits: trackerd publishes no such topic; topics: hit, pointer,")
    assert len(err.splitlines()) == 1


@pytest.mark.parametrize("endpoint", ["tcp://127.0.0.1:99999", "tcp://127.0.0.1:*", "tcp://127.0.0.1"])
def test_listen_refuses_an_endpoint_it_cannot_connect_to(endpoint):
    # ZeroMQ took tcp://127.0.0.1:99999 and the command waited until its timeout.
    process = _listen("--endpoint", endpoint, "--timeout", "30")
    out, err = process.communicate(timeout=20)
    assert process.returncode == 2 and out == ""
    assert err == f"trackerd listen: --endpoint {endpoint}: connect to tcp://HOST:PORT, PORT a number from 1 to 65535\n"


def test_listen_names_a_key_file_that_is_missing_or_not_a_key(tmp_path):
    # Regression: a missing --server-key said "cannot read CURVE key file: None".
    not_a_key = tmp_path / "server.key"
    not_a_key.write_text("hello\n")
    for path, reason in ((tmp_path / "gone.key", "no such CURVE key file"), (not_a_key, "not a CURVE key file")):
        process = _listen("--endpoint", "tcp://127.0.0.1:9", "--server-key", str(path), "--timeout", "0.5")
        out, err = process.communicate(timeout=20)
        assert process.returncode == 2 and out == ""
        assert err.startswith(f"trackerd listen: {path}: {reason}") and len(err.splitlines()) == 1, err


def test_listen_over_ipv6_loopback():
    with Publisher(ZmqOutput(endpoints=("tcp://[::1]:*",))) as publisher:
        process = _listen("--endpoint", publisher.endpoints[0], "--count", "1", "--topic", "hit")
        _serve_until_done(publisher, process, [hit_message(5)])
        out, err = process.communicate(timeout=10)
    assert process.returncode == 0, err
    assert out.startswith("hit      #5 ")


def test_listen_exits_0_on_ctrl_c(publisher):
    process = _listen("--endpoint", publisher.endpoints[0])
    stop = threading.Event()
    feeder = threading.Thread(
        target=lambda: [publisher.publish(hit_message()) or time.sleep(0.02) for _ in iter(lambda: stop.is_set(), True)]
    )
    feeder.start()
    first = process.stdout.readline()
    stop.set()
    feeder.join()
    process.send_signal(signal.SIGINT)
    process.communicate(timeout=10)
    assert first.startswith("hit")
    assert process.returncode == 0


def test_listen_reads_endpoint_and_server_key_from_the_rig(tmp_path):
    from trackerd.cli.keys import write_key_pair

    write_key_pair(tmp_path, "server", "server")
    rig = (__import__("pathlib").Path(__file__).resolve().parents[2] / "config" / "datawall.toml").read_text()
    with Publisher(
        ZmqOutput(endpoints=("tcp://127.0.0.1:*",), curve_secret_key_file=tmp_path / "server.key_secret")
    ) as pub:
        port = pub.endpoints[0].rsplit(":", 1)[1]
        text = rig.replace(
            'endpoints = ["tcp://127.0.0.1:5560"]',
            f'endpoints = ["tcp://*:{port}"]\ncurve_secret_key_file = "{tmp_path}/server.key_secret"',
        )
        assert text != rig
        (tmp_path / "rig.toml").write_text(text)
        process = _listen("--config", str(tmp_path / "rig.toml"), "--count", "1")
        _serve_until_done(pub, process, [hit_message(5)])
        out, err = process.communicate(timeout=10)
    assert process.returncode == 0, err
    assert out.startswith("hit      #5")


def test_format_tolerates_unknown_topics_and_missing_fields():
    assert format_message("gesture", {"sequence": 3, "topic": "gesture", "kind": "swipe"}) == (
        'gesture  #3  {"kind":"swipe"}'
    )
    line = format_message("hit", {"sequence": 1, "wall_x_m": 1.0, "on_wall": False, "extra": 1})
    assert line == "hit      #1  x 1.000 m  y ?  off wall  gap ?"
    status = format_message("status", json.loads(status_message().model_dump_json()))
    assert "right lost 0.0 Hz drops 3" in status and "latency p50 8.1 p99 12.0 ms" in status


def test_a_status_detail_that_repeats_the_state_is_not_printed_twice():
    stopping = json.loads(status_message(state="stopping").model_dump_json())
    assert format_message("status", {**stopping, "detail": "stopping"}).count("stopping") == 1
    assert format_message("status", {**stopping, "detail": "right: lost"}).endswith("(right: lost)")
