"""The interaction stage as a pipeline extension: smoothed hits, events, commands, hands and TUIO.

``create(rig, context)`` builds it from ``[interaction]`` (None when everything
there is off). In the processing thread, per located pair,
:meth:`InteractionExtension.on_located`:

1. feeds the pair's capture time and its located wall hit (the one published,
   trackerd.publish.from_fix.published_hit) to the engine
   (trackerd/interaction/engine.py), which smooths it and decides events;
2. says how the pair's hit is published: at the smoothed position, the
   located one kept as ``raw_*``, with the ``cursor_id``;
3. adds ``enter`` / ``leave`` / ``dwell`` / ``gesture`` events, each followed
   by its command when the grammar maps it (trackerd/interaction/outcomes.py);
4. on one pair in ``hand.every_n_pairs``, has the configured camera's frame
   looked at for a hand (trackerd/interaction/handposes.py: on a thread of its
   own live, in the processing thread in a replay) and adds the ``hand`` events
   of finished looks (and a command when the debounced count changes);
5. sends the TUIO bundle for the pair (a non-blocking UDP send).

It answers with domain events (trackerd.pipeline.events); the publisher turns
them into wire messages. Event times are capture times on the publishing
clock: the pair's own (``Located.capture_ns``), and for a gesture's start and
end the engine's times moved by the pair's clock offset.

A pointing session never ends silently. A :meth:`~InteractionExtension.reload`
that rebuilds the stage, and a :meth:`~InteractionExtension.reset` (a recording
starts, a looped replay wraps), end it as a ``leave`` (reason ``lost``, stamped
with the session's last pair) and its command, published ahead of the next
pair's messages, and with an empty TUIO ``alive``; ``cursor_id`` and the TUIO
frame count carry on. At stop, :meth:`~InteractionExtension.finish` returns the
session's last events for the caller to publish, and
:meth:`~InteractionExtension.close` sends the last empty ``alive``.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.config.rig_geometry import wall_frame
from trackerd.errors import ConfigError
from trackerd.interaction.engine import InteractionEngine
from trackerd.interaction.handposes import HandPoses
from trackerd.interaction.outcomes import EventMaker
from trackerd.interaction.tuio import TuioSender, WallCursor
from trackerd.interaction.validate import check_interaction
from trackerd.pipeline.events import CursorHit, Event, Gestured, PairEvents
from trackerd.pipeline.stats import Window
from trackerd.publish.from_fix import published_hit

if TYPE_CHECKING:
    from trackerd.pipeline.extensions import ExtensionContext, Located

log = logging.getLogger(__name__)


QUIET_LEAVE_MS = 500.0
QUIET_LEAVE_PERIODS = 5.0
"""A pointing session ends when no pair at all has come for QUIET_LEAVE_MS, or QUIET_LEAVE_PERIODS frame
periods of the rig's ``[acquisition] frame_rate_hz``, or ``leave_after_ms``, whichever is longest: far more
than the gap between two pairs, and soon enough for a client."""


def create(rig: RigConfig, context: ExtensionContext | None = None) -> InteractionExtension | None:
    """The interaction stage for a rig, or None when ``[interaction]`` turns everything off.

    Replayed (``context.replay``), hand poses are looked for in the processing thread, so the
    replay publishes what the pairs alone decide (trackerd/interaction/handposes.py)."""
    if not rig.interaction.any_enabled:
        return None
    replay = context is not None and context.replay
    return InteractionExtension(rig, threaded_hands=not replay, live=not replay)


@dataclass(frozen=True)
class _Parts:
    """What a configuration builds (see InteractionExtension._parts)."""

    rig: RigConfig
    engine: InteractionEngine
    maker: EventMaker
    hands: HandPoses | None
    tuio: WallCursor | None


class InteractionExtension:
    """See the module docstring. ``on_located`` runs in the processing thread, ``status`` in the publishing one."""

    name = "interaction"

    def __init__(self, rig: RigConfig, *, threaded_hands: bool = True, live: bool = True) -> None:
        """``live`` False (a replay): what is published follows from the pairs alone, so a stalled source
        ends no session (:meth:`on_quiet`)."""
        self._threaded_hands = threaded_hands
        self._live = live
        self._install(self._parts(rig, None))
        self.cost = Window()
        """Time per pair in on_located (ns), drained into each status."""
        self._offset_ns = 0
        """The last pair's clock offset (monotonic to publishing clock)."""
        self._pairs = 0
        self._event_counts: dict[str, int] = {}
        self._gesture_counts: dict[str, int] = {}
        self._pending: list[Event] = []
        """Events that end a session outside on_located (reload, reset), published ahead of the next pair's."""
        self._reset_requested = threading.Event()
        self._last_sequence = 0
        self._last_capture_ns = 0
        """The last pair's sequence and capture time: a session ended between pairs ended with it."""
        self._last_pair_ns: int | None = None
        """The last pair's capture time on the pairs' monotonic clock (:meth:`on_quiet`)."""
        self._tuio_frames = 0
        """The last ``fseq`` of the TUIO senders closed so far."""

    def _parts(self, rig: RigConfig, previous: InteractionEngine | None) -> _Parts:
        """Every part for ``rig`` (ConfigError, one line, when the rig cannot run), nothing installed yet."""
        cfg = rig.interaction
        checked = check_interaction(rig)
        if rig.wall is None:
            raise ConfigError("interaction: the rig has no [wall], which events are placed on")
        wall = wall_frame(rig.wall)
        engine = InteractionEngine(cfg, wall.width_m, wall.height_m, checked.templates)
        if previous is not None:
            # Session ids go on counting across rebuilds: a client must never see one twice.
            engine.cursor_id = previous.cursor_id
            engine.rejected_total = previous.rejected_total
        maker = EventMaker(wall, checked.grammar, smoothing=cfg.smoothing.enabled)
        hands = None
        if cfg.hand.enabled and checked.hand_camera is not None:
            hands = HandPoses(
                cfg.hand, checked.hand_camera, rig.cameras[checked.hand_camera].id, maker, threaded=self._threaded_hands
            )
        tuio = WallCursor(TuioSender(cfg.tuio), wall.width_m, wall.height_m) if cfg.tuio.enabled else None
        return _Parts(rig, engine, maker, hands, tuio)

    def _install(self, parts: _Parts) -> None:
        self.rig = parts.rig
        self.config = parts.rig.interaction
        self.engine = parts.engine
        self.maker = parts.maker
        self.hands = parts.hands
        self.tuio = parts.tuio

    # ------------------------------------------------------------------ PipelineExtension

    def on_pair(self, pair: FramePair) -> bool:
        """Nothing to do before the locator."""
        return False

    def on_located(self, located: Located) -> PairEvents:
        start = time.perf_counter_ns()
        if self._reset_requested.is_set():
            self._reset_requested.clear()
            self._reset_now()
        pair, capture_ns = located.pair, located.capture_ns
        # No pair made for as long as ends a session while the daemon waits (on_quiet): decided from the pairs'
        # own times too, so a replay of a recording that spans a stall gives the same leave (with this pair's
        # messages, where live it went out during the wait, and on_quiet has ended it already). Only where
        # the source numbered no pair in between: pairs it made that were not located (the processing thread
        # was slow: a search, a loaded machine) are no stall, and a session goes on across them. After a
        # stall the waiting thread takes the next pair at once.
        last_ns = self._last_pair_ns
        if (
            last_ns is not None
            and pair.sequence == self._last_sequence + 1
            and self.engine.inside
            and self._quiet(pair.timestamp_ns - last_ns)
        ):
            self._end_quietly()
        pending, self._pending = self._pending, []
        self._offset_ns = located.clock_offset_ns
        hit = published_hit(located.fix)
        raw = None if hit is None else np.array([float(v) for v in hit.wall_xy_m[:2]])
        step = self.engine.step(pair.timestamp_ns, raw)
        cursor: CursorHit | None = None
        if hit is not None and step.smoothed_m is not None:
            cursor = self.maker.cursor_hit(step.smoothed_m, self.engine.cursor_id if step.inside else None)
        events = self.maker.events(
            step.events, sequence=pair.sequence, capture_ns=capture_ns, clock_offset_ns=self._offset_ns
        )
        for event in events:
            if isinstance(event, Gestured):
                self._gesture_counts[event.name] = self._gesture_counts.get(event.name, 0) + 1
        if self.hands is not None:
            due = self._pairs % self.config.hand.every_n_pairs == 0
            events += self.hands.offer(pair, capture_ns) if due else self.hands.take()
        if self.tuio is not None:
            self.tuio.frame(pair.timestamp_ns, step.smoothed_m, step.inside, step.velocity_m_s, self.engine.cursor_id)
        self._count(events)
        self._pairs += 1
        self._last_sequence, self._last_capture_ns = pair.sequence, capture_ns
        self._last_pair_ns = pair.timestamp_ns
        self.cost.add(time.perf_counter_ns() - start)
        return PairEvents(pending, cursor, events)

    def status(self) -> dict[str, Any] | None:
        cost = self.cost.drain()
        figures: dict[str, Any] = {
            "smoothing": self.config.smoothing.enabled,
            "pointing": self.engine.inside,
            "cursor_id": self.engine.cursor_id or None,
            "events": dict(self._event_counts),
            "gestures": dict(self._gesture_counts),
            "templates": len(self.engine.templates),
            "strokes_rejected": self.engine.rejected_total,
            "hand": self.hands is not None,
            "tuio_packets": None if self.tuio is None else self.tuio.sender.packets,
            "tuio_errors": None if self.tuio is None else self.tuio.sender.errors,
        }
        if cost.size:
            p50, p99 = np.percentile(cost, [50, 99]) / 1e3
            figures.update(
                cost_p50_us=round(float(p50), 1),
                cost_p99_us=round(float(p99), 1),
                cost_max_us=round(float(cost.max()) / 1e3, 1),
            )
        return figures

    def reload(self, rig: RigConfig) -> None:
        """A new configuration: rebuild everything. A pointing session in progress ends (see the
        module docstring), and the old TUIO socket says so before it closes."""
        if rig.interaction == self.config and rig.wall == self.rig.wall:
            self.rig = rig  # nothing to rebuild, but the frame rate (on_quiet) may be new
            return
        try:
            parts = self._parts(rig, self.engine)
        except ConfigError as err:
            log.error("reload: interaction settings kept: %s", err)
            return
        self._end_to_pending()
        if self.hands is not None:
            self.hands.stop()
        if self.tuio is not None:
            self.tuio.sender.close()
            self._tuio_frames = self.tuio.sender.frame_count
        if parts.tuio is not None:
            # Clients take a bundle numbered below the last one they saw as late, and drop it,
            # so the count goes on even after a time with TUIO off.
            parts.tuio.sender.continue_after(self._tuio_frames)
        self._install(parts)

    def reset(self) -> None:
        """Forget the pointer, as a freshly started stage would: smoothing, stroke, dwell,
        enter/leave, the hand's count and background, the hand-look schedule.

        Called when a recording starts and when a looped replay wraps, so the replay of a
        recording gives the events the live run gave, and the jump from the last pair back
        to the first is no gesture. Safe from any thread: it takes effect before the next
        pair. The session in progress ends with a ``leave`` (and its command) published
        ahead of that pair's messages, and the TUIO cursor is removed; ``cursor_id`` and
        the counts in the status carry on.
        """
        self._reset_requested.set()

    def on_quiet(self, now_ns: int) -> list[Event]:
        """No pair for a while: the cameras stalled, or one was lost. A client must not keep a cursor that
        nobody moves (an outage lasts seconds to minutes), so once no pair has come for long enough
        (:meth:`_quiet`), a session in progress ends as a reset ends it: a ``leave``, reason ``lost``, stamped
        with its last pair, and an empty TUIO ``alive``, which then goes on once a second as while nothing
        points. Not in a replay, whose output follows from its pairs alone: there the pair after the gap
        ends it (:meth:`on_located` decides the same from the pairs' times), with the same events."""
        if not self._live or self._last_pair_ns is None or not self._quiet(now_ns - self._last_pair_ns):
            return []
        if self.engine.inside:
            log.info(
                "interaction: no pair for %.1f s: the pointing session ends (leave, lost)",
                (now_ns - self._last_pair_ns) / 1e9,
            )
            self._end_quietly()
        elif self.tuio is not None:
            self.tuio.sender.frame(now_ns, None)  # the empty alive, once a second
        events, self._pending = self._pending, []  # and any a reload ended meanwhile
        return events

    def _quiet(self, gap_ns: int) -> bool:
        """Whether no pair for ``gap_ns`` ends a session: over QUIET_LEAVE_MS, QUIET_LEAVE_PERIODS frame
        periods and ``leave_after_ms``."""
        period_ms = 1000.0 / self.rig.acquisition.frame_rate_hz
        return gap_ns > max(QUIET_LEAVE_MS, QUIET_LEAVE_PERIODS * period_ms, self.config.pointing.leave_after_ms) * 1e6

    def _end_quietly(self) -> None:
        """A session in progress ends as a reset ends it, into ``_pending``, and the TUIO cursor goes."""
        if not self.engine.inside:
            return
        self._end_to_pending()
        if self.tuio is not None:
            self.tuio.forget()

    def finish(self) -> list[Event]:
        """The stage's last events, at stop: the ``leave`` (and command) of a session in
        progress and any not yet published, for the caller to publish before the publisher
        closes. Also stops the hand-pose thread and removes the TUIO cursor. Call it once no
        ``on_located`` runs; idempotent."""
        self._reset_requested.clear()
        if self.hands is not None:
            self.hands.stop()
        ending = self._pending + self._end_session()
        self._pending = []
        self._count(ending)
        if self.tuio is not None:
            self.tuio.sender.end()
        return ending

    def close(self) -> None:
        """Stop the hand-pose thread; close the TUIO socket after a last empty ``alive``, so no
        client keeps the cursor."""
        if self.hands is not None:
            self.hands.stop()
        if self.tuio is not None:
            self.tuio.sender.close()
            self.tuio = None

    def _reset_now(self) -> None:
        self._last_pair_ns = None  # what came before the reset is not a gap to the pair after it
        self._end_to_pending(forget_scene=True)
        self._pairs = 0
        if self.tuio is not None:
            self.tuio.forget()

    def _end_to_pending(self, *, forget_scene: bool = False) -> None:
        """End what was going on (:meth:`_end_session`), its events published ahead of the next pair's."""
        ending = self._end_session(forget_scene=forget_scene)
        self._pending += ending
        self._count(ending)

    def _end_session(self, *, forget_scene: bool = False) -> list[Event]:
        """Reset the engine and the hand's count; the events that end what was going on."""
        sequence, capture_ns = self._last_sequence, self._last_capture_ns
        out = self.maker.events(
            self.engine.reset(), sequence=sequence, capture_ns=capture_ns, clock_offset_ns=self._offset_ns
        )
        if self.hands is not None:
            out += self.hands.end_session(sequence, capture_ns, forget_scene=forget_scene)
        return out

    def _count(self, events: list[Event]) -> None:
        for event in events:
            self._event_counts[event.kind] = self._event_counts.get(event.kind, 0) + 1
