"""Optional stages the daemon runs beside the locator: recording, interaction (smoothing, events).

An extension sees every pair and every fix in the processing thread and may
add or replace messages; its status becomes a field of the ``status`` message
named after it. Extensions are built from the rig by :func:`for_rig`, so
`trackerd run`, `trackerd replay` and the demo all get the same ones.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from typing import Any, Protocol

from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.locator import PointerFix
from trackerd.publish.messages import Message


class PipelineExtension(Protocol):
    """What the pipeline calls. ``on_pair`` and ``on_fix`` run in the processing thread and must
    not block (hand heavy work to a thread of your own through a bounded queue); ``status`` runs
    in the publishing thread."""

    name: str
    """The extension's field in the status message (``recording``, ``interaction``)."""

    def on_pair(self, pair: FramePair) -> None: ...

    def on_fix(self, fix: PointerFix, pair: FramePair, messages: list[Message]) -> list[Message]: ...

    def status(self) -> dict[str, Any] | None: ...

    def reload(self, rig: RigConfig) -> None: ...

    def close(self) -> None: ...


# Each entry: a module defining ``create(rig) -> PipelineExtension | None`` (None: not configured).
EXTENSION_MODULES: Sequence[str] = ("trackerd.recording.extension", "trackerd.interaction.extension")


def for_rig(rig: RigConfig) -> list[PipelineExtension]:
    """The extensions the rig asks for, in a fixed order (recording sees pairs before interaction)."""
    out = []
    for name in EXTENSION_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as err:
            if err.name is not None and name.startswith(err.name):
                continue  # that part of trackerd is not present in this build
            raise
        extension = module.create(rig)
        if extension is not None:
            out.append(extension)
    return out
