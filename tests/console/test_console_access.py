"""The console in process, on a pipeline fed from memory: the token, the cost rule (nothing
handed over while nobody watches), a viewer's images, and the one-line errors of --console."""

from __future__ import annotations

import asyncio
import json
import socket
import struct
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

from trackerd.acquisition.memory import MemoryPairSource
from trackerd.config.console import ConsoleConfig
from trackerd.config.loader import with_console
from trackerd.console.server import ConsoleServer
from trackerd.errors import ConfigError
from trackerd.pipeline.daemon import Pipeline
from trackerd.pipeline.tap import ConsoleTap
from trackerd.publish import Publisher

pytestmark = pytest.mark.serial  # runs daemons with their consoles


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def console(simulated_rig, tmp_path):
    """A pipeline on dark frames (nothing to find: fast) with its console, token required."""
    (tmp_path / "token").write_text("s3cret-token\n")
    listen = f"127.0.0.1:{_free_port()}"
    zmq_cfg = simulated_rig.outputs.zmq.model_copy(update={"endpoints": (f"ipc://{tmp_path}/pub.sock",)})
    rig = simulated_rig.model_copy(
        update={
            "outputs": simulated_rig.outputs.model_copy(update={"zmq": zmq_cfg}),
            "console": ConsoleConfig(
                listen=listen, token_file=tmp_path / "token", snapshot_directory=tmp_path / "snaps"
            ),
        }
    )
    frames = [[np.full((c.height_px, c.width_px), 20, np.uint8) for c in rig.cameras]]
    tap = ConsoleTap()
    pipeline = Pipeline(
        rig, lambda r: MemoryPairSource(r, frames, rate_hz=30.0), lambda r: Publisher(r.outputs.zmq), tap=tap
    )
    pipeline.start()
    server = ConsoleServer(pipeline, tap)
    server.start()
    try:
        yield server, pipeline, f"http://{listen}"
    finally:
        server.stop()
        pipeline.stop()


def _get(url: str, headers: dict[str, str] | None = None) -> tuple[int, bytes, dict[str, str]]:
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.read(), dict(response.headers)
    except urllib.error.HTTPError as err:
        return err.code, err.read(), dict(err.headers)


def _wait(condition, timeout_s: float = 30.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.02)
    return condition()


def test_every_path_needs_the_token(console) -> None:
    _server, _pipeline, base = console
    for path in ("/", "/metrics", "/healthz", "/api/info"):
        code, body, _ = _get(base + path)
        assert code == 401 and "token" in json.loads(body)["error"], path
    code, _, _ = _get(base + "/api/info", {"Authorization": "Bearer wrong"})
    assert code == 401
    code, body, _ = _get(base + "/api/info", {"Authorization": "Bearer s3cret-token"})
    assert code == 200 and json.loads(body)["cameras"][0]["id"] == "left"
    code, _, headers = _get(base + "/?token=s3cret-token")
    assert code == 200 and "trackerd_console_token=s3cret-token" in headers["Set-Cookie"]
    assert "HttpOnly" in headers["Set-Cookie"] and "SameSite=Strict" in headers["Set-Cookie"]


def test_a_client_without_the_token_is_told_so_not_that_no_daemon_answers(console) -> None:
    """`trackerd ctl` with a rig that gives no token (or another one) said "no trackerd daemon's console
    answers" of a console that had answered 401."""
    from trackerd.console.client import ConsoleClient, ConsoleError

    _server, _pipeline, base = console
    listen = base.removeprefix("http://")
    assert ConsoleClient(listen, "s3cret-token").find() is not None
    for token, says in ((None, "this rig gives none"), ("wrong", "this rig gives a different token")):
        with pytest.raises(ConsoleError) as refused:
            ConsoleClient(listen, token).find()
        assert refused.value.status == 401 and "wants its token" in str(refused.value) and says in str(refused.value)
    assert ConsoleClient(f"127.0.0.1:{_free_port()}").find() is None  # nothing listening: no daemon


