"""TUIO 1.1 bundles as a client receives them on loopback, decoded by the test's own OSC decoder."""

from __future__ import annotations

import socket

import pytest

from tests.interaction.osc_decode import decode_bundle
from trackerd.config.interaction import TuioConfig
from trackerd.errors import ConfigError
from trackerd.interaction.tuio import TuioSender


def test_cursor_bundles_follow_tuio_1_1():
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.settimeout(2.0)
    sender = TuioSender(TuioConfig(enabled=True, port=client.getsockname()[1], source="wall"))
    try:
        sender.frame(0, (7, 0.25, 0.75, 0.5, -0.1))
        sender.frame(16_000_000, (7, 0.26, 0.75, 0.6, -0.1))
        sender.frame(32_000_000, None)
        sender.frame(48_000_000, None)  # nothing new to say within a second: nothing sent
        sender.frame(1_100_000_000, None)  # but once a second the source says it is alive
        sender.frame(1_116_000_000, (8, 0.5, 0.5, 0.0, 0.0))
        sender.close()  # the daemon stops with a cursor on the display
        bundles = [decode_bundle(client.recv(2048)) for _ in range(6)]
        sender.close()
    finally:
        sender.close()
        client.close()
    timetag, first = bundles[0]
    assert timetag == 1  # "immediately"
    assert [args[0] for _, args in first] == ["source", "alive", "set", "fseq"]
    assert all(address == "/tuio/2Dcur" for address, _ in first)
    assert first[0][1][1].startswith("wall@")
    assert first[1][1] == ["alive", 7]
    assert first[2][1][:2] == ["set", 7] and first[2][1][2:] == pytest.approx([0.25, 0.75, 0.5, -0.1, 0.0])
    # Acceleration: the velocity changed by 0.1 per second in 16 ms.
    assert bundles[1][1][2][1][6] == pytest.approx(0.1 / 0.016, rel=1e-3)
    assert bundles[2][1][1][1] == ["alive"] and bundles[3][1][1][1] == ["alive"]
    assert [b[1][-1][1][1] for b in bundles] == [1, 2, 3, 4, 5, 6]  # fseq
    # The last word removes the cursor, so no client keeps one nobody moves; a second close sends nothing.
    assert bundles[4][1][1][1] == ["alive", 8] and bundles[5][1][1][1] == ["alive"]
    assert sender.packets == 6 and sender.errors == 0


def test_an_unknown_host_is_a_config_error():
    with pytest.raises(ConfigError, match=r"interaction\.tuio\.host"):
        TuioSender(TuioConfig(enabled=True, host="no-such-host.invalid"))
