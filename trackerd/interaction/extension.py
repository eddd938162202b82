"""The interaction stage as a pipeline extension: smoothed hits, events, commands, hands and TUIO.

``create(rig)`` builds it from ``[interaction]`` (None when everything there is
off). In the processing thread, per pair, :meth:`InteractionExtension.on_fix`:

1. feeds the pair's capture time and raw wall hit to the engine
   (trackerd/interaction/engine.py), which smooths it and decides events;
2. replaces the ``hit`` message's position with the smoothed one, keeping the
   raw one in ``raw_*`` and adding the ``cursor_id``;
3. appends ``enter`` / ``leave`` / ``dwell`` / ``gesture`` messages, each
   followed by its ``command`` when the grammar maps it;
4. on one pair in ``hand.every_n_pairs``, looks for a hand in the configured
   camera (about 4-5 ms at half resolution on the development machine, so
   about 1.2 ms per pair on average at the default of 4) and appends a ``hand``
   message (and a ``command`` when the debounced count changes);
5. sends the TUIO bundle for the pair (a non-blocking UDP send).

Event times are capture times on the publishing clock: the offset from the
pair's monotonic capture time to ``capture_ns`` is read off the pair's own
messages, so events line up with the hits exactly.

A pointing session never ends silently. A :meth:`~InteractionExtension.reload`
that rebuilds the stage, and a :meth:`~InteractionExtension.reset` (a recording
starts, a looped replay wraps), end it as a ``leave`` (reason ``lost``, stamped
with the session's last pair) and its command, published ahead of the next
pair's messages, and with an empty TUIO ``alive``; ``cursor_id`` and the TUIO
frame count carry on. At stop, :meth:`~InteractionExtension.finish` returns the
session's last messages for the caller to publish, and
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
from trackerd.geometry.wall import WallFrame
from trackerd.interaction.engine import Event, InteractionEngine, Step
from trackerd.interaction.grammar import Grammar
from trackerd.interaction.hand import FingerDebouncer, HandDetector, HandObservation
from trackerd.interaction.tuio import TuioSender
from trackerd.interaction.validate import check_interaction
from trackerd.locator import PointerFix
from trackerd.pipeline.stats import Window
from trackerd.publish.messages import (
    CommandMessage,
    DwellMessage,
    EnterMessage,
    GestureMessage,
    HandMessage,
    HitMessage,
    LeaveMessage,
    Message,
)

if TYPE_CHECKING:
    from trackerd.pipeline.extensions import ExtensionContext

log = logging.getLogger(__name__)


def create(rig: RigConfig, context: ExtensionContext | None = None) -> InteractionExtension | None:
    """The interaction stage for a rig, or None when ``[interaction]`` turns everything off
    (``context``, what the daemon knows beyond the rig, is not needed here)."""
    if not rig.interaction.any_enabled:
        return None
    return InteractionExtension(rig)


@dataclass(frozen=True)
class _Parts:
    """What a configuration builds (see InteractionExtension._parts)."""

    rig: RigConfig
    wall: WallFrame
    grammar: Grammar
    engine: InteractionEngine
    hand_camera: int | None
    tuio: TuioSender | None


class InteractionExtension:
    """See the module docstring. ``on_fix`` runs in the processing thread, ``status`` in the publishing one."""

    name = "interaction"

    def __init__(self, rig: RigConfig) -> None:
        self._install(self._parts(rig, None))
        self.cost = Window()
        """Time per pair in on_fix (ns), drained into each status."""
        self._offset_ns = time.time_ns() - time.monotonic_ns()
        self._pairs = 0
        self._event_counts: dict[str, int] = {}
        self._gesture_counts: dict[str, int] = {}
        self._pending: list[Message] = []
        """Messages that end a session outside on_fix (reload, reset), published ahead of the next pair's."""
        self._reset_requested = threading.Event()
        self._last_sequence = 0
        self._last_capture_ns = 0
        """The last pair's sequence and capture time: a session ended between pairs ended with it."""
        self._tuio_frames = 0
        """The last ``fseq`` of the TUIO senders closed so far."""

    @staticmethod
    def _parts(rig: RigConfig, previous: InteractionEngine | None) -> _Parts:
        """Every part for ``rig`` (ConfigError, one line, when the rig cannot run), nothing installed yet."""
        cfg = rig.interaction
        checked = check_interaction(rig)
        wall = wall_frame(rig.wall)
        engine = InteractionEngine(cfg, wall.width_m, wall.height_m, checked.templates)
        if previous is not None:
            # Session ids go on counting across rebuilds: a client must never see one twice.
            engine.cursor_id = previous.cursor_id
            engine.rejected_total = previous.rejected_total
        tuio = TuioSender(cfg.tuio) if cfg.tuio.enabled else None
        return _Parts(rig, wall, checked.grammar, engine, checked.hand_camera, tuio)

    def _install(self, parts: _Parts) -> None:
        self.rig = parts.rig
        self.config = parts.rig.interaction
        self.wall = parts.wall
        self.grammar = parts.grammar
        self.engine = parts.engine
        self.hand_camera = parts.hand_camera
        self.hand = HandDetector(self.config.hand) if self.config.hand.enabled else None
        self.debouncer = FingerDebouncer(self.config.hand.debounce_pairs)
        self._last_hand: HandObservation | None = None
        self.tuio = parts.tuio
        self._last_smoothed: np.ndarray | None = None

    # ------------------------------------------------------------------ PipelineExtension

    def on_pair(self, pair: FramePair) -> bool:
        """Nothing to do before the locator."""
        return False

    def on_fix(self, fix: PointerFix, pair: FramePair, messages: list[Message]) -> list[Message]:
        start = time.perf_counter_ns()
        if self._reset_requested.is_set():
            self._reset_requested.clear()
            self._reset_now()
        pending, self._pending = self._pending, []
        if messages:
            self._offset_ns = messages[0].capture_ns - pair.timestamp_ns
        capture_ns = pair.timestamp_ns + self._offset_ns
        out = list(messages)
        hit_index = next((i for i, m in enumerate(out) if isinstance(m, HitMessage)), None)
        raw = None
        if hit_index is not None:
            hit = out[hit_index]
            assert isinstance(hit, HitMessage)
            raw = np.array([hit.wall_x_m, hit.wall_y_m])
        step = self.engine.step(pair.timestamp_ns, raw)
        if hit_index is not None and step.smoothed_m is not None:
            out[hit_index] = self._smoothed_hit(out[hit_index], step.smoothed_m, step.inside)  # type: ignore[arg-type]
        for event in step.events:
            message = self._event_message(event, pair.sequence, capture_ns)
            out.append(message)
            trigger = event.detail["name"] if event.kind == "gesture" else event.kind
            if event.kind == "gesture":
                self._gesture_counts[trigger] = self._gesture_counts.get(trigger, 0) + 1
            self._command(out, trigger, message, pair.sequence, capture_ns)
        if self.hand is not None and self._pairs % self.config.hand.every_n_pairs == 0:
            self._look_for_hand(out, pair, capture_ns)
        if self.tuio is not None:
            self._send_tuio(pair.timestamp_ns, step)
        self._count(out[len(messages):])
        self._pairs += 1
        self._last_sequence, self._last_capture_ns = pair.sequence, capture_ns
        self.cost.add(time.perf_counter_ns() - start)
        return pending + out if pending else out

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
            "hand": self.hand is not None,
            "tuio_packets": None if self.tuio is None else self.tuio.packets,
            "tuio_errors": None if self.tuio is None else self.tuio.errors,
        }
        if cost.size:
            p50, p99 = np.percentile(cost, [50, 99]) / 1e3
            figures.update(cost_p50_us=round(float(p50), 1), cost_p99_us=round(float(p99), 1),
                           cost_max_us=round(float(cost.max()) / 1e3, 1))
        return figures

    def reload(self, rig: RigConfig) -> None:
        """A new configuration: rebuild everything. A pointing session in progress ends (see the
        module docstring), and the old TUIO socket says so before it closes."""
        if rig.interaction == self.config and rig.wall == self.rig.wall:
            return
        try:
            parts = self._parts(rig, self.engine)
        except ConfigError as err:
            log.error("reload: interaction settings kept: %s", err)
            return
        ending = self._end_session()
        self._pending += ending
        self._count(ending)
        if self.tuio is not None:
            self.tuio.close()
            self._tuio_frames = self.tuio.frame_count
        if parts.tuio is not None:
            # Clients take a bundle numbered below the last one they saw as late, and drop it,
            # so the count goes on even after a time with TUIO off.
            parts.tuio.continue_after(self._tuio_frames)
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

    def finish(self) -> list[Message]:
        """The stage's last messages, at stop: the ``leave`` (and command) of a session in
        progress and any not yet published, for the caller to publish before the publisher
        closes. Also removes the TUIO cursor. Call it once no ``on_fix`` runs; idempotent."""
        self._reset_requested.clear()
        ending = self._pending + self._end_session()
        self._pending = []
        self._count(ending)
        if self.tuio is not None:
            self.tuio.end()
        return ending

    def close(self) -> None:
        """Close the TUIO socket, after a last empty ``alive`` so no client keeps the cursor."""
        if self.tuio is not None:
            self.tuio.close()
            self.tuio = None

    def _reset_now(self) -> None:
        ending = self._end_session()
        self._pending += ending
        self._count(ending)
        if self.hand is not None:
            self.hand.reset()
        self._pairs = 0
        self._last_smoothed = None
        if self.tuio is not None:
            self.tuio.end()

    def _end_session(self) -> list[Message]:
        """Reset the engine and the hand's debouncer; the messages that end what was going on."""
        out: list[Message] = []
        for event in self.engine.reset():
            message = self._event_message(event, self._last_sequence, self._last_capture_ns)
            out.append(message)
            self._command(out, event.kind, message, self._last_sequence, self._last_capture_ns)
        if self.hand_camera is not None and self._last_hand is not None and self.debouncer.stable is not None:
            last = self._last_hand
            out.append(HandMessage(sequence=self._last_sequence, capture_ns=self._last_capture_ns,
                                   camera=self.rig.cameras[self.hand_camera].id, present=False,
                                   fingers=self.debouncer.stable, fingers_now=last.fingers,
                                   image_x_px=last.centre_px[0], image_y_px=last.centre_px[1],
                                   area_px=last.area_px))
        self._last_hand = None
        self.debouncer.reset()
        return out

    def _count(self, messages: list[Message]) -> None:
        for message in messages:
            self._event_counts[message.topic] = self._event_counts.get(message.topic, 0) + 1

    # ------------------------------------------------------------------ messages

    def _display(self, position_m: np.ndarray) -> tuple[float | None, float | None]:
        if not self.wall.has_display:
            return None, None
        px = self.wall.to_display_px(position_m)
        return float(px[0]), float(px[1])

    def _smoothed_hit(self, hit: HitMessage, smoothed_m: np.ndarray, inside: bool) -> HitMessage:
        cursor = self.engine.cursor_id if inside else None
        if not self.config.smoothing.enabled:
            return hit.model_copy(update={"cursor_id": cursor})
        x, y = self._display(smoothed_m)
        return hit.model_copy(update={
            "wall_x_m": float(smoothed_m[0]), "wall_y_m": float(smoothed_m[1]),
            "display_x_px": x, "display_y_px": y,
            "on_wall": bool(self.wall.on_wall(smoothed_m)),
            "raw_wall_x_m": hit.wall_x_m, "raw_wall_y_m": hit.wall_y_m,
            "raw_display_x_px": hit.display_x_px, "raw_display_y_px": hit.display_y_px,
            "cursor_id": cursor,
        })

    def _event_message(self, event: Event, sequence: int, capture_ns: int) -> Message:
        x, y = self._display(event.position_m)
        common = {"sequence": sequence, "capture_ns": capture_ns, "cursor_id": event.cursor_id,
                  "wall_x_m": float(event.position_m[0]), "wall_y_m": float(event.position_m[1]),
                  "display_x_px": x, "display_y_px": y}
        d = event.detail
        if event.kind == "enter":
            return EnterMessage(**common)
        if event.kind == "leave":
            return LeaveMessage(**common, reason=d["reason"], duration_ms=d["duration_ms"])
        if event.kind == "dwell":
            return DwellMessage(**common, dwell_ms=d["dwell_ms"])
        return GestureMessage(
            **common, name=d["name"], score=round(float(d["score"]), 4),
            start_ns=d["start_ns"] + self._offset_ns, end_ns=d["end_ns"] + self._offset_ns,
            duration_ms=(d["end_ns"] - d["start_ns"]) / 1e6, path_m=d["path_m"],
            start_wall_x_m=float(d["start_m"][0]), start_wall_y_m=float(d["start_m"][1]),
            runner_up=d["runner_up"],
            runner_up_score=None if d["runner_up"] is None else round(float(d["runner_up_score"]), 4),
        )

    def _command(self, out: list[Message], trigger: str, message: Message, sequence: int, capture_ns: int) -> None:
        command = self.grammar.command_for(trigger)
        if command is None:
            return
        position = {}
        if not isinstance(message, HandMessage):
            position = {key: getattr(message, key)
                        for key in ("cursor_id", "wall_x_m", "wall_y_m", "display_x_px", "display_y_px")}
        out.append(CommandMessage(sequence=sequence, capture_ns=capture_ns, command=command, trigger=trigger,
                                  trigger_topic=message.topic, **position))

    # ------------------------------------------------------------------ hands and TUIO

    def _look_for_hand(self, out: list[Message], pair: FramePair, capture_ns: int) -> None:
        assert self.hand is not None and self.hand_camera is not None
        frame = pair.frames[self.hand_camera]
        seen = self.hand.look(frame.image, frame.pixel_format)
        camera = frame.camera_id
        if seen is None:
            if self._last_hand is not None and self.debouncer.stable is not None:
                last = self._last_hand
                out.append(HandMessage(sequence=pair.sequence, capture_ns=capture_ns, camera=camera, present=False,
                                       fingers=self.debouncer.stable, fingers_now=last.fingers,
                                       image_x_px=last.centre_px[0], image_y_px=last.centre_px[1],
                                       area_px=last.area_px))
            self._last_hand = None
            self.debouncer.reset()
            return
        self._last_hand = seen
        changed = self.debouncer.add(seen.fingers)
        if self.debouncer.stable is None:
            return  # not seen steadily enough yet
        message = HandMessage(sequence=pair.sequence, capture_ns=capture_ns, camera=camera, present=True,
                              fingers=self.debouncer.stable, fingers_now=seen.fingers,
                              image_x_px=seen.centre_px[0], image_y_px=seen.centre_px[1], area_px=seen.area_px)
        out.append(message)
        if changed:
            self._command(out, f"hand_{self.debouncer.stable}", message, pair.sequence, capture_ns)

    def _send_tuio(self, time_ns: int, step: Step) -> None:
        assert self.tuio is not None
        if step.smoothed_m is not None:
            self._last_smoothed = step.smoothed_m
        if not step.inside or self._last_smoothed is None:
            self._last_smoothed = None
            self.tuio.frame(time_ns, None)
            return
        # A pair without a hit while entered keeps the cursor where it was (no remove and re-add).
        w, h = self.wall.width_m, self.wall.height_m
        x = min(max(float(self._last_smoothed[0]) / w, 0.0), 1.0)
        y = min(max(1.0 - float(self._last_smoothed[1]) / h, 0.0), 1.0)
        vx, vy = float(step.velocity_m_s[0]) / w, -float(step.velocity_m_s[1]) / h
        self.tuio.frame(time_ns, (self.engine.cursor_id, x, y, vx, vy))
