"""The unit's hardening does not break what trackerd uses: PyGObject + Aravis, NumPy/OpenCV, pyzmq, sd_notify.

systemd is not PID 1 here, so the unit cannot be started. Instead the probe
(sandbox_probe.py) runs under an equivalent of the unit's sandbox:
sandbox.sh builds its file-system view (ProtectSystem=strict, PrivateTmp,
ProtectHome, PrivateDevices, ProtectProc/ProcSubset, RuntimeDirectory) in
fresh mount and PID namespaces; setpriv runs it as an unprivileged user with
no capabilities and NoNewPrivileges; the probe installs the seccomp filters
systemd 252 derives from the unit's own SystemCallFilter,
RestrictAddressFamilies and MemoryDenyWriteExecute lines. The camera is
Aravis's fake GigE Vision camera on the loopback of a private network
namespace, streamed over UDP.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cpu_holder import run_holder

HERE = Path(__file__).resolve().parent
NOBODY = 65534
CPU_LATENCY_UNIT = HERE.parents[1] / "systemd" / "trackerd-cpu-latency.service"

pytestmark = [pytest.mark.root, pytest.mark.aravis]


def _expand(group: str, seen: set[str]) -> set[str]:
    """Syscall names in a systemd filter group, nested groups expanded (as systemd does)."""
    if group in seen:
        return set()
    seen.add(group)
    out = subprocess.run(["systemd-analyze", "syscall-filter", group], capture_output=True, text=True, check=True)
    names: set[str] = set()
    for line in out.stdout.splitlines()[1:]:
        item = line.strip()
        if not item or item.startswith("#"):
            continue
        names |= _expand(item, seen) if item.startswith("@") else {item}
    return names


def _syscall_lists(unit: Path) -> dict[str, list[str]]:
    allow: set[str] = set()
    deny: set[str] = set()
    for line in unit.read_text().splitlines():
        match = re.match(r"^SystemCallFilter=(~?)(.*)$", line.strip())
        if not match:
            continue
        names: set[str] = set()
        for item in match.group(2).split():
            names |= _expand(item, set()) if item.startswith("@") else {item}
        (deny if match.group(1) else allow).update(names)
    return {"allow": sorted(allow), "deny": sorted(deny)}


def _missing_tools() -> str | None:
    if os.geteuid() != 0:
        return "needs root for mount and PID namespaces"
    for tool in ("systemd-analyze", "unshare", "setpriv", "ip", "arv-fake-gv-camera-0.8"):
        if shutil.which(tool) is None:
            return f"{tool} is not installed"
    import ctypes.util

    if ctypes.util.find_library("seccomp") is None:
        return "libseccomp is not installed"
    try:
        import gi

        gi.require_version("Aravis", "0.8")
    except (ImportError, ValueError) as err:
        return f"Aravis 0.8 is not available ({err})"
    return None


HIDDEN_BY_THE_UNIT = ("/tmp", "/var/tmp", "/home", "/root", "/run/user")
"""Where PrivateTmp and ProtectHome put an empty directory: a checkout or venv there is out of sight."""


def _hidden_checkout() -> str | None:
    for path in (HERE.parents[1], Path(sys.prefix)):
        hidden = next((top for top in HIDDEN_BY_THE_UNIT if path.is_relative_to(top)), None)
        if hidden is not None:
            return f"{path} is under {hidden}, which the unit's sandbox hides (PrivateTmp, ProtectHome)"
    return None


def test_daemon_stack_works_under_the_units_sandbox(unit_path: Path, tmp_path: Path):
    reason = _missing_tools() or _hidden_checkout()
    if reason:
        pytest.skip(reason)
    # systemd's notification socket stands outside the sandbox, bind-mounted in as /run/notify.
    notify_dir = tmp_path / "notify"
    notify_dir.mkdir(mode=0o777)
    notify_dir.chmod(0o777)
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind(str(notify_dir / "notify"))
    (notify_dir / "notify").chmod(0o777)
    listener.settimeout(0)
    env = {
        "PATH": "/usr/sbin:/usr/bin:/sbin:/bin",
        "PYTHONPATH": str(HERE.parents[1]),
        "HOME": "/nonexistent",
        "SANDBOX_NOTIFY_DIR": str(notify_dir),
        "SANDBOX_FAKE_CAMERA": "SANDBOX1",
    }
    command = [
        # A private network namespace: the fake camera's GVCP port cannot clash with other tests.
        "unshare",
        "--net",
        "--mount",
        "--pid",
        "--fork",
        "--propagation",
        "private",
        str(HERE / "sandbox.sh"),
        str(NOBODY),
        str(NOBODY),
        "setpriv",
        f"--reuid={NOBODY}",
        f"--regid={NOBODY}",
        "--clear-groups",
        "--inh-caps=-all",
        "--bounding-set=-all",
        "--no-new-privs",
        sys.executable,
        str(HERE / "sandbox_probe.py"),
        str(unit_path),
        "127.0.0.1",
        "/run/notify/notify",
    ]
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=60, env=env, input=json.dumps(_syscall_lists(unit_path))
    )
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    print("sandbox probe:", json.dumps(report, indent=1))
    assert report["uid"] == str(NOBODY)
    assert set(report["applied"].split(",")) >= {"SystemCallFilter", "RestrictAddressFamilies"}
    failures = {name: value for name, value in report.items() if value.startswith("FAILED")}
    assert not failures, failures
    assert listener.recv(4096).startswith(b"READY=1")
    listener.close()


def test_cpu_latency_command_works_under_its_units_restrictions(tmp_path: Path):
    """`trackerd cpu-latency` as trackerd-cpu-latency.service runs it: root without any capability,
    no new privileges, and the unit's system call, address family and W^X filters."""
    import ctypes.util

    from trackerd.cpu_latency import available, current_us

    if not available():
        pytest.skip("/dev/cpu_dma_latency is not writable here (root, a kernel with PM QoS)")
    for tool in ("systemd-analyze", "setpriv"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is not installed")
    if ctypes.util.find_library("seccomp") is None:
        pytest.skip("libseccomp is not installed")
    before = current_us()
    if before is None or before <= 13:
        pytest.skip(f"a request of {before} µs is already in force here")
    command = [
        "setpriv",
        "--inh-caps=-all",
        "--bounding-set=-all",
        "--no-new-privs",
        sys.executable,
        str(HERE / "filtered_exec.py"),
        str(CPU_LATENCY_UNIT),
        sys.executable,
        "-m",
        "trackerd",
        "cpu-latency",
        "--max-us",
        "13",
    ]
    run = run_holder(command, tmp_path, stdin_text=json.dumps(_syscall_lists(CPU_LATENCY_UNIT)))
    assert "READY=1" in run.ready.splitlines()
    assert run.in_force_us == 13
    assert run.returncode == 0, run.stderr[-3000:]
    assert run.stderr == ""
    assert current_us() == before