def test_a_malformed_request_is_answered_400_and_logged_as_one_debug_line(console, caplog) -> None:
    """A URL or a header line over aiohttp's 8190 bytes: aiohttp answered 400 and logged an ERROR with its
    traceback, which anyone reaching the port could repeat into the journal."""
    import logging

    _server, _pipeline, base = console
    caplog.set_level(logging.DEBUG)
    code, _, _ = _get(base + "/api/info?" + "a" * 9000)
    assert code == 400
    code, _, _ = _get(base + "/api/info", {"X-Long": "b" * 9000})
    assert code in (400, 431)
    assert _wait(lambda: sum("refused a malformed request" in r.getMessage() for r in caplog.records) >= 2)
    assert not [r for r in caplog.records if r.name.startswith("aiohttp") and r.levelno >= logging.WARNING]


def test_every_error_answers_with_a_json_object(console) -> None:
    """docs/console.md: errors answer {"error": ...} with a 4xx status. aiohttp's own 404 and 405 were text
    pages, and a check asked for an impossible number of fixes answered 409 (a conflict) instead of 400."""
    _server, _pipeline, base = console
    bearer = {"Authorization": "Bearer s3cret-token", "X-Trackerd-Console": "1"}
    code, body, _ = _get(base + "/api/nope", bearer)
    assert code == 404 and json.loads(body) == {"error": "Not Found"}
    code, body, headers = _get(base + "/api/snapshot", bearer)  # POST only
    assert code == 405 and json.loads(body) == {"error": "Method Not Allowed"} and "POST" in headers["Allow"]
    for fixes in ("-5", "0", "19", "99999999"):  # 19: fewer than a verdict needs (a new user's audit)
        request = urllib.request.Request(base + f"/api/check?fixes={fixes}", method="POST", data=b"", headers=bearer)
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(request, timeout=10)
        assert refused.value.code == 400 and json.loads(refused.value.read()) == {
            "error": "fixes must be from 20 to 5000"
        }


def test_what_another_site_could_make_a_browser_send_is_refused(console) -> None:
    import aiohttp

    _server, _pipeline, base = console
    bearer = {"Authorization": "Bearer s3cret-token"}
    request = urllib.request.Request(base + "/api/recording/start", method="POST", data=b"", headers=bearer)
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request, timeout=10)
    assert refused.value.code == 403 and "X-Trackerd-Console" in json.loads(refused.value.read())["error"]
    request.add_header("X-Trackerd-Console", "1")
    with pytest.raises(urllib.error.HTTPError) as unavailable:  # through, and answered: no [recording] here
        urllib.request.urlopen(request, timeout=10)
    assert unavailable.value.code == 409 and "[recording] directory" in json.loads(unavailable.value.read())["message"]

    async def connect(origin: str) -> int:
        async with aiohttp.ClientSession(headers=bearer) as session:
            try:
                async with session.ws_connect(base + "/ws", origin=origin):
                    return 101
            except aiohttp.WSServerHandshakeError as err:
                return err.status

    assert asyncio.run(connect("http://evil.example")) == 403
    assert asyncio.run(connect(base)) == 101


def test_nothing_is_handed_over_until_a_page_watches_and_images_then_come(console) -> None:
    import aiohttp

    server, pipeline, base = console
    assert _wait(lambda: pipeline.pairs_processed >= 30)
    assert server.tap.offered == 0 and not server.tap.frame_wanted and not server.tap.messages_wanted

    async def watch() -> list[dict]:
        headers = {"Authorization": "Bearer s3cret-token"}
        headers_seen = []
        async with aiohttp.ClientSession(headers=headers) as session, session.ws_connect(base + "/ws") as ws:
            while len(headers_seen) < 4:
                message = await ws.receive(timeout=30)
                if message.type == aiohttp.WSMsgType.BINARY:
                    (length,) = struct.unpack(">I", message.data[:4])
                    header = json.loads(message.data[4 : 4 + length])
                    assert message.data[4 + length : 4 + length + 2] == b"\xff\xd8"  # a JPEG
                    headers_seen.append(header)
        return headers_seen

    seen = asyncio.run(watch())
    assert {h["camera"] for h in seen} == {"left", "right"}
    assert all(h["image_width_px"] == 640 and h["ends"]["red"]["found"] is False for h in seen)
    assert all(h["ends"]["red"]["reason"] for h in seen)  # why the end was not found
    assert len(seen[0]["outline_px"][0]) > 4 and len(seen[0]["corners_px"]) == 4
    # The page is gone: the pipeline stops handing anything over.
    assert _wait(lambda: not server.tap.messages_wanted)
    assert _wait(lambda: server.frames.viewers == 0)
    count = server.tap.offered
    processed = pipeline.pairs_processed
    assert _wait(lambda: pipeline.pairs_processed >= processed + 30)
    assert server.tap.offered <= count + 1  # at most the one asked for as the page left


