"""The cameras `trackerd record` and `trackerd snap` read: the rig's, or the virtual rig's for trying things out.

Both open an :class:`~trackerd.acquisition.live.LivePairSource` directly (no
pipeline), and note each camera's vendor, model and serial as it opens, for the
recording's metadata (:class:`~trackerd.recording.cameras.CameraInfo`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from typing import Any, Literal

from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError
from trackerd.recording.cameras import CameraInfo


@dataclass
class CameraSource:
    """An open pair source, the rig it was opened with and what each camera said about itself."""

    source: Any
    rig: RigConfig
    info: CameraInfo = field(default_factory=CameraInfo)
    virtual: Any = None


def add_virtual_arguments(parser: argparse.ArgumentParser, verb: str) -> None:
    """--virtual MOTION, and the network options `trackerd simrig` has, so a virtual rig can run
    beside another one (each prefix has its own namespaces, links and lock file)."""
    from trackerd.sim import netns
    from trackerd.sim.motion import MOTIONS

    parser.add_argument(
        "--virtual",
        metavar="MOTION",
        choices=MOTIONS,
        help=f"{verb} simulated cameras serving a rendered motion ({', '.join(MOTIONS)})",
    )
    parser.add_argument(
        "--prefix",
        default=netns.DEFAULT_PREFIX,
        help=f"with --virtual: network namespace name prefix (default {netns.DEFAULT_PREFIX})",
    )
    parser.add_argument(
        "--subnet",
        default=netns.DEFAULT_SUBNET,
        help=f"with --virtual: addresses for the cameras' links (default {netns.DEFAULT_SUBNET})",
    )


@contextmanager
def open_cameras(
    rig: RigConfig,
    *,
    virtual_motion: str | None = None,
    label: str = "trackerd",
    prefix: str | None = None,
    subnet: str | None = None,
) -> Iterator[CameraSource]:
    """Start the rig's cameras (or, with ``virtual_motion``, simulated cameras serving that motion,
    networked under ``prefix`` and ``subnet``, by default the virtual rig's)."""
    from trackerd.acquisition.live import LivePairSource

    with ExitStack() as stack:
        virtual = None
        if virtual_motion is not None:
            from trackerd.sim import netns
            from trackerd.sim.rig import VirtualRig

            network: Literal["netns", "loopback"] = "netns" if netns.netns_missing_reason() is None else "loopback"
            if network == "netns":
                try:
                    netns.plan(len(rig.cameras), prefix or netns.DEFAULT_PREFIX, subnet or netns.DEFAULT_SUBNET)
                except ValueError as err:
                    raise ConfigError(f"--prefix/--subnet: {err}") from None
            if network == "loopback" and rig.acquisition.trigger == "software":
                acquisition = rig.acquisition.model_copy(update={"trigger": "free_running"})
                rig = rig.model_copy(update={"acquisition": acquisition})
            print(
                f"{label}: starting simulated cameras serving the '{virtual_motion}' motion (rendered once, then"
                " cached)...",
                file=sys.stderr,
                flush=True,
            )
            virtual = stack.enter_context(
                VirtualRig(
                    rig,
                    motion=virtual_motion,
                    network=network,
                    prefix=prefix or netns.DEFAULT_PREFIX,
                    subnet=subnet or netns.DEFAULT_SUBNET,
                )
            )
            rig = virtual.daemon_rig
        info = CameraInfo(before=None if virtual is None else virtual.on_open)
        opened = CameraSource(None, rig, info, virtual)
        opened.source = stack.enter_context(LivePairSource(rig, on_open=info.on_open))
        yield opened
