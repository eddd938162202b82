"""Network namespaces that give each simulated camera its own IP address (needs root and iproute2).

Aravis's GvFakeCamera binds the GVCP port on one address, so two simulated
cameras need two addresses. Camera ``i`` of a virtual rig lives in namespace
``<prefix>-cam<i>``, joined to the host by a veth pair: ``<prefix><i>h`` on the
host with the first address of a /30 and ``<prefix><i>c`` in the namespace with
the second. With the default subnet 10.213.0.0/24, camera 0 is 10.213.0.2 (host
side 10.213.0.1), camera 1 is 10.213.0.6 (host side 10.213.0.5), and so on.

A lock file per prefix (``/run/lock/trackerd-<prefix>.lock``) keeps two virtual
rigs from using the same names; whoever holds it may delete any namespace or
link left with its prefix by a run that crashed.
"""

from __future__ import annotations

import fcntl
import ipaddress
import json
import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from trackerd.errors import TrackerdError

DEFAULT_PREFIX = "trkd"
DEFAULT_SUBNET = "10.213.0.0/24"
DEFAULT_MTU = 9000
"""Jumbo frames on the cameras' links: with 1500-byte packets the rig sustains about half its
frame rate (each packet costs the simulated camera and Aravis's receiver about the same work)."""
LOCK_DIR = Path("/run/lock")
_PREFIX = re.compile(r"^[a-z][a-z0-9]{0,7}$")


class NetnsError(TrackerdError):
    """A namespace or veth pair could not be created or removed."""


@dataclass(frozen=True)
class CameraNet:
    """The network of one simulated camera."""

    index: int
    namespace: str
    host_link: str
    camera_link: str
    host_address: str
    camera_address: str
    prefix_length: int = 30


def netns_missing_reason() -> str | None:
    """Why namespaces cannot be used here, or None if they can."""
    if os.geteuid() != 0:
        return "network namespaces need root"
    if shutil.which("ip") is None:
        return "the ip command (iproute2) is not installed"
    return None


def plan(n_cameras: int, prefix: str = DEFAULT_PREFIX, subnet: str = DEFAULT_SUBNET) -> list[CameraNet]:
    """Names and addresses for ``n_cameras`` cameras; ValueError if they do not fit."""
    if not _PREFIX.match(prefix):
        raise ValueError(
            f"namespace prefix '{prefix}' must be 1-8 lowercase letters and digits, starting with a letter"
        )
    network = ipaddress.ip_network(subnet)
    if network.version != 4 or network.num_addresses < 4 * n_cameras:
        raise ValueError(f"subnet {subnet} has no room for {n_cameras} /30 links")
    nets = []
    for index, block in enumerate(network.subnets(new_prefix=30)):
        if index == n_cameras:
            break
        host, camera = list(block.hosts())
        nets.append(
            CameraNet(
                index,
                f"{prefix}-cam{index}",
                f"{prefix}{index}h",
                f"{prefix}{index}c",
                str(host),
                str(camera),
            )
        )
    return nets


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)
    if check and result.returncode != 0:
        raise NetnsError(f"ip {' '.join(args)}: {result.stderr.strip() or 'failed'}")
    return result


def create(net: CameraNet, mtu: int | None = None) -> None:
    """Create the namespace, the veth pair and the addresses of one camera."""
    _ip("netns", "add", net.namespace)
    try:
        _ip(
            "link",
            "add",
            net.host_link,
            "type",
            "veth",
            "peer",
            "name",
            net.camera_link,
            "netns",
            net.namespace,
        )
        if mtu is not None:
            _ip("link", "set", net.host_link, "mtu", str(mtu))
            _ip("-n", net.namespace, "link", "set", net.camera_link, "mtu", str(mtu))
        _ip("addr", "add", f"{net.host_address}/{net.prefix_length}", "dev", net.host_link)
        _ip("link", "set", net.host_link, "up")
        _ip(
            "-n",
            net.namespace,
            "addr",
            "add",
            f"{net.camera_address}/{net.prefix_length}",
            "dev",
            net.camera_link,
        )
        _ip("-n", net.namespace, "link", "set", net.camera_link, "up")
        _ip("-n", net.namespace, "link", "set", "lo", "up")
    except NetnsError:
        remove(net)
        raise


def remove(net: CameraNet) -> None:
    """Remove one camera's namespace (which takes its veth pair with it). Quiet if absent."""
    _ip("netns", "del", net.namespace, check=False)
    _ip("link", "del", net.host_link, check=False)


def remove_stale(prefix: str) -> list[str]:
    """Delete every namespace and link named with ``prefix`` (call only while holding the lock)."""
    removed = []
    names = _ip("netns", "list", check=False).stdout.split("\n")
    for line in names:
        name = line.split(" ", 1)[0]
        if name.startswith(f"{prefix}-cam"):
            _ip("netns", "del", name, check=False)
            removed.append(name)
    links = json.loads(_ip("-j", "link", "show", check=False).stdout or "[]")
    pattern = re.compile(rf"^{re.escape(prefix)}\d+[hc]$")
    for link in links:
        name = link.get("ifname", "")
        if pattern.match(name):
            _ip("link", "del", name, check=False)
            removed.append(name)
    return removed


def exec_prefix(net: CameraNet) -> list[str]:
    """The command prefix that runs a program inside the camera's namespace."""
    return ["ip", "netns", "exec", net.namespace]


class PrefixLock:
    """An exclusive, non-blocking lock on a namespace prefix, held until released or the process exits."""

    def __init__(self, prefix: str, directory: Path = LOCK_DIR) -> None:
        self.path = directory / f"trackerd-{prefix}.lock"
        self._handle: IO[str] | None = None

    def acquire(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        handle = self.path.open("a+")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError as err:
            handle.seek(0)
            owner = handle.read().strip() or "another process"
            handle.close()
            raise NetnsError(
                f"another virtual rig uses the namespace prefix (lock {self.path} held by {owner})"
            ) from err
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()}\n")
        handle.flush()
        self._handle = handle

    def release(self) -> None:
        if self._handle is not None:
            fcntl.flock(self._handle, fcntl.LOCK_UN)
            self._handle.close()
            self._handle = None