def test_console_addresses_are_checked_in_one_line(simulated_rig) -> None:
    with pytest.raises(ConfigError, match=r"^--console: .*0\.0\.0\.0:8560.*token_file"):
        with_console(simulated_rig, "0.0.0.0:8560")
    with pytest.raises(ConfigError, match=r"^--console: .*not HOST:PORT"):
        with_console(simulated_rig, "8560")
    with pytest.raises(ConfigError, match=r"^--console: .*port must be a number from 1 to 65535"):
        with_console(simulated_rig, "127.0.0.1:70000")
    assert with_console(simulated_rig, "off").console.enabled is False
    moved = with_console(simulated_rig, "127.0.0.1:9000").console
    assert moved.listen == "127.0.0.1:9000" and "listen" in moved.model_fields_set
    assert "listen" not in simulated_rig.console.model_fields_set


def test_snapshots_by_hand_go_to_a_folder_of_the_users_own(tmp_path, monkeypatch) -> None:
    """Without systemd's state directory the console's snapshots went to /tmp/trackerd-snapshots, one name
    for every user (0755: each saw the others'), which anyone could make first, or make a link by that
    name to where root's snapshots would then be written."""
    import os

    from trackerd.console.frames import own_directory
    from trackerd.console.server import default_snapshot_directory

    monkeypatch.delenv("STATE_DIRECTORY", raising=False)
    assert default_snapshot_directory().name == f"trackerd-snapshots-{os.getuid()}"
    fresh = tmp_path / "mine" / "snaps"
    own_directory(fresh)
    assert fresh.is_dir() and (fresh.stat().st_mode & 0o777) == 0o700
    own_directory(fresh)  # again: it is ours
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(PermissionError, match="not a folder of this user's"):
        own_directory(tmp_path / "link")
    if os.getuid() == 0:
        (tmp_path / "theirs").mkdir()
        os.chown(tmp_path / "theirs", 65534, 65534)
        with pytest.raises(PermissionError, match="not a folder of this user's"):
            own_directory(tmp_path / "theirs")


def test_a_token_every_user_can_read_is_warned_about(tmp_path) -> None:
    from trackerd.console.access import token_exposed

    token = tmp_path / "token"
    token.write_text("s3cret-token\n")
    token.chmod(0o644)
    assert (
        token_exposed(token)
        == f"{token}: the console token is readable by every user of this host (mode 0644); chmod o-r it"
    )
    token.chmod(0o640)
    assert token_exposed(token) is None


def test_a_token_that_is_not_utf8_is_refused_as_any_wrong_token(console) -> None:
    """A new user's audit: one byte that is not UTF-8 in the bearer token or the cookie answered 500 and
    logged a traceback at ERROR (shown in the page's warnings) for anyone who sent it."""
    _server, _pipeline, base = console
    for headers in ({"Authorization": "Bearer p\xe4"}, {"Cookie": "trackerd_console_token=\xe4\xe4"}):
        code, body, _ = _get(base + "/api/info", headers)  # urllib sends the header's text as Latin-1 bytes
        assert code == 401 and "needs its token" in json.loads(body)["error"], (code, body)


