"""The daemon's state machine on its own: camera states in, state and detail out."""

from __future__ import annotations

from trackerd.pipeline.state import DaemonStateMachine

BOTH_STREAMING = [("left", "streaming"), ("right", "streaming")]


def test_it_starts_until_every_camera_streams_then_runs():
    machine = DaemonStateMachine()
    assert machine.observe([], reloading=False) == ("starting", "waiting for cameras")
    assert machine.observe([("left", "streaming"), ("right", "connecting")], reloading=False) == (
        "starting",
        "waiting for right",
    )
    assert machine.observe(BOTH_STREAMING, reloading=False) == ("running", None)
    assert machine.state == "running" and machine.detail is None


def test_a_camera_lost_before_ready_is_still_starting_and_after_ready_degraded():
    machine = DaemonStateMachine()
    lost = [("left", "lost"), ("right", "streaming")]
    machine.observe(BOTH_STREAMING, reloading=False)
    # Running, but READY not sent yet: systemd has not been told the daemon works.
    assert machine.observe(lost, reloading=False) == ("starting", "waiting for left")
    machine.observe(BOTH_STREAMING, reloading=False)
    assert machine.announce_ready()
    assert machine.observe(lost, reloading=False) == ("degraded", "camera left not streaming")
    assert machine.observe([("left", "lost"), ("right", "reconnecting")], reloading=False) == (
        "degraded",
        "camera left, right not streaming",
    )
    assert machine.observe(BOTH_STREAMING, reloading=False) == ("running", None)


def test_ready_is_announced_once_and_only_while_running():
    machine = DaemonStateMachine()
    machine.observe([("left", "connecting")], reloading=False)
    assert not machine.announce_ready()
    machine.observe(BOTH_STREAMING, reloading=False)
    assert machine.announce_ready()
    assert not machine.announce_ready()
    assert machine.ready_announced


def test_a_reload_shows_whatever_the_cameras_do():
    machine = DaemonStateMachine()
    assert machine.observe(BOTH_STREAMING, reloading=True) == ("reloading", "applying a new configuration")
    assert machine.observe([("left", "stopped")], reloading=True) == ("reloading", "applying a new configuration")
    assert machine.observe(BOTH_STREAMING, reloading=False) == ("running", None)


def test_stopping_is_for_good():
    machine = DaemonStateMachine()
    machine.observe(BOTH_STREAMING, reloading=False)
    machine.stop()
    assert machine.observe(BOTH_STREAMING, reloading=False) == ("stopping", "stopping")
    assert machine.observe([], reloading=True) == ("stopping", "stopping")
    assert not machine.announce_ready()
