"""Optional stages the daemon runs beside the locator: recording, interaction (smoothing, events).

An extension sees every pair and every fix in the processing thread and may
add or replace messages; its status becomes a field of the ``status`` message
named after it. Extensions are built from the rig by :func:`for_rig`, so
`trackerd run`, `trackerd replay` and the demo all get the same ones.

Starting afresh: when a pair does not follow from the one before (an on-demand
recording starts with it, a replay loops round), every stage forgets what it
carried over (the locator's tracking, the interaction's smoothing and strokes),
so that what is published from that pair on depends only on the pairs from it
on, and a replay of the recording reproduces it.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError
from trackerd.locator import PointerFix
from trackerd.publish.messages import Message


class PipelineExtension(Protocol):
    """What the pipeline calls. ``on_pair`` and ``on_fix`` run in the processing thread and must
    not block (hand heavy work to a thread of your own through a bounded queue); ``status`` runs
    in the publishing thread."""

    name: str
    """The extension's field in the status message (``recording``, ``interaction``)."""

    def on_pair(self, pair: FramePair) -> bool:
        """Sees the pair before it is located; True asks every stage to start afresh from this
        pair (see the module's docstring), as when a recording starts with it."""
        ...

    def on_fix(self, fix: PointerFix, pair: FramePair, messages: list[Message]) -> list[Message]: ...

    def reset(self) -> None:
        """Forget what was carried over from earlier pairs (processing thread, before the next pair)."""
        ...

    def status(self) -> dict[str, Any] | None: ...

    def reload(self, rig: RigConfig) -> None: ...

    def finish(self) -> list[Message]:
        """The last messages, published at stop before the publisher closes (a pending leave)."""
        ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class ExtensionContext:
    """What the daemon knows beyond the rig, for extensions that record it."""

    rig_file: Path | None = None
    """The rig TOML the configuration was read from (None: built in memory)."""
    camera_info: Mapping[str, Mapping[str, str | None]] | None = None
    """By camera id, what each camera says about itself (vendor, model, serial, device), filled
    as the cameras open (trackerd.recording.cameras.CameraInfo)."""
    clock_offset_ns: int | None = None
    """The pipeline's monotonic-to-epoch offset (None: not fixed); recordings made on demand store
    it, so their replays publish the capture times the daemon published live, to the nanosecond."""


# Each entry: a module defining ``create(rig, context) -> PipelineExtension | None`` (None: not
# configured).
EXTENSION_MODULES: Sequence[str] = ("trackerd.recording.extension", "trackerd.interaction.extension")


def for_rig(rig: RigConfig, context: ExtensionContext | None = None) -> list[PipelineExtension]:
    """The extensions the rig asks for, in a fixed order (recording sees pairs before interaction)."""
    context = context or ExtensionContext()
    out = []
    for name in EXTENSION_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as err:
            if err.name is not None and name.startswith(err.name):
                continue  # that part of trackerd is not present in this build
            raise
        try:
            extension = module.create(rig, context)
        except ConfigError as err:
            # What the rig asks of an extension is checked here, after the file was loaded: name the
            # file, as the loader's own errors do.
            if context.rig_file is None:
                raise
            raise err.in_file(context.rig_file) from None
        if extension is not None:
            out.append(extension)
    return out
