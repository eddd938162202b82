"""Optional stages the daemon runs beside the locator: recording, interaction (smoothing, events).

An extension sees every pair before it is located (``on_pair``) and every
located pair (``on_located``: the pair, its fix and its capture time on the
publishing clock) in the processing thread, and answers with domain events
(trackerd.pipeline.events), never wire messages: the publisher turns them into
messages once (trackerd.publish.from_fix). Its status becomes a field of the
``status`` message named after it.

Extensions are built explicitly where the daemon is assembled (`trackerd run`
and `trackerd replay` in trackerd/cli/run.py, the replay benchmark, the
recording export), each from its own module's ``create(rig, context)``, which
returns None when the rig does not ask for it. Given the kinds it may build
(:class:`ExtensionKind`), the daemon also builds, at a reload, one that the new
rig asks for and the old one did not (``[recording] directory`` added, an
``[interaction]`` turned on); one already built is reloaded instead.

Starting afresh: when a pair does not follow from the one before (an on-demand
recording starts with it, a replay loops round), every stage forgets what it
carried over (the locator's tracking, the interaction's smoothing and strokes),
so that what is published from that pair on depends only on the pairs from it
on, and a replay of the recording reproduces it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.locator import PointerFix
from trackerd.pipeline.events import Event, PairEvents


@dataclass(frozen=True, slots=True)
class Located:
    """One pair as the locator left it: what an extension is handed after the locator."""

    pair: FramePair
    fix: PointerFix
    capture_ns: int
    """The pair's capture time on the publishing clock (its messages' ``capture_ns``)."""

    @property
    def clock_offset_ns(self) -> int:
        """From the pair's monotonic capture time (``pair.timestamp_ns``) to the publishing clock."""
        return self.capture_ns - self.pair.timestamp_ns


class PipelineExtension(Protocol):
    """What the pipeline calls. ``on_pair`` and ``on_located`` run in the processing thread and must
    not block (hand heavy work to a thread of your own through a bounded queue); ``status`` runs
    in the publishing thread."""

    name: str
    """The extension's field in the status message (``recording``, ``interaction``)."""

    def on_pair(self, pair: FramePair) -> bool:
        """Sees the pair before it is located; True asks every stage to start afresh from this
        pair (see the module's docstring), as when a recording starts with it."""
        ...

    def on_located(self, located: Located) -> PairEvents:
        """What the extension makes of the located pair (trackerd.pipeline.events.NOTHING: nothing)."""
        ...

    def reset(self) -> None:
        """Forget what was carried over from earlier pairs (processing thread, before the next pair)."""
        ...

    def on_quiet(self, now_ns: int) -> list[Event]:
        """No pair has come for a while (the processing thread's wait for one timed out; ``now_ns`` on the
        pairs' monotonic clock): events to publish now, without a pair (a session ended by a stalled
        source). Called often while pairs are late: it must be cheap, and decide by the time alone."""
        ...

    def status(self) -> dict[str, Any] | None: ...

    def reload(self, rig: RigConfig) -> None: ...

    def finish(self) -> list[Event]:
        """The last events, published at stop before the publisher closes (a pending leave)."""
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
    replay: bool = False
    """The pairs come from a recording (a replay, an export): what is published must follow from
    the pairs alone, never from timing, so work an extension does on a thread of its own when live
    (hand poses) is done in the processing thread instead."""


@dataclass(frozen=True)
class ExtensionKind:
    """One kind of extension a daemon can run, for building it when a reload first asks for it."""

    name: str
    """The name its extensions have (:attr:`PipelineExtension.name`)."""
    create: Callable[[RigConfig, ExtensionContext], PipelineExtension | None]
    """Its module's ``create``: the extension a rig asks for, or None."""
