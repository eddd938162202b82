"""CURVE: encryption and authentication with keys from `trackerd keys`, over real TCP on loopback."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zmq
import zmq.auth

from tests.publish.conftest import hit_message, publish_until_received, subscriber
from trackerd.cli.keys import write_key_pair
from trackerd.config.models import ZmqOutput
from trackerd.errors import ConfigError
from trackerd.publish import Publisher

pytestmark = pytest.mark.skipif(not zmq.has("curve"), reason="libzmq without CURVE")


def _curve_subscriber(context, endpoint: str, server_public: bytes, client_pair=None) -> zmq.Socket:
    public, secret = client_pair or zmq.curve_keypair()
    sub = context.socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    sub.curve_serverkey = server_public
    sub.curve_publickey = public
    sub.curve_secretkey = secret
    sub.subscribe(b"hit")
    sub.connect(endpoint)
    return sub


def _received_during(publisher: Publisher, subs: list[zmq.Socket], seconds: float) -> list[int]:
    """Publish a hit every 10 ms for ``seconds`` and count what each subscriber gets."""
    counts = [0] * len(subs)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        publisher.publish(hit_message())
        time.sleep(0.01)
        for index, sub in enumerate(subs):
            while sub.poll(0):
                sub.recv_multipart()
                counts[index] += 1
    return counts


@pytest.fixture
def server_keys(tmp_path: Path) -> tuple[Path, bytes]:
    _, secret_file = write_key_pair(tmp_path, "server", "server")
    public, _ = zmq.auth.load_certificate(str(secret_file))
    return secret_file, public


def test_right_server_key_receives_a_wrong_one_gets_nothing(server_keys, context):
    secret_file, public = server_keys
    config = ZmqOutput(endpoints=("tcp://127.0.0.1:*",), curve_secret_key_file=secret_file)
    with Publisher(config) as publisher:
        endpoint = publisher.endpoints[0]
        right = _curve_subscriber(context, endpoint, public)
        wrong = _curve_subscriber(context, endpoint, zmq.curve_keypair()[0])
        plain = subscriber(context, endpoint, b"hit")  # no CURVE at all
        # The right client's handshake is done once a message reaches it (however slow the machine);
        # the others had that long and the window below to get anything.
        publish_until_received(publisher, right, hit_message(), timeout_s=10.0)
        counts = _received_during(publisher, [right, wrong, plain], 0.6)
        # The daemon carried on: the right client still receives after the failed handshakes.
        later = _received_during(publisher, [right], 0.3)
    print(f"\nCURVE: right key {counts[0]} + {later[0]} messages, wrong key {counts[1]}, no CURVE {counts[2]}")
    assert counts[0] > 0 and later[0] > 0
    assert counts[1] == 0 and counts[2] == 0


def test_only_authorized_clients_may_subscribe_and_reload_reads_new_keys(server_keys, tmp_path, context):
    secret_file, public = server_keys
    clients = tmp_path / "clients"
    clients.mkdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    _, known_secret = write_key_pair(clients, "wall-app", "client")
    stranger_public, stranger_secret = write_key_pair(elsewhere, "stranger", "client")
    config = ZmqOutput(
        endpoints=("tcp://127.0.0.1:*",), curve_secret_key_file=secret_file, curve_authorized_keys_dir=clients
    )
    with Publisher(config) as publisher:
        endpoint = publisher.endpoints[0]
        known = _curve_subscriber(context, endpoint, public, zmq.auth.load_certificate(str(known_secret)))
        stranger = _curve_subscriber(context, endpoint, public, zmq.auth.load_certificate(str(stranger_secret)))
        publish_until_received(publisher, known, hit_message(), timeout_s=10.0)
        counts = _received_during(publisher, [known, stranger], 0.6)
        assert counts[0] > 0 and counts[1] == 0
        # The operator adds the stranger's key and reloads (SIGHUP); a new connection is accepted.
        os.replace(stranger_public, clients / stranger_public.name)
        publisher.reload_authorized_keys()
        again = _curve_subscriber(context, endpoint, public, zmq.auth.load_certificate(str(stranger_secret)))
        publish_until_received(publisher, again, hit_message(), timeout_s=10.0)  # raises if refused


def test_unusable_key_files_are_refused_before_binding(server_keys, tmp_path):
    secret_file, _ = server_keys
    cases = []
    exposed = tmp_path / "exposed.key_secret"
    exposed.write_bytes(secret_file.read_bytes())
    exposed.chmod(0o644)
    cases.append((exposed, "accessible to other users .mode 0644.; chmod 600 it"))
    cases.append((tmp_path / "server.key", "holds a public key only"))
    cases.append((tmp_path / "missing.key_secret", "no such CURVE key file"))
    garbage = tmp_path / "garbage.key_secret"
    garbage.write_text("not a certificate\n")
    garbage.chmod(0o600)
    cases.append((garbage, "not a CURVE key file"))
    for path, message in cases:
        with pytest.raises(ConfigError, match=message):
            Publisher(ZmqOutput(endpoints=("tcp://127.0.0.1:*",), curve_secret_key_file=path))
    empty = tmp_path / "no-clients"
    empty.mkdir()
    with pytest.raises(ConfigError, match="no client public keys"):
        Publisher(
            ZmqOutput(
                endpoints=("tcp://127.0.0.1:*",), curve_secret_key_file=secret_file, curve_authorized_keys_dir=empty
            )
        )


def test_curve_allows_a_network_endpoint_in_the_config(server_keys):
    secret_file, _ = server_keys
    ZmqOutput(endpoints=("tcp://0.0.0.0:5560",), curve_secret_key_file=secret_file)
    with pytest.raises(ValueError, match="needs curve_secret_key_file"):
        ZmqOutput(curve_authorized_keys_dir=Path("/etc/trackerd/curve/clients"))


def _keys(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "trackerd", "keys", *args], capture_output=True, text=True, timeout=60)


def test_keys_command_writes_a_private_secret_and_refuses_to_overwrite(tmp_path, capsys):
    from trackerd.cli.main import main

    result = _keys("server", "--dir", str(tmp_path))  # once as operators run it, the rest in-process
    assert result.returncode == 0, result.stderr
    public_file, secret_file = tmp_path / "server.key", tmp_path / "server.key_secret"
    assert public_file.stat().st_mode & 0o777 == 0o644
    assert secret_file.stat().st_mode & 0o777 == 0o600
    public, secret = zmq.auth.load_certificate(str(secret_file))
    assert zmq.auth.load_certificate(str(public_file)) == (public, None)
    assert zmq.curve_public(secret) == public  # the pair belongs together
    before = secret_file.read_bytes()

    assert main(["keys", "server", "--dir", str(tmp_path)]) == 1
    assert capsys.readouterr().err.strip().endswith("already exist; use --force to replace")
    assert secret_file.read_bytes() == before

    assert main(["keys", "server", "--dir", str(tmp_path), "--force"]) == 0
    assert secret_file.read_bytes() != before
    assert secret_file.stat().st_mode & 0o777 == 0o600

    assert main(["keys", "client", "--name", "wall-app", "--dir", str(tmp_path)]) == 0
    assert (tmp_path / "wall-app.key").exists()
    capsys.readouterr()
    assert main(["keys", "client", "--dir", str(tmp_path / "nope")]) == 1
    assert "no such directory" in capsys.readouterr().err
    assert main(["keys", "client", "--name", "../x", "--dir", str(tmp_path)]) == 2
    assert "--name" in capsys.readouterr().err
