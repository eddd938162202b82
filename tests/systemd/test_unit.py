"""systemd/trackerd.service and trackerd-cpu-latency.service: `systemd-analyze verify` can fail, the
exposure scores stay low, and the settings the daemon relies on are there. That verify passes on the
units as installed is test_install.py's."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from trackerd.config.models import RigAcquisition

REPO = Path(__file__).resolve().parents[2]
DROP_IN = REPO / "systemd" / "packet-socket.conf"
CPU_LATENCY_UNIT = REPO / "systemd" / "trackerd-cpu-latency.service"
GIGE_HEARTBEAT_TIMEOUT_S = 3.0
"""GigE Vision's default GevHeartbeatTimeout: a camera stays bound to a dead controller this long."""

needs_analyze = pytest.mark.skipif(
    shutil.which("systemd-analyze") is None, reason="systemd-analyze is not installed (Debian package systemd)"
)


def _settings(path: Path) -> dict[str, list[str]]:
    settings: dict[str, list[str]] = {}
    for raw in path.read_text().splitlines():
        line = raw.strip()
        if line and not line.startswith(("#", "[")) and "=" in line:
            key, value = line.split("=", 1)
            settings.setdefault(key, []).append(value)
    return settings


def _installable_copy(unit: Path, directory: Path) -> Path:
    """The unit with ExecStart pointing at an executable that exists here (verify checks it)."""
    stand_in = directory / "trackerd"
    stand_in.write_text("#!/bin/sh\nexit 0\n")
    stand_in.chmod(0o755)
    text = unit.read_text().replace("/opt/trackerd/venv/bin/trackerd", str(stand_in))
    copy = directory / unit.name
    copy.write_text(text)
    return copy


@needs_analyze
def test_verify_catches_a_broken_unit(tmp_path: Path, unit_path: Path):
    """The verification of the installed units (test_install.py) can fail: a misspelt directive is
    reported. A stand-in executable is enough here, and needs neither root nor an install."""
    broken = tmp_path / "broken"
    broken.mkdir()
    copy = _installable_copy(unit_path, broken)
    copy.write_text(copy.read_text().replace("Type=notify", "Type=notfy"))
    result = subprocess.run(["systemd-analyze", "verify", str(copy)], capture_output=True, text=True, timeout=60)
    assert "notfy" in result.stderr


@needs_analyze
@pytest.mark.parametrize("unit", ["trackerd.service", "trackerd-cpu-latency.service"])
def test_security_exposure_score(unit: str):
    result = subprocess.run(
        ["systemd-analyze", "security", "--offline=true", "--no-pager", str(REPO / "systemd" / unit)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    match = re.search(r"Overall exposure level for \S+: ([0-9.]+) (\w+)", result.stdout)
    assert match, result.stdout[-2000:] + result.stderr
    score = float(match.group(1))
    print(f"systemd-analyze security {unit}: {score} {match.group(2)} (docs/deployment.md records it)")
    documented = (REPO / "docs" / "deployment.md").read_text()
    assert f"Overall exposure level for {unit}: {score:.1f}" in documented, "update the score in docs/deployment.md"
    assert score <= 2.0


def test_service_settings_the_daemon_relies_on(unit_path: Path):
    settings = _settings(unit_path)
    assert settings["Type"] == ["notify"]
    assert settings["ExecStart"][0].split()[0] == "/opt/trackerd/venv/bin/trackerd"
    assert "run --config /etc/trackerd/rig.toml" in settings["ExecStart"][0]
    assert settings["ExecReload"] == ["/bin/kill -HUP $MAINPID"]
    assert settings["Restart"] == ["on-failure"]
    restart_s = float(settings["RestartSec"][0].removesuffix("s"))
    loss_timeout_s = RigAcquisition().loss_timeout_ms / 1000.0
    assert restart_s > max(GIGE_HEARTBEAT_TIMEOUT_S, loss_timeout_s)
    watchdog_s = float(settings["WatchdogSec"][0].removesuffix("s"))
    # The watchdog must outlast a camera loss being noticed, or every loss would restart the daemon.
    assert watchdog_s > loss_timeout_s * 2
    assert settings["RestartPreventExitStatus"] == ["2"]  # ConfigError.exit_code
    assert settings["NoNewPrivileges"] == ["yes"]
    assert settings["ProtectSystem"] == ["strict"]
    assert settings["CapabilityBoundingSet"] == [""]
    assert "AF_PACKET" not in settings["RestrictAddressFamilies"][0]


def test_the_recording_example_is_writable_under_the_unit(unit_path: Path):
    """Regression (issue 15): ProtectSystem=strict left no directory to record into, while
    docs/recording.md's daemon example writes to /var/lib/trackerd/recordings."""
    settings = _settings(unit_path)
    writable = [Path("/var/lib", name) for value in settings.get("StateDirectory", []) for name in value.split()]
    writable += [Path("/run", name) for value in settings.get("RuntimeDirectory", []) for name in value.split()]
    text = (REPO / "docs" / "recording.md").read_text()
    match = re.search(r'^directory = "(/[^"]+)"', text, re.MULTILINE)
    assert match, "docs/recording.md has no daemon example with an absolute directory"
    example = Path(match.group(1))
    assert any(example.is_relative_to(place) for place in writable), (example, writable)


def test_packet_socket_drop_in_grants_only_cap_net_raw():
    settings = _settings(DROP_IN)
    assert settings["AmbientCapabilities"] == ["CAP_NET_RAW"]
    assert settings["CapabilityBoundingSet"] == ["CAP_NET_RAW"]
    assert "AF_PACKET" in settings["RestrictAddressFamilies"][0].split()
    assert settings["PrivateUsers"] == ["no"]


def test_cpu_latency_unit_runs_the_command_with_the_daemon_and_no_capabilities():
    settings = _settings(CPU_LATENCY_UNIT)
    assert settings["Type"] == ["notify"]  # `trackerd cpu-latency` sends READY=1 once the request is in force
    assert settings["ExecStart"][0].split()[:2] == ["/opt/trackerd/venv/bin/trackerd", "cpu-latency"]
    # Started with the daemon once enabled, stopped and restarted with it.
    assert settings["WantedBy"] == ["trackerd.service"]
    assert settings["PartOf"] == ["trackerd.service"]
    assert settings["Before"] == ["trackerd.service"]
    # Root only because the device is root's: no capability, and no device but that one.
    assert "User" not in settings
    assert settings["CapabilityBoundingSet"] == [""]
    assert settings["NoNewPrivileges"] == ["yes"]
    assert settings["DevicePolicy"] == ["closed"]
    assert settings["DeviceAllow"] == ["/dev/cpu_dma_latency rw"]
    assert settings["PrivateNetwork"] == ["yes"]
