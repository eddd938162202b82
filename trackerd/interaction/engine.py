"""The interaction engine: wall hits in, smoothed hits and pointing events out.

One engine follows one pointer. Per camera pair it takes the pair's capture
time and the raw wall hit (or None when the pair gave no hit) and returns the
smoothed hit and the events the pair completed:

``enter``    the (smoothed) hit has been on the display for ``enter_after_ms``;
``leave``    it has been off the display, beyond ``edge_margin_mm``, or missing,
             for ``leave_after_ms`` (the margin is the hysteresis that keeps a
             pointer held at the edge from flickering);
``dwell``    while entered, the hit stayed within ``radius_mm`` of where it came
             to rest for ``time_ms``; once per rest (the hit must move out of the
             radius, or a gesture end, before the next);
``gesture``  a stroke (trackerd/interaction/strokes.py) that began on the display
             matched a template (trackerd/interaction/recognizer.py) well and
             unambiguously enough, and fits the template's kinematic gates.

No clocks are read here: every time is a capture time from the caller, so the
same hits give the same events, live or replayed. :meth:`InteractionEngine.reset`
forgets the pointer (a recording starts, a looped replay wraps, the stage is
rebuilt): what follows gives the events a new engine would give, except that
``cursor_id`` keeps counting, so no client ever sees a session id twice.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from trackerd.config.interaction import InteractionConfig
from trackerd.interaction.recognizer import score_all
from trackerd.interaction.smoothing import OneEuroFilter
from trackerd.interaction.strokes import Stroke, StrokeSegmenter
from trackerd.interaction.templates import Template, stroke_features

Array = NDArray[np.float64]
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Event:
    """Something the pointer did, decided at capture time ``time_ns``."""

    kind: str
    """``enter``, ``leave``, ``dwell`` or ``gesture``."""
    time_ns: int
    cursor_id: int
    position_m: Array
    """Wall position (2,) the event refers to (the dwell's mean, a gesture's end, ...)."""
    detail: dict[str, Any] = field(default_factory=dict)
    """Kind-specific: leave: reason, duration_ms; dwell: dwell_ms, spread_mm; gesture: name,
    score, start_ns, end_ns, path_m, start_m, runner_up, runner_up_score."""


@dataclass(frozen=True)
class Step:
    """What one pair gave."""

    smoothed_m: Array | None
    """The smoothed hit (2,), None when the pair had no hit."""
    events: list[Event]
    inside: bool
    """Whether the pointer is entered (on the display) after this pair."""
    velocity_m_s: Array
    """The filter's velocity estimate (2,), for TUIO's cursor velocity."""


@dataclass(frozen=True)
class Rejection:
    """A stroke that was not a gesture, and why (for `trackerd gesture` and tests)."""

    stroke: Stroke
    reason: str
    scores: list[tuple[str, float]]


class InteractionEngine:
    """Smoothing, enter/leave, dwell and gestures for one pointer on a wall of ``width_m`` x ``height_m``."""

    def __init__(
        self, config: InteractionConfig, width_m: float, height_m: float, templates: dict[str, Template]
    ) -> None:
        self.config = config
        self.width_m = width_m
        self.height_m = height_m
        self.templates = dict(templates)
        self._shapes = [t.shape for t in self.templates.values()]
        self.filter = OneEuroFilter(config.smoothing)
        self.segmenter = StrokeSegmenter(config.gestures)
        self.rejections: list[Rejection] = []
        """Recent strokes that were no gesture (the last REJECTIONS_KEPT)."""
        self.counts: dict[str, int] = {}
        self.rejected_total = 0
        """Strokes that were no gesture, since start."""
        self.cursor_id = 0
        self._clear_pointer()

    def _clear_pointer(self) -> None:
        """The per-pointer state of a new engine (smoothing and strokes have their own reset)."""
        self._last_step_ns: int | None = None
        """Capture time of the last pair seen (a reset's leave is decided then)."""
        self._last_hit_ns: int | None = None
        self._inside = False
        self._since_ns: int | None = None
        """Outside: when the hit first came on the display; inside: when it first went off."""
        self._entered_ns = 0
        self._last_on_m: Array | None = None
        self._dwell_anchor: Array | None = None
        self._dwell_start_ns = 0
        self._dwell_sum = np.zeros(2)
        self._dwell_count = 0
        self._dwell_armed = True

    @property
    def inside(self) -> bool:
        """Whether the pointer is entered on the display."""
        return self._inside

    # ------------------------------------------------------------------ per pair

    def step(self, time_ns: int, raw_m: Array | None) -> Step:
        """Process one pair: its capture time and its raw wall hit (2,) in metres, or None."""
        events: list[Event] = []
        smoothed: Array | None = None
        self._last_step_ns = time_ns
        gap_ns = self.config.smoothing.reset_after_ms * 1e6
        if self._last_hit_ns is not None and time_ns - self._last_hit_ns > gap_ns:
            self._lost(events)
        if raw_m is not None:
            self._last_hit_ns = time_ns
            if self.config.smoothing.enabled:
                smoothed = self.filter(time_ns, raw_m)
            else:
                smoothed = np.asarray(raw_m, dtype=np.float64)[:2].copy()
        if self.config.pointing.enabled:
            self._pointing(time_ns, smoothed, events)
        if self._inside and smoothed is not None:
            if self.config.dwell.enabled:
                self._dwell(time_ns, smoothed, events)
            if self.config.gestures.enabled and self._shapes:
                self._gesture_sample(time_ns, smoothed, events)
        for event in events:
            self.counts[event.kind] = self.counts.get(event.kind, 0) + 1
        return Step(smoothed, events, self._inside, self.filter.velocity_m_s)

    def reset(self) -> list[Event]:
        """Forget the pointer: smoothing, stroke, dwell and enter/leave state, as a new engine.

        Returns the ``leave`` (reason ``lost``, at the last pair's time) that ends the pointing
        session when the pointer was entered, else nothing. A stroke in progress is dropped,
        not recognised: what comes after a reset (the first pair of a looped replay) is not the
        continuation of what came before it. ``cursor_id`` and the counts carry on.
        """
        events: list[Event] = []
        self.segmenter.reset()
        if self._inside:
            assert self._last_step_ns is not None
            self._leave(self._last_step_ns, "lost", events)
            self.counts["leave"] = self.counts.get("leave", 0) + 1
        self.filter.reset()
        self._clear_pointer()
        return events

    def _lost(self, events: list[Event]) -> None:
        """No hit for longer than reset_after_ms: end a stroke and start the filter afresh."""
        self._last_hit_ns = None
        self.filter.reset()
        self._end_stroke(events)

    # ------------------------------------------------------------------ enter / leave

    def _on_display(self, position_m: Array, margin_m: float) -> bool:
        x, y = float(position_m[0]), float(position_m[1])
        return -margin_m <= x <= self.width_m + margin_m and -margin_m <= y <= self.height_m + margin_m

    def _pointing(self, time_ns: int, smoothed: Array | None, events: list[Event]) -> None:
        cfg = self.config.pointing
        if not self._inside:
            if smoothed is not None and self._on_display(smoothed, 0.0):
                if self._since_ns is None:
                    self._since_ns = time_ns
                if time_ns - self._since_ns >= cfg.enter_after_ms * 1e6:
                    self._enter(time_ns, smoothed, events)
            else:
                self._since_ns = None
            return
        if smoothed is not None and self._on_display(smoothed, cfg.edge_margin_mm / 1000.0):
            self._since_ns = None
            self._last_on_m = smoothed
            return
        if self._since_ns is None:
            self._since_ns = time_ns
        if time_ns - self._since_ns >= cfg.leave_after_ms * 1e6:
            self._leave(time_ns, "lost" if smoothed is None else "off_display", events)

    def _enter(self, time_ns: int, position_m: Array, events: list[Event]) -> None:
        self._inside = True
        self._since_ns = None
        self._entered_ns = time_ns
        self._last_on_m = position_m
        self.cursor_id += 1
        self._reset_dwell(position_m, time_ns, armed=True)
        self.segmenter.reset()
        events.append(Event("enter", time_ns, self.cursor_id, position_m.copy()))

    def _leave(self, time_ns: int, reason: str, events: list[Event]) -> None:
        self._end_stroke(events)
        self._inside = False
        self._since_ns = None
        position = self._last_on_m if self._last_on_m is not None else np.zeros(2)
        events.append(
            Event(
                "leave",
                time_ns,
                self.cursor_id,
                position.copy(),
                {"reason": reason, "duration_ms": (time_ns - self._entered_ns) / 1e6},
            )
        )

    # ------------------------------------------------------------------ dwell

    def _reset_dwell(self, position_m: Array, time_ns: int, armed: bool) -> None:
        self._dwell_anchor = position_m.copy()
        self._dwell_start_ns = time_ns
        self._dwell_sum = position_m.copy()
        self._dwell_count = 1
        self._dwell_armed = armed

    def _dwell(self, time_ns: int, position_m: Array, events: list[Event]) -> None:
        cfg = self.config.dwell
        assert self._dwell_anchor is not None
        if float(np.hypot(*(position_m - self._dwell_anchor))) > cfg.radius_mm / 1000.0:
            self._reset_dwell(position_m, time_ns, armed=True)
            return
        self._dwell_sum += position_m
        self._dwell_count += 1
        if self._dwell_armed and time_ns - self._dwell_start_ns >= cfg.time_ms * 1e6:
            self._dwell_armed = False
            mean = self._dwell_sum / self._dwell_count
            events.append(
                Event("dwell", time_ns, self.cursor_id, mean, {"dwell_ms": (time_ns - self._dwell_start_ns) / 1e6})
            )

    # ------------------------------------------------------------------ gestures

    def _gesture_sample(self, time_ns: int, position_m: Array, events: list[Event]) -> None:
        stroke = self.segmenter.add(time_ns, position_m)
        if stroke is not None:
            self._recognise(stroke, events)

    def _end_stroke(self, events: list[Event]) -> None:
        stroke = self.segmenter.end()
        if stroke is not None and self._inside:
            self._recognise(stroke, events)

    def _recognise(self, stroke: Stroke, events: list[Event]) -> None:
        cfg = self.config.gestures
        features = stroke_features(stroke.times_ns, stroke.points_m)
        if features.duration_ms > cfg.max_stroke_ms:
            self._reject(stroke, "longer than max_stroke_ms", [])
            return
        scores = score_all(stroke.points_m, self._shapes)
        best_name, best = scores[0]
        runner_up, second = scores[1] if len(scores) > 1 else (None, 0.0)
        if best < cfg.min_score_ratio:
            self._reject(stroke, f"best match {best_name} scores {best:.2f} < {cfg.min_score_ratio:.2f}", scores)
            return
        if best - second < cfg.min_margin_ratio:
            self._reject(stroke, f"ambiguous: {best_name} {best:.2f} vs {runner_up} {second:.2f}", scores)
            return
        why_not = self.templates[best_name].admits(features)
        if why_not is not None:
            self._reject(stroke, why_not, scores)
            return
        # The rest that follows a gesture is not a click.
        self._reset_dwell(stroke.points_m[-1], stroke.end_ns, armed=False)
        events.append(
            Event(
                "gesture",
                stroke.end_ns,
                self.cursor_id,
                stroke.points_m[-1].copy(),
                {
                    "name": best_name,
                    "score": best,
                    "start_ns": stroke.start_ns,
                    "end_ns": stroke.end_ns,
                    "path_m": features.path_m,
                    "start_m": stroke.points_m[0].copy(),
                    "runner_up": runner_up,
                    "runner_up_score": second,
                },
            )
        )

    def _reject(self, stroke: Stroke, reason: str, scores: list[tuple[str, float]]) -> None:
        self.rejected_total += 1
        self.rejections.append(Rejection(stroke, reason, scores))
        del self.rejections[:-REJECTIONS_KEPT]
        log.debug("stroke of %.2f m is no gesture: %s", stroke.path_m, reason)


REJECTIONS_KEPT = 20
