"""How the virtual rig's cameras are reached: their own network namespaces, or the loopback interface.

As root (``netns``), each camera process runs in its own network namespace, reachable at its own
address over a veth pair (:mod:`trackerd.sim.netns`); the namespace prefix is locked while a rig
uses it, so a second rig cannot take over or tear down the first one's links. Without root
(``loopback``), the first camera is a GigE Vision camera on 127.0.0.1 and the second is Aravis's
in-process Fake camera.
"""

from __future__ import annotations

from typing import Any, Literal

from trackerd.config.models import RigConfig
from trackerd.errors import TrackerdError
from trackerd.sim import netns

Network = Literal["auto", "netns", "loopback"]
FAKE_DEVICE_ID = "Fake_1"


def choose_network(rig: RigConfig, network: Network) -> Literal["netns", "loopback"]:
    """The network the rig's cameras can have: ``auto`` takes namespaces where they can be made; an
    explicit choice the rig cannot have is a TrackerdError saying why."""
    if network == "auto":
        network = "netns" if netns.netns_missing_reason() is None else "loopback"
    if network == "netns" and (reason := netns.netns_missing_reason()):
        raise TrackerdError(f"cannot build the virtual rig's network: {reason}")
    if network == "loopback" and len(rig.cameras) > 2:
        raise TrackerdError("without network namespaces the virtual rig serves at most two cameras")
    if network == "loopback" and rig.acquisition.trigger == "software":
        # Aravis 0.8's in-process Fake stream does not wait for TriggerSoftware: in trigger
        # mode it delivers frames at its own trigger frequency.
        raise TrackerdError(
            "software triggering needs network namespaces (root): the in-process Fake camera"
            " used without them ignores software triggers"
        )
    return network


class RigNetwork:
    """The links of a rig's simulated cameras, and how the daemon addresses each camera over them."""

    def __init__(
        self, camera_count: int, network: Literal["netns", "loopback"], prefix: str, subnet: str, mtu: int | None
    ) -> None:
        self.kind = network
        self.prefix = prefix
        self.mtu = mtu
        try:
            self.nets = netns.plan(camera_count, prefix, subnet) if network == "netns" else []
        except ValueError as err:
            raise TrackerdError(f"cannot plan the virtual rig's network: {err}") from err
        self._lock: netns.PrefixLock | None = None

    @property
    def gige_cameras(self) -> range:
        """The cameras served by a camera process (the rest are in-process Fake cameras)."""
        return range(len(self.nets)) if self.kind == "netns" else range(1)

    def claim(self) -> None:
        """Take the namespace prefix and clear what a crashed rig left under it (netns only).

        The prefix is taken first: a rig turned away must not render a loop for nothing,
        truncate the running rig's truth files, or touch its namespaces. Only a rig holding
        the lock ever removes namespaces (:meth:`release` checks it)."""
        if self.kind != "netns":
            return
        lock = netns.PrefixLock(self.prefix)
        lock.acquire()
        self._lock = lock
        netns.remove_stale(self.prefix)

    def create_links(self) -> None:
        for net in self.nets:
            netns.create(net, self.mtu)

    def release(self) -> None:
        """Remove the links and give the prefix back, if this rig holds it."""
        if self.kind == "netns" and self._lock is not None:
            for net in self.nets:
                netns.remove(net)
            self._lock.release()
            self._lock = None

    def exec_prefix(self, index: int) -> tuple[list[str], str]:
        """How to run camera ``index``'s process: (command prefix, network interface it serves on)."""
        if self.kind == "netns":
            return netns.exec_prefix(self.nets[index]), self.nets[index].camera_link
        return [], "lo"

    def camera_update(self, index: int, serial: str) -> dict[str, Any]:
        """The fields of camera ``index``'s config that address it as the simulated camera it is."""
        if self.kind == "netns":
            return {"address": self.nets[index].camera_address, "device_id": None, "serial": serial}
        if index == 0:
            return {"address": "127.0.0.1", "device_id": None, "serial": serial}
        return {"address": None, "device_id": FAKE_DEVICE_ID, "serial": None}

    @property
    def jumbo_frames(self) -> bool:
        return self.kind == "netns" and self.mtu is not None and self.mtu >= 9000
