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
"""

from __future__ import annotations

import logging
import time
from typing import Any

import numpy as np

from trackerd.acquisition.frame import FramePair
from trackerd.config.models import RigConfig
from trackerd.errors import ConfigError
from trackerd.geometry.wall import WallFrame
from trackerd.interaction.engine import Event, InteractionEngine, Step
from trackerd.interaction.grammar import Grammar
from trackerd.interaction.hand import FingerDebouncer, HandDetector, HandObservation
from trackerd.interaction.templates import load_templates
from trackerd.interaction.tuio import TuioSender
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

log = logging.getLogger(__name__)


def create(rig: RigConfig) -> InteractionExtension | None:
    """The interaction stage for a rig, or None when ``[interaction]`` turns everything off."""
    if not rig.interaction.any_enabled:
        return None
    return InteractionExtension(rig)


class InteractionExtension:
    """See the module docstring. ``on_fix`` runs in the processing thread, ``status`` in the publishing one."""

    name = "interaction"

    def __init__(self, rig: RigConfig) -> None:
        self._build(rig)
        self.cost = Window()
        """Time per pair in on_fix (ns), drained into each status."""
        self._offset_ns = time.time_ns() - time.monotonic_ns()
        self._pairs = 0
        self._event_counts: dict[str, int] = {}
        self._gesture_counts: dict[str, int] = {}

    def _build(self, rig: RigConfig) -> None:
        cfg = rig.interaction
        self.rig = rig
        self.config = cfg
        self.wall = WallFrame.from_config(rig.wall)
        templates = {}
        if cfg.gestures.enabled:
            templates = load_templates(cfg.gestures.template_dir, builtin=cfg.gestures.builtin,
                                       only=cfg.gestures.only)
        self.grammar = Grammar(cfg.commands, set(templates))
        self.engine = InteractionEngine(cfg, self.wall.width_m, self.wall.height_m, templates)
        self.hand_camera: int | None = None
        self.hand: HandDetector | None = None
        self.debouncer = FingerDebouncer(cfg.hand.debounce_pairs)
        self._last_hand: HandObservation | None = None
        if cfg.hand.enabled:
            ids = [c.id for c in rig.cameras]
            camera = cfg.hand.camera or ids[0]
            if camera not in ids:
                raise ConfigError(f"interaction.hand.camera: no camera '{camera}'; the rig has {', '.join(ids)}")
            self.hand_camera = ids.index(camera)
            self.hand = HandDetector(cfg.hand)
        self.tuio = TuioSender(cfg.tuio) if cfg.tuio.enabled else None
        self._last_smoothed: np.ndarray | None = None

    # ------------------------------------------------------------------ PipelineExtension

    def on_pair(self, pair: FramePair) -> None:
        """Nothing to do before the locator."""

    def on_fix(self, fix: PointerFix, pair: FramePair, messages: list[Message]) -> list[Message]:
        start = time.perf_counter_ns()
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
        for message in out[len(messages):]:
            self._event_counts[message.topic] = self._event_counts.get(message.topic, 0) + 1
        self._pairs += 1
        self.cost.add(time.perf_counter_ns() - start)
        return out

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
        """A new configuration: rebuild everything (a pointing session in progress ends quietly)."""
        if rig.interaction == self.config and rig.wall == self.rig.wall:
            return
        old_tuio = self.tuio
        try:
            self._build(rig)
        except ConfigError as err:
            log.error("reload: interaction settings kept: %s", err)
            return
        if old_tuio is not None:
            old_tuio.close()

    def close(self) -> None:
        if self.tuio is not None:
            self.tuio.close()
            self.tuio = None

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
