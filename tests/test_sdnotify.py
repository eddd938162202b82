"""sd_notify (trackerd/sdnotify.py) against a stand-in for systemd: a datagram socket of the test's own."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from trackerd.sdnotify import SdNotify


@pytest.fixture
def notify_socket(tmp_path: Path):
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    path = tmp_path / "notify"
    sock.bind(str(path))
    sock.settimeout(2.0)
    yield str(path), sock
    sock.close()


def _drain(sock: socket.socket) -> list[str]:
    out = []
    sock.settimeout(0.2)
    try:
        while True:
            out.append(sock.recv(4096).decode())
    except TimeoutError:
        return out


def test_ready_status_watchdog_reloading_stopping_arrive_in_order(notify_socket):
    path, sock = notify_socket
    with SdNotify({"NOTIFY_SOCKET": path}) as notifier:
        assert notifier.enabled
        assert notifier.ready("2 cameras streaming")
        assert notifier.status("running: 60.0 pairs/s")
        assert notifier.watchdog()
        assert notifier.reloading()
        assert notifier.stopping()
    received = _drain(sock)
    assert received[0] == "READY=1\nSTATUS=2 cameras streaming"
    assert received[1] == "STATUS=running: 60.0 pairs/s"
    assert received[2] == "WATCHDOG=1"
    assert received[3].startswith("RELOADING=1\nMONOTONIC_USEC=")
    assert received[4] == "STOPPING=1"


def test_no_status_line_is_sent_after_stopping(notify_socket):
    # The publishing thread may report the pair in hand after SIGTERM's handler said STOPPING=1:
    # systemctl status must keep showing the stop, not "running".
    path, sock = notify_socket
    with SdNotify({"NOTIFY_SOCKET": path}) as notifier:
        assert notifier.status("running: 60.0 pairs/s")
        assert notifier.stopping("stopping")
        assert not notifier.status("running: 59.8 pairs/s")
        assert notifier.watchdog()
    assert _drain(sock) == ["STATUS=running: 60.0 pairs/s", "STOPPING=1\nSTATUS=stopping", "WATCHDOG=1"]


def test_abstract_namespace_socket(notify_socket):
    name = f"trackerd-test-{os.getpid()}"
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(b"\0" + name.encode())
    sock.settimeout(2.0)
    with SdNotify({"NOTIFY_SOCKET": "@" + name}) as notifier:
        notifier.ready()
    assert sock.recv(4096) == b"READY=1"
    sock.close()


def test_no_notify_socket_means_no_op():
    notifier = SdNotify({})
    assert not notifier.enabled
    assert notifier.ready() is False and notifier.watchdog() is False and notifier.stopping() is False
    assert notifier.watchdog_interval_s() is None


def test_watchdog_interval_respects_watchdog_pid():
    assert SdNotify({"WATCHDOG_USEC": "10000000"}).watchdog_interval_s() == 10.0
    assert SdNotify({"WATCHDOG_USEC": "10000000", "WATCHDOG_PID": str(os.getpid())}).watchdog_interval_s() == 10.0
    assert SdNotify({"WATCHDOG_USEC": "10000000", "WATCHDOG_PID": "1"}).watchdog_interval_s() is None
    assert SdNotify({"WATCHDOG_USEC": "0"}).watchdog_interval_s() is None
    assert SdNotify({"WATCHDOG_USEC": "soon"}).watchdog_interval_s() is None


def test_progress_feeds_the_watchdog_at_most_every_quarter_interval(notify_socket):
    """Judged call by call from each call's start and end time, so a stalled test machine cannot
    make it fail: a ping is sent once a quarter interval has passed since the last, never sooner."""
    path, sock = notify_socket
    quarter_s = 0.1
    notifier = SdNotify({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "400000"})  # 0.4 s: a ping per 0.1 s
    calls: list[tuple[float, float, bool]] = []
    pings = 0
    deadline = time.monotonic() + 10.0
    while pings < 4 and time.monotonic() < deadline:
        before = time.monotonic()
        sent = notifier.progress()  # "a pair was processed", about 1000 times a second
        calls.append((before, time.monotonic(), sent))
        pings += sent
        time.sleep(0.001)
    assert _drain(sock) == ["WATCHDOG=1"] * pings == ["WATCHDOG=1"] * 4
    last_ping: tuple[float, float] | None = None  # (start, end) of the call that last sent
    for before, after, sent in calls:
        if last_ping is not None and sent:
            assert after - last_ping[0] >= quarter_s  # never sooner than a quarter interval...
        elif last_ping is not None:
            assert before - last_ping[1] < quarter_s  # ...and a call that sent nothing was too soon
        if sent:
            last_ping = (before, after)
    # Without progress, nothing is sent: the watchdog only sees real work.
    time.sleep(0.15)
    assert _drain(sock) == []
    notifier.close()


def test_a_vanished_systemd_is_survived(tmp_path):
    notifier = SdNotify({"NOTIFY_SOCKET": str(tmp_path / "gone")})
    assert notifier.ready() is False
    assert notifier.watchdog() is False
    notifier.close()


def test_a_child_process_notifies_like_the_daemon_will(notify_socket):
    """The variables systemd sets, in a real separate process: READY, then WATCHDOG, then STOPPING."""
    path, sock = notify_socket
    code = (
        "from trackerd.sdnotify import SdNotify\n"
        "n = SdNotify()\n"
        "n.ready('streaming')\n"
        "assert n.watchdog_interval_s() == 2.0\n"
        "n.progress()\n"
        "n.stopping()\n"
    )
    env = {**os.environ, "NOTIFY_SOCKET": path, "WATCHDOG_USEC": "2000000"}
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=30)
    assert _drain(sock) == ["READY=1\nSTATUS=streaming", "WATCHDOG=1", "STOPPING=1"]