def test_ctl_snap_into_a_place_it_cannot_write_says_so_before_the_daemon_takes_one(console, tmp_path) -> None:
    """A new user's audit: `ctl snap OUT` asked the daemon for the snapshot first and then met OUT (a file, a
    full disk) with a traceback, leaving the snapshot on the daemon's host."""
    from trackerd.console.client import ConsoleClient
    from trackerd.errors import RecordingError

    _server, _pipeline, base = console
    client = ConsoleClient(base.removeprefix("http://"), "s3cret-token")
    a_file = tmp_path / "afile"
    a_file.write_text("not a folder\n")
    with pytest.raises(RecordingError, match="exists and is not a folder"):
        client.snapshot_into(a_file)
    assert not (tmp_path / "snaps").exists() or not any((tmp_path / "snaps").iterdir())


def test_the_console_client_names_what_is_not_a_console(tmp_path) -> None:
    """A new user's audit: `ctl --console` given the rig's ZeroMQ port, or anything that answers HTTP with other
    than the console's JSON, ended in a traceback (BadStatusLine, LineTooLong, JSONDecodeError)."""
    import http.server
    import threading

    from trackerd.console.client import ConsoleClient, ConsoleError

    class NotJson(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self.send_response(200)
            self.end_headers()
            self.wfile.write(b"<html>another web server</html>")

        def log_message(self, *_args) -> None:
            pass

    web = http.server.HTTPServer(("127.0.0.1", 0), NotJson)
    garbage = socket.socket()
    garbage.bind(("127.0.0.1", 0))
    garbage.listen()

    def answer_garbage() -> None:
        connection, _ = garbage.accept()
        request = b""
        while b"\r\n\r\n" not in request:  # all of it read: closing with bytes unread would send a reset
            chunk = connection.recv(4096)
            if not chunk:
                break
            request += chunk
        connection.sendall(b"\xff\x00\x01 not HTTP at all\r\n\r\n")
        connection.close()

    threads = [threading.Thread(target=web.handle_request), threading.Thread(target=answer_garbage)]
    for thread in threads:
        thread.start()
    try:
        for listen in (f"127.0.0.1:{web.server_address[1]}", f"127.0.0.1:{garbage.getsockname()[1]}"):
            client = ConsoleClient(listen)
            # find() too (what ctl and snap ask first): not "no daemon answers", which sends a user looking
            # for a stopped daemon.
            with pytest.raises(ConsoleError, match="answers, but not as a trackerd console"):
                client.find()
    finally:
        for thread in threads:
            thread.join(10)
        web.server_close()
        garbage.close()


def test_a_token_file_of_other_than_printable_ascii_is_refused_in_one_line(tmp_path) -> None:
    """A new user's audit: a token file of random bytes was read with replacement characters and accepted;
    `trackerd ctl` then failed with a traceback encoding it (a header carries Latin-1), and a UTF-8 token
    was sent as other bytes than the console compared."""
    from trackerd.console.access import read_token

    for content in ("pässwort\n".encode(), bytes(range(128, 160)), b"two words\n"):
        path = tmp_path / "token"
        path.write_bytes(content)
        with pytest.raises(ConfigError, match="the console token must be printable ASCII"):
            read_token(path)
    path.write_bytes(b"  0123abcd-token \nsecond line ignored\n")
    assert read_token(path) == "0123abcd-token"


def test_listen_given_the_console_port_says_it_is_not_a_publisher(console) -> None:
    """A new user's audit: `trackerd listen --endpoint` given the console's address printed the console's HTTP
    error page as messages (and, with --json, lines that are not JSON) and exited 0: ZeroMQ took the HTTP
    answer for an old-protocol peer's messages."""
    import subprocess
    import sys

    _server, _pipeline, base = console
    endpoint = "tcp://" + base.removeprefix("http://")
    for extra in ((), ("--json",)):
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "trackerd",
                "listen",
                "--endpoint",
                endpoint,
                "--timeout",
                "10",
                "--count",
                "3",
                *extra,
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert run.returncode == 1 and "Traceback" not in run.stderr, (run.returncode, run.stderr)
        assert f"{endpoint} sends messages that are not trackerd's" in run.stderr, run.stderr
        assert run.stdout == "", run.stdout
